"""Driver of `.ci/generated_client`: a shop's integration written against the Python client that
`openapi-python-client` generated from openapi.yaml (the package `skintight_client` on PYTHONPATH). It sends
no HTTP of its own: every request goes through the generated functions, and every answer is read through
the generated models. `curl` is run only to check the downloads against an independent reader.

It uploads the body, submits the calf sleeve (and repeats the submission with its Idempotency-Key), follows
the job's events to the end (and resumes them with Last-Event-ID), reads the job and its artifact list, and
downloads every artifact (whole, and resumed from a byte offset). Exits 1 on any mismatch, listing them.
"""

import argparse
import hashlib
import io
import json
import pathlib
import subprocess
import sys
import uuid

import httpx

from skintight_client import AuthenticatedClient
from skintight_client.api.assets import get_asset, upload_asset
from skintight_client.api.jobs import get_artifact, get_job, job_events, list_artifacts, submit_job
from skintight_client.api.operations import openapi
from skintight_client.models import (
    Artifact,
    Asset,
    Error,
    Job,
    JobEventCompleted,
    JobEventIteration,
    JobEventQueued,
    JobEventStarted,
    JobEventWarning,
    JobStatus,
    MeshFormat,
    SimulateJobRequest,
)
from skintight_client.types import File

# `result.json` carries the run's own timings (the CLI's run and the server's differ in them): compared with
# `curl` and the listing only. The DXF files carry their run's identity in the header — creation dates
# ($TDCREATE, $TDUCREATE, $TDUPDATE, $TDUUPDATE) and GUIDs ($FINGERPRINTGUID, $VERSIONGUID) —: compared with
# the CLI's with those six values masked. Every other artifact must equal the CLI's file byte for byte.
TIMED = {"result.json"}
DXF_RUN = {b"$TDCREATE", b"$TDUCREATE", b"$TDUPDATE", b"$TDUUPDATE", b"$FINGERPRINTGUID", b"$VERSIONGUID"}


def undated(name, data):
    """The artifact's bytes with the DXF header's dates and GUIDs masked (other artifacts as they are)."""
    if not name.endswith(".dxf"):
        return data
    lines = data.split(b"\r\n")
    for i, line in enumerate(lines):
        if line.strip() in DXF_RUN and i + 2 < len(lines):
            lines[i + 2] = b"<run>"
    return b"\r\n".join(lines)

# `x-sse-events` of openapi.yaml: the model of each event kind's `data`.
EVENT_MODELS = {
    "queued": JobEventQueued,
    "started": JobEventStarted,
    "iteration": JobEventIteration,
    "warning": JobEventWarning,
    "completed": JobEventCompleted,
}

failures = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        failures.append(what)


def sse_events(text):
    """The events of a text/event-stream body: (id, event, data) of each block with data."""
    out = []
    for block in text.replace("\r\n", "\n").split("\n\n"):
        fields = {}
        for line in block.split("\n"):
            if not line or line.startswith(":"):
                continue
            name, _, value = line.partition(":")
            fields.setdefault(name, []).append(value[1:] if value.startswith(" ") else value)
        if "data" in fields:
            out.append((int(fields["id"][0]), fields.get("event", ["message"])[0], "\n".join(fields["data"])))
    return out


