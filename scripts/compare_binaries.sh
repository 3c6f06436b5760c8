#!/usr/bin/env bash
# Interleaved A/B of two tomograf binaries' whole `project` command on one CT file (one
# process per run, OLD then NEW, REPEATS times): the command's own loading and render
# figures and the wall time, median of REPEATS runs each. Both must write the same
# images: the script checks.
#
#   scripts/compare_binaries.sh OLD_BINARY NEW_BINARY CT.nii[.gz] [REPEATS] [-- project flags]
#
# CT `-` projects without a CT file: the built-in phantom, or the volume of a scene given
# in the flags (`-- --scene examples/meshes.toml`).
# The flags default to `--view ap --pitch 2.6` (256² detector, SAD 1000 / SID 1500: the
# geometry of scripts/compare_plastimatch.py); flags given after `--` replace them, e.g.
# `-- --arc 0:10:36 --pitch 2.6` for an orbit. Build OLD from an earlier commit with
# `cargo build --release` in a worktree. Used for docs/datasets.md ("Loading speed") and
# docs/projector.md.
#
# BEFORE_EACH='command' runs that shell command (its output discarded) before every run,
# e.g. another tool's render, to measure tomograf right after another large process
# (docs/projector.md, "Session 28"). To compare one binary with an environment variable
# set and unset, give as OLD a two-line wrapper script: `#!/bin/sh` and
# `VAR=value exec /path/to/tomograf "$@"`.
set -euo pipefail
old=$1 new=$2 ct=$3 repeats=${4:-9}
shift $(( $# < 4 ? $# : 4 ))
[[ ${1:-} == -- ]] && shift
flags=("$@")
[[ ${#flags[@]} -eq 0 ]] && flags=(--view ap --pitch 2.6)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
declare -A load render wall
for ((r = 0; r < repeats; r++)); do
  for v in old new; do
    exe=${!v}
    [[ -n ${BEFORE_EACH:-} ]] && { bash -c "$BEFORE_EACH" >/dev/null 2>&1 || true; }
    start=$(date +%s.%N)
    ct_arg=("$ct")
    [[ $ct == - ]] && ct_arg=()
    msg=$("$exe" --threads 2 project "${ct_arg[@]}" "${flags[@]}" --format npy -o "$work/$v" 2>&1)
    end=$(date +%s.%N)
    load[$v]+="$(grep -o 'loading [0-9]* ms' <<<"$msg" | grep -o '[0-9]*') "
    render[$v]+="$(grep -o 'view(s) of [0-9×]* in [0-9.]* ms' <<<"$msg" | grep -o '[0-9.]* ms' | grep -o '[0-9.]*') "
    wall[$v]+="$(awk -v a="$start" -v b="$end" 'BEGIN { print b - a }') "
  done
done
cmp -s "$work"/old/*.npy "$work"/new/*.npy || { echo "the two binaries' images differ" >&2; exit 1; }
median() { tr ' ' '\n' | grep . | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
echo "$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores; $ct ${flags[*]}; median of $repeats interleaved runs"
for v in old new; do
  printf '%s: loading %s ms, render %s ms, whole command %.3f s\n' "$v" "$(median <<<"${load[$v]}")" \
    "$(median <<<"${render[$v]}")" "$(median <<<"${wall[$v]}")"
done
