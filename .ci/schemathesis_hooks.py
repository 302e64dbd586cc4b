"""Schemathesis hooks for `.ci/schemathesis`: schema-valid requests get inputs the server can use.

The schema says what a request looks like; some inputs must also *work*: a job spec is the kind's document
(a scene, a design job), an upload is a mesh. For positive (schema-valid) cases these hooks put in valid
ones — a short `selftest` spec, small `simulate`/`design` specs, a tetrahedron as the mesh — and a fresh
`Idempotency-Key`; negative cases are left as generated, so the server must still reject them.
"""

import copy
import json
import pathlib
import uuid

import schemathesis

ROOT = pathlib.Path(__file__).resolve().parent.parent

TETRAHEDRON = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"

# The small cylinder of the service tests, one Newton iteration: cheap to queue many of.
_CYLINDER = json.loads((ROOT / "examples" / "cylinder.json").read_text())
_CYLINDER["body"]["source"].update({"radial_segments": 12, "rings": 2, "layers": 8})
_CYLINDER["garment"]["edge_length"] = 0.015
_CYLINDER["solver"]["max_iterations"] = 1
_DESIGN = copy.deepcopy(_CYLINDER)
_DESIGN["objectives"] = {
    "shape": {"weight": 1.0, "target": {"kind": "revolution", "profile": [[-0.12, 0.049], [0.12, 0.044]]}}
}
_DESIGN["optimizer"] = {"max_iterations": 1, "mode_levels": [6]}

SPECS = {
    # Long enough (2 s) that a cancel usually finds it queued or running.
    "selftest": {"iterations": 20, "sleep_ms": 100, "seed": 1},
    "simulate": _CYLINDER,
    "design": _DESIGN,
    # Two frames of the smallest shared pattern.
    "yarn_simulate": {"pattern": "stocktiniest_9", "cells": [2, 2], "scenario": "hang",
                      "duration_s": 0.0125, "dt_s": 0.004166666666666667, "frame_rate_hz": 120},
}


def _positive(case):
    meta = getattr(case, "meta", None)
    return meta is None or str(meta.generation.mode) == "positive"


def _fix(case):
    if not _positive(case):
        return
    op = (case.method.upper(), case.path)
    if op == ("POST", "/v1/jobs") and isinstance(case.body, dict):
        kind = case.body.get("kind")
        if kind in SPECS:
            case.body["spec"] = copy.deepcopy(SPECS[kind])
        if case.headers and "Idempotency-Key" in case.headers:
            case.headers["Idempotency-Key"] = str(uuid.uuid4())
    elif op == ("POST", "/v1/assets"):
        # The format from the query wins over the Content-Type; a tetrahedron in OBJ.
        case.query = {"format": "obj"}
        case.body = TETRAHEDRON


@schemathesis.hook
def before_call(ctx, case, kwargs):
    """Every phase's schema-valid requests (examples and coverage included) get usable inputs."""
    _fix(case)
