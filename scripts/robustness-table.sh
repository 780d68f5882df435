#!/usr/bin/env bash
# Every scenario in scenarios/ (and the flat floor) × EEMP trot and free (with their tables) and the
# model-free policy × ground truth and the Kalman filter: 20 s at 0.3 m/s. Prints a Markdown table
# of fell / velocity RMSE m/s. (A first cut of the robustness suite: no seeds, no resume.)
# Usage: scripts/robustness-table.sh [eemp binary] [output folder] [policy file]
set -euo pipefail
eemp="${1:-target/release/eemp}"
out="${2:-out/robustness-table}"
policy="${3:-policies/a1_model_free_v1.safetensors}"
echo "| scenario | EEMP trot, GT | EEMP trot, KF | EEMP free, GT | EEMP free, KF | model-free, GT | model-free, KF |"
echo "|---|---|---|---|---|---|---|"
for sc in flat scenarios/*.toml; do
  row="| $(basename "$sc" .toml) |"
  for method in trot free model-free; do
    case "$method" in
      model-free) args=(--controller model-free --policy "$policy") ;;
      *) args=(--gait "$method" --params-table "tables/a1_$method.toml") ;;
    esac
    [ "$sc" = flat ] || args+=(--scenario "$sc")
    for est in ground-truth kf; do
      dir="$out/$(basename "$sc" .toml)-$method-$est"
      "$eemp" walk "${args[@]}" --estimator "$est" --speed 0.3 --duration 20 --trace-hz 10 --out "$dir" >/dev/null
      cell=$(python3 -c "
import json,sys
s=json.load(open('$dir/summary.json'))
print(f\"fell {s['fell_at_s']:.1f} s\" if s['fell'] else f\"{s['vel_rmse_mps']:.3f}\")")
      row="$row $cell |"
    done
  done
  echo "$row"
done
