#!/usr/bin/env bash
# `eemp reproduce` on a Slurm cluster: the sweeps and suites split over job arrays (`--shard`),
# the trainings one task each, the rest in order. From the repository root, after
# `make mujoco && cargo build --release -p eemp-cli`:
#
#   bash scripts/reproduce-slurm.sh submit          # queues the five phases below, chained
#
# Phases (each also runs by hand: `bash scripts/reproduce-slurm.sh PHASE`, array phases under
# sbatch --array=1-N):
#   sweep-shards   array: eemp reproduce --shard K/N --stage <the sweep stages>
#   sweeps         eemp reproduce --merge-shards N --stage <the sweep stages> (merge, tables)
#   trainings      array, one training stage per task: eemp reproduce --stage train-…
#   suite-shards   array: eemp reproduce --shard K/N --stage <the suite stages>
#   rest           eemp reproduce --merge-shards N: runs every stage that is not up to date in
#                  pipeline order, a shardable one from its merged shards; a fine-tune whose
#                  starting policy was retrained beside it in the trainings phase is stale (its
#                  manifest holds the inputs it started from) and is retrained here; then the
#                  paper's page
#
# Every step resumes after a preemption or requeue; a task stopped by its time limit resumes
# when the same phase is submitted again. Environment: OUT (default out/study),
# SHARDS (N, default 8), EEMP (default target/release/eemp), PIPELINE (default reproduce.toml).
#
#SBATCH --job-name=eemp-reproduce
#SBATCH --cpus-per-task=4
#SBATCH --mem-per-cpu=1G
#SBATCH --time=02:00:00
#SBATCH --requeue
#SBATCH --output=eemp-reproduce-%x-%A_%a.out
set -euo pipefail

OUT=${OUT:-out/study}
SHARDS=${SHARDS:-8}
EEMP=${EEMP:-target/release/eemp}
PIPELINE=${PIPELINE:-reproduce.toml}

# Stage names by kind, from the pipeline file (sweeps: sweep-* and sensitivity; trainings:
# train-*; suites: the other stages with a shardable step).
stages() { awk '/^name = /{gsub(/"/,"",$3); print $3}' "$PIPELINE"; }
sweep_stages() { stages | grep -E '^(sweep-|sensitivity$)' | tr '\n' ' '; }
training_stages() { stages | grep -E '^train-'; }
suite_stages() {
    awk '/^name = /{gsub(/"/,"",$3); n=$3} /^shard = true/{print n}' "$PIPELINE" | sort -u |
        grep -vE '^(sweep-|sensitivity$|train-)' | tr '\n' ' '
}

# `--stage A --stage B …`
as_stage_args() { for s in "$@"; do printf -- '--stage %s ' "$s"; done; }

shard_of_task() {
    local first=${SLURM_ARRAY_TASK_MIN:-1}
    echo $((SLURM_ARRAY_TASK_ID - first + 1))
}

case "${1:-}" in
submit)
    # `--parsable` prints `id` or `id;cluster`: the dependency takes the id.
    a=$(sbatch --parsable --array=1-"$SHARDS" --job-name=sweep-shards "$0" sweep-shards)
    b=$(sbatch --parsable --dependency=afterok:"${a%%;*}" --job-name=sweeps "$0" sweeps)
    n=$(training_stages | wc -l)
    c=$(sbatch --parsable --dependency=afterok:"${b%%;*}" --array=1-"$n" --job-name=trainings "$0" trainings)
    d=$(sbatch --parsable --dependency=afterok:"${c%%;*}" --array=1-"$SHARDS" --job-name=suite-shards "$0" suite-shards)
    sbatch --dependency=afterok:"${d%%;*}" --time=12:00:00 --job-name=rest "$0" rest
    ;;
sweep-shards)
    : "${SLURM_ARRAY_TASK_ID:?run under sbatch --array=1-N}"
    # shellcheck disable=SC2046
    "$EEMP" reproduce --pipeline "$PIPELINE" --out "$OUT" --shard "$(shard_of_task)/$SHARDS" $(as_stage_args $(sweep_stages))
    ;;
sweeps)
    # shellcheck disable=SC2046
    "$EEMP" reproduce --pipeline "$PIPELINE" --out "$OUT" --merge-shards "$SHARDS" $(as_stage_args $(sweep_stages))
    ;;
trainings)
    : "${SLURM_ARRAY_TASK_ID:?run under sbatch --array=1-<number of training stages>}"
    stage=$(training_stages | sed -n "$(shard_of_task)p")
    "$EEMP" reproduce --pipeline "$PIPELINE" --out "$OUT" --stage "$stage"
    ;;
suite-shards)
    : "${SLURM_ARRAY_TASK_ID:?run under sbatch --array=1-N}"
    # shellcheck disable=SC2046
    "$EEMP" reproduce --pipeline "$PIPELINE" --out "$OUT" --shard "$(shard_of_task)/$SHARDS" $(as_stage_args $(suite_stages))
    ;;
rest)
    "$EEMP" reproduce --pipeline "$PIPELINE" --out "$OUT" --merge-shards "$SHARDS"
    ;;
*)
    echo "usage: $0 submit | sweep-shards | sweeps | trainings | suite-shards | rest" >&2
    exit 2
    ;;
esac
