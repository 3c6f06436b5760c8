#!/usr/bin/env bash
# Measured peak memory of `tomograf reconstruct-classical` and `tomograf project` against
# the estimates the jobs check before they allocate (eval/src/classical.rs `peak_bytes`,
# scene/src/prepare.rs `render_peak_bytes`; docs/reliability.md, "Memory budget"). Prints
# two markdown tables: job, grid, views, estimated and measured peak (MiB, `/usr/bin/time
# -v` maximum resident set) and their ratio.
# Usage: scripts/memory_peaks.sh [TOMOGRAF_BIN] [SIZES] [VIEW_COUNTS]
#   e.g. scripts/memory_peaks.sh target/release/tomograf "128 256" "72 36"
set -euo pipefail
bin="${1:-target/release/tomograf}"
sizes=(${2:-128 256})
counts=(${3:-72 36})
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
echo "| method | grid | views of 128² | estimated MiB | measured MiB | estimate / measured |"
echo "|---|---|---:|---:|---:|---:|"
for i in "${!sizes[@]}"; do
  n="${sizes[$i]}"
  v="${counts[$i]}"
  "$bin" project --arc "0:$(python3 -c "print(360/$v)"):$v" --rows 128 --cols 128 --format npy \
    -o "$work/p$v" >/dev/null 2>&1
  for m in fdk sart sirt sart-tv; do
    /usr/bin/time -v "$bin" reconstruct-classical "$work/p$v" --method "$m" --dims "$n,$n,$n" \
      --spacing "$(python3 -c "print(400/$n)")" --iterations 2 -o "$work/r.nii.gz" \
      >"$work/out" 2>"$work/err"
    est=$(grep -o 'estimated peak memory [0-9]*' "$work/err" | awk '{print $4}')
    kib=$(grep 'Maximum resident' "$work/err" | awk '{print $6}')
    python3 -c "e=$est; m=$kib/1024; print(f'| $m | ${n}³ | $v | {e} | {m:.0f} | {e/m:.2f} |')"
  done
done
echo
echo "| project | volume | views of 256² | estimated MiB | measured MiB | estimate / measured |"
echo "|---|---|---:|---:|---:|---:|"
for i in "${!sizes[@]}"; do
  n="${sizes[$i]}"
  v="${counts[$i]}"
  for physics in "" "--preset kv-flat-panel-120kvp"; do
    /usr/bin/time -v "$bin" project --phantom-dims "$n,$n,$n" $physics \
      --arc "0:$(python3 -c "print(360/$v)"):$v" --rows 256 --cols 256 --format npy \
      -o "$work/proj" >"$work/out" 2>"$work/err"
    est=$(cat "$work/out" "$work/err" | grep -o 'estimated peak memory [0-9]*' | awk '{print $4}')
    kib=$(grep 'Maximum resident' "$work/err" | awk '{print $6}')
    kind=$([ -n "$physics" ] && echo "detector physics" || echo "ideal DRR")
    python3 -c "e=$est; m=$kib/1024; print(f'| $kind | ${n}³ | $v | {e} | {m:.0f} | {e/m:.2f} |')"
    rm -rf "$work/proj"
  done
done
