#!/usr/bin/env bash
# Interleaved A/B of two tomograf binaries' whole `project` command on one CT file: the
# command's own loading figure and the wall time, median of REPEATS runs each.
#
#   scripts/compare_loading.sh OLD_BINARY NEW_BINARY CT.nii[.gz] [REPEATS] [-- extra project flags]
#
# Used for docs/datasets.md, "Loading speed" (build OLD from an earlier commit with
# `cargo build --release` in a worktree). Both must write the same image: the script checks.
set -euo pipefail
old=$1 new=$2 ct=$3 repeats=${4:-9}
shift $(( $# < 4 ? $# : 4 ))
[[ ${1:-} == -- ]] && shift
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
declare -A load wall
for ((r = 0; r < repeats; r++)); do
  for v in old new; do
    exe=${!v}
    start=$(date +%s.%N)
    msg=$("$exe" --threads 2 project "$ct" --view ap --pitch 2.6 --format npy -o "$work/$v" "$@" 2>&1)
    end=$(date +%s.%N)
    load[$v]+="$(grep -o 'loading [0-9]* ms' <<<"$msg" | grep -o '[0-9]*') "
    wall[$v]+="$(echo "$end - $start" | bc) "
  done
done
cmp -s "$work"/old/*.npy "$work"/new/*.npy || { echo "the two binaries' images differ" >&2; exit 1; }
median() { tr ' ' '\n' | grep . | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
echo "$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores; $ct; median of $repeats interleaved runs"
for v in old new; do
  printf '%s: loading %s ms, whole command %.3f s\n' "$v" "$(median <<<"${load[$v]}")" "$(median <<<"${wall[$v]}")"
done
