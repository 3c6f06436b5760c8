#!/usr/bin/env bash
# The data-consistency settings of TomoGRAF inference (sweeps × start weight) scored on
# validation phantoms, as docs/model.md ("How many sweeps") measured them:
#
#   tomograf --threads 1 study domain-shift -o data/studies/val-seed1 --scale small --seed 1 \
#       --shifts full-chest,paper-in-house,table --stage data
#   scripts/refine_grid.sh CHECKPOINT data/studies/val-seed1/data/test OUT [VIEWS] [JOBS]
#
# For every setting w-N (start weight w when no view is explained, N sweeps) and every
# test set under the second argument, runs `tomograf evaluate --refine N` with a copy of
# the checkpoint whose [infer] refine_start_weight is w (the first setting also scores the
# baselines), JOBS processes at a time (4 shards per set), then prints mean PSNR and SSIM
# per set, view count and method. Settings: SETTINGS="0.5-10 0.75-10 0.5-20 0.75-20".
# TOMOGRAF: the binary (default target/release/tomograf).
set -euo pipefail
ck=$1 sets=$2 out=$3 views=${4:-1,2} jobs=${5:-$(nproc)}
bin=${TOMOGRAF:-target/release/tomograf}
settings=${SETTINGS:-0.5-10 0.75-10 0.5-20 0.75-20}
mkdir -p "$out"
first=1
cmds=()
for s in $settings; do
  w=${s%-*} n=${s#*-}
  copy="$out/checkpoint-w$w"
  if [ ! -d "$copy" ]; then
    cp -r "$ck" "$copy.tmp"
    sed -i "s/^refine_start_weight = .*/refine_start_weight = $w/" "$copy.tmp/config.toml"
    grep -q "^refine_start_weight = $w$" "$copy.tmp/config.toml" || echo "refine_start_weight = $w" >> "$copy.tmp/config.toml"
    mv "$copy.tmp" "$copy"
  fi
  extra=--no-baselines; [ $first = 1 ] && extra=
  for set in "$sets"/*/; do
    name=$(basename "$set")
    for shard in 0 1 2 3; do
      cmds+=("$bin --threads 1 evaluate $set --checkpoint $copy --refine $n $extra --views $views --shard $shard/4 -o $out/$s/$name")
    done
  done
  first=0
done
printf '%s\n' "${cmds[@]}" | xargs -P "$jobs" -I{} sh -c '{} > /dev/null 2>> '"$out"'/errors.log'
python3 - "$out" $settings <<'PY'
import csv, glob, os, statistics as st, sys
from collections import defaultdict
out, settings = sys.argv[1], sys.argv[2:]
rows = defaultdict(list)
for i, s in enumerate(settings):
    for f in glob.glob(f"{out}/{s}/*/items/*.csv"):
        name = f.split("/")[-3]
        for r in csv.DictReader(open(f)):
            m = r["method"]
            if m == "TomoGRAF":
                m = f"TomoGRAF w {s.split('-')[0]}, {s.split('-')[1]} sweeps"
            elif i > 0:
                continue
            rows[(name, int(r["views"]), m)].append((float(r["psnr_db"]), float(r["ssim"])))
print("| set | views | method | n | PSNR (dB) | SSIM |\n|---|---:|---|---:|---:|---:|")
for (name, v, m), x in sorted(rows.items()):
    print(f"| {name} | {v} | {m} | {len(x)} | {st.mean(a for a, _ in x):.2f} | {st.mean(b for _, b in x):.3f} |")
PY
