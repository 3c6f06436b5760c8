#!/usr/bin/env bash
# The data-consistency settings of TomoGRAF inference (where the sweeps start × how many)
# scored on validation phantoms, as docs/model.md ("How many sweeps", "Where the sweeps
# start") measured them:
#
#   tomograf --threads 1 study domain-shift -o data/studies/val-seed1 --scale small --seed 1 \
#       --shifts full-chest,paper-in-house --stage data --split test
#   scripts/refine_grid.sh CHECKPOINT data/studies/val-seed1/data/test OUT [VIEWS] [JOBS]
#
# Every folder under the second argument holding a manifest.jsonl is a validation set.
# For every setting and every set, runs `tomograf evaluate --refine N` with a copy of the
# checkpoint whose [infer] section holds the setting (the first setting also scores the
# baselines), JOBS processes at a time (4 shards per set), then prints per set and view
# count each method's mean PSNR and SSIM, whole volume and body, and each setting's paired
# difference from the first (mean over items ± the 95 % t-interval half-width).
# Settings (SETTINGS, space-separated), N the sweep count:
#   A-N      start from A × the network volume's attenuation (refine_start_weight = A)
#   A+B-N    ... + B × the mean training volume's (refine_start_mean_weight = B)
#   fit-N    A and B fitted to the views by least squares (refine_start = "fitted")
#   held-N   chosen among the configured start, ½ + ½ and the mean alone by views left out
#            of the network's fit (refine_start = "held-out"; one view: the configured start)
#   ...-always  any of the above with the gate open: the sweeps run whatever the views'
#            projection PSNR (refine_below_db = inf), so the start weights always apply
# (the start weights apply when no view is explained; see model/src/refine.rs).
# TOMOGRAF: the binary (default target/release/tomograf).
set -euo pipefail
ck=$1 sets=$2 out=$3 views=${4:-1,2} jobs=${5:-$(nproc)}
bin=${TOMOGRAF:-target/release/tomograf}
settings=${SETTINGS:-0.5-20 0.5+0.5-20 fit-20}
mkdir -p "$out"
first=1
cmds=()
for s in $settings; do
  core=${s%-always} gate=
  [ "$core" != "$s" ] && gate="
refine_below_db = inf"
  start=${core%-*} n=${core#*-}
  case $start in
    fit) conf='refine_start = "fitted"' ;;
    held) conf='refine_start = "held-out"' ;;
    *+*) conf="refine_start_weight = ${start%+*}
refine_start_mean_weight = ${start#*+}" ;;
    *) conf="refine_start_weight = $start" ;;
  esac
  conf="$conf$gate"
  copy="$out/checkpoint-$start${gate:+-always}"
  if [ ! -d "$copy" ]; then
    cp -r "$ck" "$copy.tmp"
    # Drop any start setting the checkpoint holds, then append this one to [infer] (last).
    sed -i '/^refine_start/d; /^refine_below_db/d' "$copy.tmp/config.toml"
    python3 - "$copy.tmp/config.toml" "$conf" <<'PY'
import sys
path, conf = sys.argv[1], sys.argv[2]
text = open(path).read()
head, sep, tail = text.partition("[infer]\n")
assert sep, "no [infer] section in " + path
# Insert right after the [infer] header, so the keys land in that table.
open(path, "w").write(head + sep + conf + "\n" + tail)
PY
    mv "$copy.tmp" "$copy"
  fi
  extra=--no-baselines; [ $first = 1 ] && extra=
  for set in "$sets"/*/; do
    [ -f "$set/manifest.jsonl" ] || continue
    name=$(basename "$set")
    for shard in 0 1 2 3; do
      cmds+=("$bin --threads 1 evaluate $set --checkpoint $copy --refine $n $extra --views $views --shard $shard/4 -o $out/$s/$name")
    done
  done
  first=0
done
printf '%s\n' "${cmds[@]}" | xargs -P "$jobs" -I{} sh -c '{} > /dev/null 2>> '"$out"'/errors.log'
python3 - "$out" $settings <<'PY'
import csv, glob, math, statistics as st, sys
from collections import defaultdict
out, settings = sys.argv[1], sys.argv[2:]
rows = defaultdict(dict)  # (set, views, method) -> {item: (psnr, ssim, body psnr, body ssim)}
for i, s in enumerate(settings):
    for f in glob.glob(f"{out}/{s}/*/items/*.csv"):
        name = f.split("/")[-3]
        for r in csv.DictReader(open(f)):
            m = r["method"]
            if m == "TomoGRAF":
                m = f"TomoGRAF {s}"
            elif i > 0:
                continue
            rows[(name, int(r["views"]), m)][r["item"]] = tuple(
                float(r[k]) for k in ("psnr_db", "ssim", "body_psnr_db", "body_ssim"))
print("| set | views | method | n | PSNR (dB) | SSIM | body PSNR (dB) | body SSIM |")
print("|---|---:|---|---:|---:|---:|---:|---:|")
for (name, v, m), x in sorted(rows.items()):
    cols = " | ".join(f"{st.mean(t[c] for t in x.values()):.{2 if c % 2 == 0 else 3}f}" for c in range(4))
    print(f"| {name} | {v} | {m} | {len(x)} | {cols} |")
# Paired differences from the first setting, over the items both scored.
T95 = {1: 12.71, 2: 4.30, 3: 3.18, 4: 2.78, 5: 2.57, 6: 2.45, 7: 2.36, 8: 2.31, 9: 2.26,
       10: 2.23, 11: 2.20, 12: 2.18, 13: 2.16, 14: 2.14, 15: 2.13}
def ci(d, p=2):
    if len(d) < 2:
        return f"{d[0]:+.{p}f}" if d else "–"
    h = T95.get(len(d) - 1, 2.0) * st.stdev(d) / math.sqrt(len(d))
    mark = " (resolved)" if abs(st.mean(d)) > h else ""
    return f"{st.mean(d):+.{p}f} ± {h:.{p}f}{mark}"
print(f"\nPaired difference from TomoGRAF {settings[0]} (dB, mean ± 95 % t-interval over items):\n")
print("| set | views | setting | PSNR | SSIM | body PSNR | body SSIM |\n|---|---:|---|---:|---:|---:|---:|")
for (name, v, m), x in sorted(rows.items()):
    if not m.startswith("TomoGRAF ") or m.startswith("TomoGRAF (") or m == f"TomoGRAF {settings[0]}":
        continue
    base = rows[(name, v, f"TomoGRAF {settings[0]}")]
    common = sorted(set(x) & set(base))
    print(f"| {name} | {v} | {m[9:]} | " + " | ".join(
        ci([x[k][c] - base[k][c] for k in common], 2 if c % 2 == 0 else 3) for c in range(4)) + " |")
PY
