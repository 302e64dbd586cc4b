#!/usr/bin/env bash
# Side by side timing of the 16 × 16 knit hang probe (docs/BENCHMARKS.md, "Knit: a stockinette patch
# hanging under gravity"): the patch_hang benchmark built at BASE (default 102227d, before issue 19's
# speed-ups) and at the working tree, run one after the other on the same machine, the working tree's
# twice: with KNIT_HANG_NEWTON=legacy (the old Newton loop over the new evaluation) and as it is.
#
#   tools/knit_hang_compare.sh [BASE] [STEPS] [ITERATIONS] [ROUNDS]     # defaults: 102227d 3 6 2
#
# Each probe: no relaxation, STEPS time steps of 1/240 s, at most ITERATIONS Newton iterations per step;
# the three probes are run in turn ROUNDS times (the machine is shared: compare within a round).
# Logs in ${KNIT_COMPARE_OUT:-/tmp/knit_hang_compare}/{base,legacy,new}_ROUND.log, each ending with the
# process's wall and CPU seconds (/usr/bin/time).
set -euo pipefail
base=${1:-102227d}
steps=${2:-3}
iterations=${3:-6}
rounds=${4:-2}
root=$(git rev-parse --show-toplevel)
out=${KNIT_COMPARE_OUT:-/tmp/knit_hang_compare}
mkdir -p "$out"
build() { # $1: source tree; prints the test binary
  # patch_hang is the app crate's test since issue 42, the knit crate's before.
  local package=skintight
  if [ -f "$1/crates/knit/tests/patch_hang.rs" ]; then package=skintight-knit; fi
  (cd "$1" && cargo test --release -p "$package" --test patch_hang --no-run --message-format=json 2>/dev/null) |
    sed -n 's/.*"executable":"\([^"]*patch_hang[^"]*\)".*/\1/p' | tail -1
}
base_bin="$out/patch_hang_base"
if [ -n "${KNIT_BASE_BIN:-}" ]; then
  base_bin=$KNIT_BASE_BIN # a patch_hang test binary built at BASE before
else
  tree="$out/base_tree"
  rm -rf "$tree" && mkdir -p "$tree"
  git -C "$root" archive "$base" | tar -x -C "$tree"
  ln -sfn "$root/../shared" "$out/shared"
  cp "$(CARGO_TARGET_DIR="$root/target" build "$tree")" "$base_bin"
fi
new_bin=$(build "$root")
export KNIT_HANG_RELAX=0 KNIT_HANG_NEWTON_ITERATIONS=$iterations
KNIT_HANG_SECONDS=$(python3 -c "print($steps / 240)")
export KNIT_HANG_SECONDS
cd "$root/crates/knit"
probe() { # $1: name, $2: round, then the command
  local name=$1 round=$2
  shift 2
  /usr/bin/time -f "process: %e s wall, %U s user, %S s system" "$@" benchmark --ignored --nocapture \
    >"$out/${name}_$round.log" 2>&1
}
for round in $(seq 1 "$rounds"); do
  probe base "$round" "$base_bin"
  KNIT_HANG_NEWTON=legacy probe legacy "$round" "$new_bin"
  probe new "$round" "$new_bin"
done
for round in $(seq 1 "$rounds"); do
  for run in base legacy new; do
    echo "== $run, round $round"
    grep -E 'cells:|energy alone|Newton iterations per step|Newton time|"factorizations"|"min_distance_over_diameter"|^process' \
      "$out/${run}_$round.log"
  done
done
