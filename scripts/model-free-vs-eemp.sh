#!/usr/bin/env bash
# The model-free RL baseline beside EEMP (trot and free gait with their per-speed tables), 20 s
# per run, the same scenario and metrics code for every method.
# Usage: scripts/model-free-vs-eemp.sh [eemp binary] [output folder] [policy file] [extra `eemp walk` options...]
# (prints a Markdown table: fell / velocity RMSE m/s / CoT / manipulability / touchdowns)
set -euo pipefail
eemp="${1:-target/release/eemp}"
out="${2:-out/model-free-vs-eemp}"
policy="${3:-policies/a1_model_free.safetensors}"
shift $(( $# < 3 ? $# : 3 ))
echo "| speed m/s | method | fell | vel RMSE m/s | CoT | manipulability | steps |"
echo "|---|---|---|---|---|---|---|"
for speed in 0.1 0.3 0.5 0.8 1.0; do
  for method in model-free trot free; do
    dir="$out/$method-$speed"
    case "$method" in
      model-free) args=(--controller model-free --policy "$policy") ;;
      *) args=(--gait "$method" --params-table "tables/a1_$method.toml") ;;
    esac
    "$eemp" walk "${args[@]}" --speed "$speed" --duration 20 --trace-hz 10 --out "$dir" "$@" >/dev/null
    python3 - "$dir/summary.json" "$method" "$speed" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
f = lambda v, d=3: "–" if v is None else f"{v:.{d}f}"
fell = f"yes ({s['fell_at_s']:.1f} s)" if s["fell"] else "no"
name = {"model-free": "model-free RL", "trot": "EEMP trot, table", "free": "EEMP free, table"}[sys.argv[2]]
print(f"| {sys.argv[3]} | {name} | {fell} | {f(s['vel_rmse_mps'])} | {f(s['cot'])} | {f(s['manipulability'],2)} | {s['steps_total']} |")
PY
  done
done
