#!/bin/sh
# A staged ribbon study on a Slurm cluster (docs/distributed.md §7): designs that choose runs from
# earlier runs — `--method auto` at large d picks the dimension-adaptive design, `--design
# screened` screens first — run in stages. Each stage is one job array (`sbatch --array --wait`),
# then `ribbon merge`: it exits 3 after planning the next stage (its plan in SHARDS/stage-K/), and
# 0 once it has written the outputs (4 when it wrote them but its check did not trust the
# surrogate for some outputs). A fixed design is the same loop with one stage.
#
# Run from the repository root:  examples/slurm/stages.sh [SHARDS]   (default 4)
#
# PLAN (default study.plan) is made here when it does not exist, for the shipped study: the ur5
# with every value uncertain (d = 72, robots/ur5/ur5.all-values.uncertainty.toml), 0.5 s, whose
# `auto` design is dimension-adaptive. Make your own with `ribbon plan ROBOT.urdf [analyze
# options] --plan study.plan` first. Outputs: SUMMARY, CSV, MCAP (defaults summary.json,
# envelope.csv, envelope.mcap); SBATCH_FLAGS adds flags to every sbatch (e.g. a partition).
set -eu
N=${1:-4}
RIBBON=${RIBBON:-ribbon}
export RIBBON PLAN=${PLAN:-study.plan} SHARDS=${SHARDS:-shards}
if [ ! -e "$PLAN" ]; then
    "$RIBBON" plan robots/ur5/ur5.urdf --uncertainty robots/ur5/ur5.all-values.uncertainty.toml \
        --duration 0.5 --plan "$PLAN"
fi
stage=1
while :; do
    echo "stages.sh: stage $stage: $N array tasks" >&2
    # shellcheck disable=SC2086 # SBATCH_FLAGS is a list of flags
    sbatch --wait --array=0-$((N - 1)) ${SBATCH_FLAGS:-} examples/slurm/shard.sbatch
    status=0
    "$RIBBON" merge "$PLAN" "$SHARDS" --summary "${SUMMARY:-summary.json}" \
        --csv "${CSV:-envelope.csv}" --out "${MCAP:-envelope.mcap}" || status=$?
    case $status in
        0) echo "stages.sh: done after $stage stages" >&2; exit 0 ;;
        3) stage=$((stage + 1)) ;;   # the next stage is planned: run its shards
        4) echo "stages.sh: outputs written after $stage stages, but the surrogate is not trusted for some outputs (the warning above names them)" >&2; exit 4 ;;
        *) exit "$status" ;;         # 1: a failure, 2: refused input (named on stderr)
    esac
done
