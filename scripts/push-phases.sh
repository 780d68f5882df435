#!/usr/bin/env bash
# Falls under a push schedule, over the push's phase in the gait cycle.
#
# A scenario's pushes come every `every_s` seconds (4 s in scenarios/pushes*.toml), a multiple of
# the gaits' cycles (a trot's 2ΔT, a walk's 4ΔT at ΔT 0.25 s), so every push of a run meets the
# same phase of the gait, and runs that differ only in their seed (a small random start) mostly
# share it: a suite's three seeds then sample about one phase. This script shifts the first push
# by PHASES equal steps over STEP_S each (default 20 × 0.05 s = one second, a whole walk cycle)
# and prints one mark per run (F: fell, .: walked) and the count.
#
# Usage: scripts/push-phases.sh GAIT SPEED SCENARIO [eemp walk options...]
#   e.g. scripts/push-phases.sh walk 0.1 scenarios/pushes-slippery-0.3.toml --estimator kf --seed 1
# Environment: EEMP (the binary, default target/release/eemp), PHASES (20), STEP_S (0.05),
# DURATION (20), OUT (a temporary folder).
set -euo pipefail
if [ $# -lt 3 ]; then
  sed -n '2,15p' "$0" >&2
  exit 2
fi
gait=$1 speed=$2 scenario=$3
shift 3
eemp=${EEMP:-target/release/eemp}
phases=${PHASES:-20}
step=${STEP_S:-0.05}
out=${OUT:-$(mktemp -d)}
mkdir -p "$out"
first=$(sed -n 's/^first_s *= *\([0-9.]*\).*/\1/p' "$scenario")
if [ -z "$first" ] || ! grep -q '^\[push_schedule\]' "$scenario"; then
  echo "push-phases: $scenario has no [push_schedule] with first_s" >&2
  exit 2
fi
marks=""
for k in $(seq 0 $((phases - 1))); do
  at=$(python3 -c "print(round($first + $k * $step, 4))")
  scen="$out/phase-$k.toml"
  sed "s/^first_s *=.*/first_s = $at/" "$scenario" >"$scen"
  "$eemp" walk --gait "$gait" --speed "$speed" --duration "${DURATION:-20}" --scenario "$scen" \
    --trace-hz 1 --out "$out/run-$k" "$@" >/dev/null
  marks+=$(python3 -c "import json,sys; print('F' if json.load(open(sys.argv[1]))['fell'] else '.', end='')" "$out/run-$k/summary.json")
done
falls=$(echo -n "$marks" | tr -cd F | wc -c)
echo "$gait $speed $(basename "$scenario") first push at $first + k·$step s, k = 0…$((phases - 1)): $marks  falls $falls of $phases"
