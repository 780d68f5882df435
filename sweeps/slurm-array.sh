#!/usr/bin/env bash
# The EEMP parameter study on a Slurm cluster: one job-array task per shard of the run list,
# each into its own folder, then one merge + report.
#
# From the repository root, after `make mujoco && cargo build --release -p eemp-cli`:
#
#   jid=$(sbatch --parsable sweeps/slurm-array.sh)                      # tasks 1..N: the shards
#   sbatch --dependency=afterok:$jid --wrap "bash sweeps/slurm-array.sh merge"   # then merge
#
# or run the merge by hand once every task has finished:
#
#   bash sweeps/slurm-array.sh merge      # eemp sweep merge OUT/shard-* --out OUT/merged
#                                         # eemp sweep report OUT/merged
#
# Task K of N runs `eemp sweep --shard K/N --out OUT/shard-K`: run i of the sorted run list
# belongs to shard i % N + 1, so the shards are disjoint, cover the grid and get a similar mix
# of gaits and speeds. A task that is preempted, requeued or resubmitted resumes where it
# stopped (finished runs are kept). N is the size of the array: change --array (and nothing
# else) to use more or fewer nodes. Environment overrides: CONFIG, OUT, EEMP.
#
# Size: sweeps/paper.toml has 2048 runs of ~1 s CPU each; 8 tasks × 4 CPUs finish in ~2 min.
#
#SBATCH --job-name=eemp-sweep
#SBATCH --array=1-8
#SBATCH --cpus-per-task=4
#SBATCH --mem-per-cpu=500M
#SBATCH --time=00:30:00
#SBATCH --requeue
#SBATCH --output=eemp-sweep-%A_%a.out

set -euo pipefail

CONFIG=${CONFIG:-sweeps/paper.toml}
OUT=${OUT:-out/paper}
EEMP=${EEMP:-target/release/eemp}

if [[ "${1:-}" == "merge" ]]; then
    "$EEMP" sweep merge "$OUT"/shard-* --out "$OUT/merged"
    "$EEMP" sweep report "$OUT/merged"
    exit 0
fi

: "${SLURM_ARRAY_TASK_ID:?submit with sbatch as a job array, or run with the argument 'merge'}"
first=${SLURM_ARRAY_TASK_MIN:-1}
count=${SLURM_ARRAY_TASK_COUNT:-$((SLURM_ARRAY_TASK_MAX - first + 1))}
shard=$((SLURM_ARRAY_TASK_ID - first + 1))

echo "task $SLURM_ARRAY_TASK_ID on $(hostname): shard $shard/$count of $CONFIG into $OUT/shard-$shard"
"$EEMP" sweep --config "$CONFIG" --out "$OUT/shard-$shard" --shard "$shard/$count" \
    --threads "${SLURM_CPUS_PER_TASK:-1}"
