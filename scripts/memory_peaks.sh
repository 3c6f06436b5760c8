#!/usr/bin/env bash
# Measured peak memory of `tomograf reconstruct-classical` and `tomograf project` against
# the estimates the jobs check before they allocate (eval/src/classical.rs `peak_bytes`,
# scene/src/prepare.rs `render_peak_bytes`; docs/reliability.md, "Memory budget"). Prints
# two markdown tables: job, grid, views, estimated and measured peak (MiB, `/usr/bin/time
# -v` maximum resident set) and their ratio.
# A third table, for `tomograf dataset` (scene/src/peak.rs `item_peak_bytes`), when CT files
# are given: one item from each CT (64³ grid, 36 views, ideal DRR; 128³, 72 views, detector
# physics; 256³, 144 views, ideal DRR) and from a lidc and a full-chest phantom.
# Usage: scripts/memory_peaks.sh [TOMOGRAF_BIN] [SIZES] [VIEW_COUNTS] [CT_FILES]
#   e.g. scripts/memory_peaks.sh target/release/tomograf "128 256" "72 36" "a.nii.gz b.nii.gz"
#   SIZES "none" skips the first two tables.
set -euo pipefail
bin="${1:-target/release/tomograf}"
sizes=(${2:-128 256})
counts=(${3:-72 36})
cts=(${4:-})
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
if [ "${2:-}" != none ]; then
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
fi

[ ${#cts[@]} -eq 0 ] && exit 0
echo
echo "| dataset item | source voxels | grid, views, physics | estimated MiB | measured MiB | estimate / measured |"
echo "|---|---:|---|---:|---:|---:|"
item() {
  local label="$1" voxels="$2" setting="$3"
  shift 3
  /usr/bin/time -v "$bin" --threads 1 dataset "$@" -o "$work/ds" >"$work/out" 2>"$work/err"
  est=$(grep -o 'estimated peak memory [0-9]*' "$work/err" | awk '{print $4}')
  kib=$(grep 'Maximum resident' "$work/err" | awk '{print $6}')
  python3 -c "e=$est; m=$kib/1024; print(f'| $label | $voxels | $setting | {e} | {m:.0f} | {e/m:.2f} |')"
  rm -rf "$work/ds"
}
for setting in "64 36" "128 72 kv-flat-panel-120kvp" "256 144"; do
  set -- $setting
  flags=(--size "$1" --views "$2")
  [ -n "${3:-}" ] && flags+=(--preset "$3")
  for ct in "${cts[@]}"; do
    voxels=$(python3 -c "import gzip,struct,sys; h=(gzip.open if sys.argv[1].endswith('.gz') else open)(sys.argv[1],'rb').read(348); d=struct.unpack('<8h',h[40:56]); print(d[1]*d[2]*d[3])" "$ct")
    item "$(basename "$ct")" "$voxels" "${1}³, $2, ${3:-ideal DRR}" "$ct" "${flags[@]}"
  done
  for profile in lidc full-chest; do
    item "$profile phantom" "–" "${1}³, $2, ${3:-ideal DRR}" --phantoms 1 --profile "$profile" "${flags[@]}"
  done
done