def sha256(b):
    return hashlib.sha256(b).hexdigest()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--url", required=True)
    ap.add_argument("--key", required=True)
    ap.add_argument("--body", required=True, type=pathlib.Path)
    ap.add_argument("--scene", required=True, type=pathlib.Path)
    ap.add_argument("--cli", required=True, type=pathlib.Path)
    ap.add_argument("--work", required=True, type=pathlib.Path)
    a = ap.parse_args()
    client = AuthenticatedClient(base_url=a.url, token=a.key, timeout=httpx.Timeout(300.0),
                                 raise_on_unexpected_status=True)

    # The document itself, as text.
    doc = openapi.sync(client=client)
    check(isinstance(doc, str) and doc.startswith("openapi: 3.1"), "GET /openapi.yaml read as text")

    # Upload the body, its format named (a generated client sends application/octet-stream).
    body = a.body.read_bytes()
    r = upload_asset.sync_detailed(client=client, body=File(payload=io.BytesIO(body), file_name="body.obj"),
                                   format_=MeshFormat.OBJ)
    check(r.status_code in (200, 201) and isinstance(r.parsed, Asset), f"upload answered {r.status_code}")
    asset = r.parsed
    check(asset.sha256 == sha256(body) and asset.bytes_ == len(body) and asset.format_ == MeshFormat.OBJ,
          "the asset's sha256, size and format are the upload's")
    check(isinstance(get_asset.sync(asset.id, client=client), Asset), "GET the asset")

    # Submit the calf sleeve on it, typed as a `simulate` request.
    scene = json.loads(a.scene.read_text())
    scene["body"]["source"]["path"] = asset.id
    request = SimulateJobRequest.from_dict({"kind": "simulate", "spec": scene})
    key = str(uuid.uuid4())
    r = submit_job.sync_detailed(client=client, body=request, idempotency_key=key)
    check(r.status_code == 201 and isinstance(r.parsed, Job), f"submit answered {r.status_code}: {r.content[:300]!r}")
    job = r.parsed
    again = submit_job.sync_detailed(client=client, body=request, idempotency_key=key)
    check(again.status_code == 200 and again.parsed.id == job.id,
          "the same Idempotency-Key answers 200 with the same job")

    # Follow its events to the end (the stream closes after the final event).
    text = job_events.sync(job.id, client=client)
    check(isinstance(text, str), "the event stream read as text")
    events = sse_events(text)
    ids = [e[0] for e in events]
    check(ids == list(range(1, len(ids) + 1)), f"event ids 1..{len(ids)} without gaps")
    kinds = [e[1] for e in events]
    check(kinds[:2] == ["queued", "started"] and kinds[-1] == "completed", f"events {kinds[:2]} … {kinds[-1:]}")
    iterations = 0
    completed = None
    for _, kind, data in events:
        model = EVENT_MODELS.get(kind)
        check(model is not None, f"event kind {kind} is one of the documented ones")
        if model is None:
            continue
        parsed = model.from_dict(json.loads(data))
        if kind == "iteration":
            iterations += 1
            check(parsed.iteration == iterations, f"iteration event {parsed.iteration} in order")
        if kind == "completed":
            completed = parsed
    check(iterations > 0, f"{iterations} iteration events")
    # Resumed after its second-to-last event: the last one again, nothing else.
    resumed = sse_events(job_events.sync(job.id, client=client, last_event_id=ids[-2]))
    check(resumed == events[-1:], "Last-Event-ID resumes after that event")

    done = get_job.sync(job.id, client=client)
    check(isinstance(done, Job) and done.status == JobStatus.COMPLETED, f"the job is {done.status}")

    # Every artifact: the generated client's bytes, the listing's sha256 and curl's download agree, and
    # the deterministic ones equal the CLI's files.
    listing = list_artifacts.sync(job.id, client=client).artifacts
    names = sorted(x.name for x in listing)
    check(completed is not None and sorted(completed.artifacts) == names, "`completed` names every artifact")
    cli = sorted(p.name for p in a.cli.iterdir())
    check(set(cli) <= set(names), f"the server's artifacts include the CLI's files: missing {set(cli) - set(names)}")
    for art in listing:
        assert isinstance(art, Artifact)
        got = get_artifact.sync(job.id, art.name, client=client)
        check(isinstance(got, File), f"{art.name}: downloaded as bytes ({art.content_type})")
        data = got.payload.read()
        digest = sha256(data)
        curl = subprocess.run(["curl", "-sf", "-H", f"Authorization: Bearer {a.key}",
                               f"{a.url}/v1/jobs/{job.id}/artifacts/{art.name}"],
                              check=True, capture_output=True).stdout
        check(digest == art.sha256 and len(data) == art.bytes_ and digest == sha256(curl),
              f"{art.name}: {len(data)} bytes, sha256 {digest[:16]}… = listing = curl")
        if art.name in cli and art.name not in TIMED:
            mine = (a.cli / art.name).read_bytes()
            dated = " (dates and GUIDs masked)" if art.name.endswith(".dxf") else ""
            check(undated(art.name, data) == undated(art.name, mine), f"{art.name}: = the CLI's file{dated}")
        # Resumed from the middle: the rest, in the artifact's own bytes.
        half = len(data) // 2
        part = get_artifact.sync_detailed(job.id, art.name, client=client, range_=f"bytes={half}-")
        check(part.status_code == 206 and part.parsed.payload.read() == data[half:],
              f"{art.name}: Range bytes={half}- answered 206 with the rest")
    print(f"{len(listing)} artifacts, {len(events)} events")
    if failures:
        print(f"{len(failures)} mismatches:\n  " + "\n  ".join(failures), file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
