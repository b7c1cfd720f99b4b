#!/bin/sh
# A whole ribbon study on a Slurm cluster: plan here, one array task per shard, merge here.
# Run from the repository root:  examples/slurm/study.sh [SHARDS]   (default 4)
# The shipped study: the ur5 with its six link masses ±5 % (robots/ur5/ur5.uncertainty.toml), 0.5 s.
set -eu
N=${1:-4}
RIBBON=${RIBBON:-ribbon}
export RIBBON PLAN=${PLAN:-study.plan} SHARDS=${SHARDS:-shards}
"$RIBBON" plan robots/ur5/ur5.urdf --duration 0.5 --plan "$PLAN"
sbatch --wait --array=0-$((N - 1)) examples/slurm/shard.sbatch
"$RIBBON" merge "$PLAN" "$SHARDS" --summary summary.json --csv envelope.csv --out envelope.mcap
