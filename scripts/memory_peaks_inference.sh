#!/usr/bin/env bash
# Measured peak memory of `tomograf reconstruct` (TomoGRAF inference) against the estimate
# it checks before the fit (model/src/config.rs `inference_peak_bytes`; docs/reliability.md,
# "Memory budget"). Two fields (hidden 64, 16 samples, inference patches of 16²; hidden
# 256, 64 samples, patches of 64²: 4 096 and 262 144 points per step), each trained for 2
# iterations on lidc phantoms at 64³ and 96³, and the `tiny` preset's field (hidden 32, 8
# samples, whole views) at 16³, 32³ and 64³, reconstruct 63 iterations (3 of them tune the
# generator on the large patch) from 1 and 2 views. Prints a markdown table.
# Usage: scripts/memory_peaks_inference.sh [TOMOGRAF_BIN]
set -euo pipefail
bin="$(realpath "${1:-target/release/tomograf}")"
demo="$(realpath "$(dirname "$0")/../model/checkpoints/demo/config.toml")"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
config() { # name hidden samples patch
  python3 - "$demo" "$@" <<'PY'
import re, sys
demo, name, hidden, samples, patch = sys.argv[1:]
s = open(demo).read()
s = re.sub(r'(?m)^hidden = \d+', f'hidden = {hidden}', s)
s = re.sub(r'(?m)^samples = \d+', f'samples = {samples}', s)
s = re.sub(r'(?m)^iterations = \d+', 'iterations = 2', s, count=1)
head, infer = s.split('[infer]')
infer = re.sub(r'(?m)^patch = \d+', f'patch = {patch}', infer)
open(f'{name}.toml', 'w').write(head + '[infer]' + infer)
PY
}
config small-field 64 16 16
config large-field 256 64 64
python3 - "$(dirname "$demo")/../../presets/tiny.toml" <<'PY'
import re, sys
s = open(sys.argv[1]).read()
open('tiny.toml', 'w').write(re.sub(r'(?m)^iterations = \d+', 'iterations = 2', s, count=1))
PY
echo "| field | grid | views | estimated MiB | measured MiB | estimate / measured |"
echo "|---|---|---:|---:|---:|---:|"
for set in "64 small-field large-field" "96 small-field large-field" "16 tiny" "32 tiny" "64 tiny"; do
  read -r n fields <<<"$set"
  [ -d "d$n" ] || "$bin" --threads 1 dataset --phantoms 2 --profile lidc --size "$n" --views 10 -o "d$n" >/dev/null 2>&1
  for field in $fields; do
    "$bin" --threads 1 train "d$n" -o "t-$field-$n" --config "$field.toml" >/dev/null 2>&1
    for v in 1 2; do
      /usr/bin/time -v "$bin" --threads 1 reconstruct "d$n/00000" --checkpoint "t-$field-$n/checkpoint" \
        --views "$v" --iterations 63 -o rec >out 2>err
      est=$(grep -o 'estimated peak memory [0-9]*' err | awk '{print $4}')
      kib=$(grep 'Maximum resident' err | awk '{print $6}')
      python3 -c "e=$est; m=$kib/1024; print(f'| $field | ${n}³ | $v | {e} | {m:.0f} | {e/m:.2f} |')"
    done
  done
done
