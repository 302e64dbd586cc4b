#!/usr/bin/env bash
# The 16 × 16 stockinette hang of issue 19's acceptance (docs/BENCHMARKS.md, "Knit: a stockinette patch
# hanging under gravity"), carried across working sessions. The run needs more wall-clock time than a
# session has on the 2-core development machine (16 045 relaxation iterations of ~0.85 s, then 240 time
# steps of ~35 s on average, from ~65 s down to under 10 s as the patch settles), and a session's
# processes and every file outside the checkout end with it; the checkout is what the next session starts
# from. So the run's checkpoint (`checkpoint.json`, src/knit/checkpoint.rs;
# with the frames written so far once it steps) travels in the checkout as one archive, and each session
# continues it from there.
#
#   tools/knit_hang_acceptance.sh start    # unpack the carried run into OUT (unless OUT has a checkpoint),
#                                          # build, and continue it in the background (log OUT.log)
#   tools/knit_hang_acceptance.sh status   # where the run is: phase, relaxation iterations, steps, wall time,
#                                          # and the hours left at the steps' rate so far
#   tools/knit_hang_acceptance.sh pack     # put OUT's checkpoint (and frames) into the carried archive
#   tools/knit_hang_acceptance.sh stop     # stop the background run (its checkpoint stays: `start` resumes)
#
# A run packed part-way through the steps carries every frame so far (~0.8 MB each) while they fit in the
# limit below, and frame 0 with the last frame after that (the run's figures are in the checkpoint).
#
# OUT is out/hang16 (KNIT_HANG_OUT names another); the archive is benches/hang_stock_16x16/run.tar.gz.
# Pack before a session ends and commit the archive; when the run completes (OUT/result.json), record its
# figures in docs/BENCHMARKS.md and delete the archive. The run of issue 19 completed in session 28 (its
# figures head the section; 25 873 s in all, the steps 8502 s) and its archive is deleted, so `start` now
# begins a fresh run. The run is the ignored test
# `benchmark_16x16_hang` of tests/patch_hang.rs with KNIT_HANG_RESUME=1 (the same scene as
# examples/knit/hang_stock_16x16.json).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
out=${KNIT_HANG_OUT:-out/hang16}
carried=benches/hang_stock_16x16/run.tar.gz
# The archive may hold this much (bytes): the checkpoint is ~1.8 MB compressed, a frame ~0.8 MB.
limit=${KNIT_HANG_PACK_LIMIT:-$((24 * 1024 * 1024))}
case "${1:-}" in
start)
    mkdir -p "$out"
    out=$(cd "$out" && pwd)
    if [ ! -f "$out/checkpoint.json" ] && [ ! -f "$out/result.json" ] && [ -f "$carried" ]; then
        tar -xzf "$carried" -C "$out"
        echo "unpacked $carried into $out"
    fi
    cargo test --release -p skintight --test patch_hang --no-run
    (
        KNIT_HANG_OUT="$out" KNIT_HANG_RESUME=1 setsid nohup cargo test --release -p skintight \
            --test patch_hang -- --ignored --nocapture benchmark_16x16_hang >>"$out.log" 2>&1 </dev/null &
        echo $! >"$out.pid"
    )
    echo "running in the background (pid $(cat "$out.pid")); log $out.log"
    ;;
status)
    python3 - "$out" <<'EOF'
import json, os, sys
out = sys.argv[1]
result, checkpoint = os.path.join(out, "result.json"), os.path.join(out, "checkpoint.json")
if os.path.exists(result) and not os.path.exists(checkpoint):
    r = json.load(open(result))
    keys = ["relax_newton_iterations", "relax_converged", "steps", "newton_iterations", "unconverged_steps",
            "min_distance_over_diameter", "relax_seconds", "seconds"]
    print("complete:", json.dumps({k: r.get(k) for k in keys}))
elif os.path.exists(checkpoint):
    c = json.load(open(checkpoint))
    print(f"{c['phase']}: relaxation {c['relax_newton_iterations']} Newton iterations, {c['steps']} steps, "
          f"{c['seconds']:.0f} s of wall-clock time ({c['relax_seconds']:.0f} s relaxing)")
    scene = c["scene"]
    total = round(scene["duration_s"] / scene["dt_s"])
    stepping = c["seconds"] - c["relax_seconds"]
    if c["phase"] == "stepping" and c["steps"] > 0:
        per_step = stepping / c["steps"]
        left = (total - c["steps"]) * per_step
        print(f"{c['steps']} of {total} steps, {per_step:.0f} s a step so far: ~{left / 3600:.1f} h to go")
else:
    sys.exit(f"{out}: no checkpoint.json or result.json (run `start` first)")
EOF
    ;;
pack)
    if [ -f "$out/result.json" ] && [ ! -f "$out/checkpoint.json" ]; then
        echo "$out/result.json: the run is complete; record it in docs/BENCHMARKS.md and git rm $carried" >&2
        exit 1
    fi
    if [ ! -f "$out/checkpoint.json" ]; then
        echo "$out/checkpoint.json: no checkpoint to pack (run \`start\` first)" >&2
        exit 1
    fi
    mkdir -p "$(dirname "$carried")"
    # The checkpoint is replaced atomically (written beside, then renamed), so a copy of it is whole; it is
    # archived first, and the frames it names were written before it (a resume drops any later frame).
    tmp="$carried.tmp"
    (cd "$out" && { echo checkpoint.json; ls -A | grep -v -e '^checkpoint\.json$' -e '^result\.json$' -e '\.tmp$' || true; } |
        tar -czf - -T -) >"$tmp"
    size=$(stat -c %s "$tmp")
    if [ "$size" -gt "$limit" ]; then
        # The steps need more than one session (session 27: ~60 Newton iterations a step), and 60 frames of
        # 0.8 MB exceed what the repository should carry. The run's figures (counters, smallest distance
        # over every step) are in the checkpoint, so frames 1 .. last-1 stay behind: the next session's
        # sequence.json lists them without their files (a carried benchmark run, not a product).
        last=$(python3 -c "import json,sys; m=json.load(open(sys.argv[1])); print(m['frames'][-1]['file'])" "$out/sequence.json")
        (cd "$out" && { echo checkpoint.json; echo sequence.json; echo vertex_sources.npy; echo frames/000000.npy;
            if [ "$last" != frames/000000.npy ]; then echo "$last"; fi; } | tar -czf - -T -) >"$tmp"
        size=$(stat -c %s "$tmp")
        echo "$out: all frames would exceed $limit bytes; packed frame 0 and the last ($last) only" >&2
    fi
    if [ "$size" -gt "$limit" ]; then
        rm -f "$tmp"
        echo "$out: the archive would be $size bytes, more than $limit" >&2
        exit 1
    fi
    mv "$tmp" "$carried"
    echo "packed $out into $carried ($size bytes)"
    "$root/tools/knit_hang_acceptance.sh" status
    ;;
stop)
    if [ -f "$out.pid" ]; then
        kill -- "-$(cat "$out.pid")" 2>/dev/null || kill "$(cat "$out.pid")" 2>/dev/null || true
        rm -f "$out.pid"
        echo "stopped; \`start\` resumes from $out/checkpoint.json"
    else
        echo "$out.pid: no run started by this script" >&2
        exit 1
    fi
    ;;
*)
    echo "usage: tools/knit_hang_acceptance.sh start|status|pack|stop (OUT: \${KNIT_HANG_OUT:-out/hang16})" >&2
    exit 2
    ;;
esac
