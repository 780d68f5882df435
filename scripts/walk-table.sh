#!/usr/bin/env bash
# The walking table of issue 3: 20 s runs per gait and speed. Without extra options: Table II's
# parameters (`--table-ii`). Extra options replace that default: include `--table-ii` among them
# for Table II (e.g. `--estimator kf --table-ii`); without it each gait walks on its shipped
# table, `eemp walk`'s default.
# Usage: scripts/walk-table.sh [eemp binary] [output folder] [extra `eemp walk` options...]
# (prints a Markdown table)
set -euo pipefail
eemp="${1:-target/release/eemp}"
out="${2:-out/walk-table}"
shift $(( $# < 2 ? $# : 2 ))
if [ $# -eq 0 ]; then set -- --table-ii; fi
echo "| gait | speed m/s | fell | vel RMSE m/s | CoT | CoT J/m | manipulability | steps | all-stance | RTF |"
echo "|---|---|---|---|---|---|---|---|---|---|"
for gait in trot free walk; do
  for speed in 0.05 0.1 0.3 0.4 0.5 0.8 1.0; do
    dir="$out/$gait-$speed"
    "$eemp" walk --gait "$gait" --speed "$speed" --duration 20 --trace-hz 10 --out "$dir" "$@" >/dev/null
    python3 - "$dir/summary.json" "$gait" "$speed" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
f = lambda v, d=3: "–" if v is None else f"{v:.{d}f}"
fell = f"yes ({s['fell_at_s']:.1f} s)" if s["fell"] else "no"
print(f"| {sys.argv[2]} | {sys.argv[3]} | {fell} | {f(s['vel_rmse_mps'])} | {f(s['cot'])} | {f(s['cot_j_per_m'],1)} | {f(s['manipulability'],2)} | {s['steps_total']} | {f(s['all_stance_fraction'],2)} | {f(s['realtime_factor'],1)} |")
PY
  done
done
