#!/usr/bin/env bash
# Submits a whole tomograf study to SLURM: data → train → evaluate as job arrays, each
# stage starting when the one before has succeeded on every shard, then the report
# (docs/scale-out.md). Prints the job ids; with --wait, waits for the report and exits
# with its status.
#
#   scripts/slurm/study.sh [--wait] STUDY-DIR KIND [study options…]
#   e.g. SHARDS=16 TRAIN_SHARDS=4 CPUS=8 scripts/slurm/study.sh /shared/studies/r realism-gap --scale small
#
# Environment: SHARDS (data and evaluate array size, default 4), TRAIN_SHARDS (one per
# model: 4 for realism-gap, 1 for domain-shift; default 4), CPUS (threads per task, 1),
# SBATCH_ARGS (more sbatch options: partition, time, account …), TOMOGRAF_BIN (the CLI,
# else `tomograf` on PATH). The study folder must be on a file system every node sees.
set -euo pipefail
wait=""
if [ "${1:-}" = --wait ]; then wait=--wait; shift; fi
[ $# -ge 2 ] || { sed -n '2,13p' "$0" >&2; exit 2; }
here=$(cd "$(dirname "$0")" && pwd)
shards=${SHARDS:-4} train=${TRAIN_SHARDS:-4} cpus=${CPUS:-1}
submit() { sbatch --parsable --cpus-per-task="$cpus" ${SBATCH_ARGS:-} "$@"; }
d=$(submit --array=0-$((shards - 1)) "$here/study.sbatch" data "$@")
t=$(submit --array=0-$((train - 1)) --dependency=afterok:"$d" "$here/study.sbatch" train "$@")
e=$(submit --array=0-$((shards - 1)) --dependency=afterok:"$t" "$here/study.sbatch" evaluate "$@")
r=$(submit $wait --output=tomograf-study-report-%j.out --dependency=afterok:"$e" "$here/study.sbatch" report "$@")
echo "data $d, train $t, evaluate $e, report $r"
