#!/usr/bin/env bash
# Measured peak memory of `tomograf evaluate` against the estimate it checks before loading
# the training set (eval/src/peak.rs `evaluation_peak_bytes`; docs/reliability.md, "Memory
# budget"): 2 lidc test items scored from 1 and 2 views, with the PCA prior of 8 and 24
# training items, at 64³ and 96³ (the baselines alone), and at 64³ with the shipped demo
# checkpoint too. Prints a markdown table.
# Usage: scripts/memory_peaks_evaluate.sh [TOMOGRAF_BIN]
set -euo pipefail
bin="$(realpath "${1:-target/release/tomograf}")"
demo="$(realpath "$(dirname "$0")/../model/checkpoints/demo")"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
echo "| grid | training items | checkpoint | estimated MiB | measured MiB | estimate / measured |"
echo "|---|---:|---|---:|---:|---:|"
run() { # label... then evaluate arguments
  local grid="$1" n="$2" ck="$3"
  shift 3
  rm -rf ev
  /usr/bin/time -v "$bin" --threads 1 evaluate "$@" --views 1,2 -o ev >out 2>err
  est=$(grep -o 'estimated peak memory [0-9]*' err | awk '{print $4}')
  kib=$(grep 'Maximum resident' err | awk '{print $6}')
  python3 -c "e=$est; m=$kib/1024; print(f'| ${grid}³ | $n | $ck | {e} | {m:.0f} | {e/m:.2f} |')"
}
for g in 64 96; do
  "$bin" --threads 1 dataset --phantoms 2 --profile lidc --size "$g" --views 10 -o "test$g" >/dev/null 2>&1
  for n in 8 24; do
    "$bin" --threads 1 dataset --phantoms "$n" --seed 100 --profile lidc --size "$g" --views 10 \
      -o "train$g-$n" >/dev/null 2>&1
    run "$g" "$n" none "test$g" --train-data "train$g-$n"
    [ "$g" = 64 ] && run "$g" "$n" demo "test$g" --train-data "train$g-$n" --checkpoint "$demo" --iterations 63
  done
done
