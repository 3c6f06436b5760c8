#!/usr/bin/env bash
# Measured peak memory of `tomograf train` against the estimate it checks before loading
# its data set (eval/src/peak.rs `training_peak_bytes`; docs/reliability.md, "Memory
# budget"). Four fields derived from the `small` preset (hidden × samples per ray × patch ×
# batch; `small-gan` also trains its discriminators), each trained for 2 iterations on two
# data sets (8 lidc phantoms at 64³ and 32 at 96³, 36 views each) and on 16 at 128³, then the
# `tiny` preset's field on 8 phantoms at 16³, 32³ and 64³ (every row is in the fit). Prints a
# markdown table.
# Usage: scripts/memory_peaks_train.sh [TOMOGRAF_BIN]
set -euo pipefail
bin="$(realpath "${1:-target/release/tomograf}")"
presets="$(realpath "$(dirname "$0")/../model/presets")"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
config() { # name preset hidden samples patch batch (the preset's own where empty)
  python3 - "$presets" "$@" <<'PY'
import re, sys
presets, name, preset, hidden, samples, patch, batch = sys.argv[1:]
s = open(f"{presets}/{preset}.toml").read()
head, sep, infer = s.partition('[infer]')
for key, v in [("hidden", hidden), ("samples", samples), ("patch", patch), ("batch", batch)]:
    if not v:
        continue
    head, n = re.subn(rf'(?m)^{key} = \d+', f'{key} = {v}', head)
    assert n == 1, key
head = re.sub(r'(?m)^iterations = \d+', 'iterations = 2', head, count=1)
open(f'{name}.toml', 'w').write(head + sep + infer)
PY
}
config small small 128 32 16 4
config narrow small 64 16 16 4
config wide small 256 64 16 8
config small-gan small-gan 128 32 16 4
config tiny tiny "" "" "" ""
echo "| config | hidden, samples, patch, batch | data set | estimated MiB | measured MiB | estimate / measured |"
echo "|---|---|---|---:|---:|---:|"
for set in "8 64 small narrow wide small-gan" "32 96 small narrow wide small-gan" \
  "16 128 small narrow wide small-gan" "8 16 tiny" "8 32 tiny" "8 64 tiny"; do
  read -r count n configs <<<"$set"
  [ -d "d$n" ] || "$bin" --threads 1 dataset --phantoms "$count" --profile lidc --size "$n" --views 36 -o "d$n" >/dev/null 2>&1
  for c in $configs; do
    rm -rf "t-$c"
    /usr/bin/time -v "$bin" --threads 1 train "d$n" -o "t-$c" --config "$c.toml" >out 2>err || { cat err >&2; exit 1; }
    est=$(grep -o 'estimated peak memory [0-9]*' err out | head -1 | awk '{print $4}' || true)
    kib=$(grep 'Maximum resident' err | awk '{print $6}')
    sizes=$(python3 -c "import re; s=open('$c.toml').read(); print(', '.join(re.search(rf'(?m)^{k} = (\d+)', s).group(1) for k in ['hidden','samples','patch','batch']))")
    python3 -c "e='${est:-nan}'; m=$kib/1024; print(f'| $c | $sizes | $count × ${n}³ | {e} | {m:.0f} | {float(e)/m:.2f} |')"
  done
done
