#!/usr/bin/env bash
# The design benchmark: the tapered cylinder and the tight pants designed by Gauss-Newton, side by side in
# one sitting, with this checkout's build (evaluations from the last equilibrium; with the predictor; with
# the predictor and inexact solves) and with a base commit built from git (default cf525de, the commit
# before the design-speed work), and a table of time per iteration, per evaluation, per Newton step and
# one factorization, and the time and work to a target (the cylinder: 1/50 of its initial objective; the
# pants: 99 % of the area in the stretch window).
#
#   tools/design_bench.sh [BASE_COMMIT]        CASES="cylinder pants" (default) or one of them
#
# The base is checked out into target/design-bench/base-COMMIT (a detached git worktree) and built there
# once (a full release build, ~10 min on 2 cores); runs write into target/design-bench/runs/. The jobs
# are the examples with the fabric-limits term off (weight 0) for this build, which is the base's
# objective (the term came later). The pants read ../shared/data/bodies/regular_1k.obj beside the
# checkout. It takes ~5 min for the cylinder and ~20 min for the pants on 2 shared cores.
set -euo pipefail
base=${1:-cf525de}
cases=${CASES:-cylinder pants}
root=$(git rev-parse --show-toplevel)
bench=$root/target/design-bench
runs=$bench/runs
wt=$bench/base-$base
mkdir -p "$runs"

if [ ! -x "$wt/target/release/skintight" ]; then
    [ -d "$wt" ] || git -C "$root" worktree add --detach "$wt" "$base" >/dev/null
    echo "building $base in $wt" >&2
    (cd "$wt" && cargo build --release --bin skintight >&2)
fi
(cd "$root" && cargo build --release --bin skintight >&2)

example() {
    case $1 in
    cylinder) echo design_cylinder_tapered_gn.json ;;
    pants) echo design_pants_stretch_tight_gn.json ;;
    *) echo "unknown case $1 (cylinder, pants)" >&2; exit 2 ;;
    esac
}

# A variant of an example: relative paths made absolute, the fabric-limits term off, options added.
# Relative paths are resolved against this checkout's examples/ (a base worktree is not beside the data).
variant() { # source destination options-json
    python3 - "$1" "$2" "$3" "$root/examples" <<'PY'
import json, os, sys
src, dst, opts, here = sys.argv[1], sys.argv[2], json.loads(sys.argv[3]), sys.argv[4]
job = json.load(open(src))
def fix(v):
    if isinstance(v, dict):
        return {k: (os.path.normpath(os.path.join(here, x)) if k == "path" and isinstance(x, str)
                    and not os.path.isabs(x) else fix(x)) for k, x in v.items()}
    if isinstance(v, list):
        return [fix(x) for x in v]
    return v
job = fix(job)
job.setdefault("optimizer", {}).update(opts)
json.dump(job, open(dst, "w"))
PY
}

run() { # name binary job
    echo "running $1" >&2
    "$2" design "$3" --out "$runs/$1" --quiet >/dev/null 2>"$runs/$1.err" || true
}

for case in $cases; do
    ex=$(example "$case")
    variant "$wt/examples/$ex" "$runs/$case-base.json" '{}'
    variant "$root/examples/$ex" "$runs/$case-last.json" \
        '{"fabric_limits": {"weight": 0}, "predictor": false, "inexact_solves": false}'
    variant "$root/examples/$ex" "$runs/$case-predictor.json" \
        '{"fabric_limits": {"weight": 0}, "predictor": true, "inexact_solves": false}'
    variant "$root/examples/$ex" "$runs/$case-inexact.json" \
        '{"fabric_limits": {"weight": 0}, "predictor": true, "inexact_solves": true}'
    run "$case-base" "$wt/target/release/skintight" "$runs/$case-base.json"
    for v in last predictor inexact; do
        run "$case-$v" "$root/target/release/skintight" "$runs/$case-$v.json"
    done
done

python3 - "$runs" "$base" $cases <<'PY'
import json, os, sys
runs, base, cases = sys.argv[1], sys.argv[2], sys.argv[3:]
labels = {"base": f"{base} (base)", "last": "warm start", "predictor": "predictor",
          "inexact": "predictor + inexact"}
head = ("| case | build | iterations | evaluations | Newton its | factorizations | design s | s / iteration "
        "| s / evaluation | s / Newton step | one factorization s | to target: s | to target: Newton its |")
print(head)
print("|" + "---|" * (head.count("|") - 1))
for case in cases:
    for v in ["base", "last", "predictor", "inexact"]:
        d = os.path.join(runs, f"{case}-{v}")
        try:
            r = json.load(open(os.path.join(d, "result.json")))
            h = json.load(open(os.path.join(d, "history.json")))
        except (OSError, ValueError) as e:
            print(f"| {case} | {labels[v]} | failed: {e} |")
            continue
        its = r["iterations"]
        evals = r.get("evaluations_total", r.get("evaluations"))
        newton = r.get("newton_iterations_total", r.get("newton_iterations"))
        fact = r.get("factorizations_total")
        secs = r["design_seconds"]
        t = r.get("timings", {})
        if case == "cylinder":
            o0 = h[0]["objective"]
            hit = [e for e in h if e["objective"] <= o0 / 50]
        elif any("window_area_fraction" in e for e in h):
            hit = [e for e in h if (e.get("window_area_fraction") or 0) >= 0.99]
        else:
            # A build whose history has no window fraction: the end of the run, if it got there.
            final = (r.get("window_area_fraction") or {}).get("final") or 0
            hit = [dict(h[-1], seconds=secs, newton_iterations_total=None)] if final >= 0.99 else []
        first = hit[0] if hit else None
        fmt = lambda x, f="{:.3g}": "—" if x is None else f.format(x)
        print(f"| {case} | {labels[v]} | {its} | {evals} | {newton} | {fmt(fact, '{}')} | {secs:.1f} | "
              f"{secs / max(its, 1):.2f} | {secs / max(evals, 1):.3f} | {fmt(t.get('newton_step_s'))} | "
              f"{fmt(t.get('one_factorization_s'))} | "
              f"{fmt(first and first['seconds'], '{:.1f}')} | "
              f"{fmt(first and first.get('newton_iterations_total'), '{}')} |")
PY
