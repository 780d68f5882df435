#!/usr/bin/env bash
# The learned baselines (motion imitation, model-free RL) beside EEMP (trot and free gait with
# their per-speed tables), 20 s per run, the same scenario and metrics code for every method.
# Usage: METHODS="imitation model-free trot free" scripts/baselines-vs-eemp.sh [eemp binary] [output folder] [extra `eemp walk` options...]
# Prints a Markdown table: fell / velocity RMSE m/s / CoT / manipulability / touchdowns / how
# often the diagonal (trot) and lateral (pace) leg pairs share contact state.
set -euo pipefail
eemp="${1:-target/release/eemp}"
out="${2:-out/baselines-vs-eemp}"
shift $(( $# < 2 ? $# : 2 ))
methods="${METHODS:-imitation model-free trot free}"
echo "| speed m/s | method | fell | vel RMSE m/s | CoT | manipulability | steps | diagonal pairs agree | lateral pairs agree |"
echo "|---|---|---|---|---|---|---|---|---|"
for speed in 0.1 0.3 0.5 0.8 1.0; do
  for method in $methods; do
    dir="$out/$method-$speed"
    case "$method" in
      model-free) args=(--controller model-free --policy policies/a1_model_free_v1.safetensors) ;;
      imitation) args=(--controller imitation --policy policies/a1_imitation.safetensors) ;;
      *) args=(--gait "$method" --params-table "tables/a1_$method.toml") ;;
    esac
    "$eemp" walk "${args[@]}" --speed "$speed" --duration 20 --trace-hz 100 --out "$dir" "$@" >/dev/null
    python3 - "$dir" "$method" "$speed" <<'PY'
import csv, json, sys
d, method, speed = sys.argv[1:]
s = json.load(open(f"{d}/summary.json"))
rows = list(csv.DictReader(open(f"{d}/trace.csv")))
t0, t1 = s["metrics_window_s"]  # the window the metrics are measured on
rows = [r for r in rows if t0 <= float(r["time_s"]) <= t1]
def agree(a, b):
    if not rows:
        return None
    return sum(r[f"{a}_contact"] == r[f"{b}_contact"] for r in rows) / len(rows)
def pair(p, q):
    a, b = agree(*p), agree(*q)
    return None if a is None else min(a, b)
f = lambda v, dd=3: "–" if v is None else f"{v:.{dd}f}"
pct = lambda v: "–" if v is None else f"{100 * v:.0f} %"
fell = f"yes ({s['fell_at_s']:.1f} s)" if s["fell"] else "no"
name = {"model-free": "model-free RL", "imitation": "motion imitation",
        "trot": "EEMP trot, table", "free": "EEMP free, table"}[method]
print(f"| {speed} | {name} | {fell} | {f(s['vel_rmse_mps'])} | {f(s['cot'])} | {f(s['manipulability'],2)} "
      f"| {s['steps_total']} | {pct(pair(('FR','RL'),('FL','RR')))} | {pct(pair(('FR','RR'),('FL','RL')))} |")
PY
  done
done
