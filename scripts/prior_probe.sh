#!/usr/bin/env bash
# Which phantom population makes the shipped mixed prior fail as it fails on the real CTs
# (issue 47: the network explains the views above the 30 dB gate, yet inside the body it is
# no better than SART-TV from the mean)? A validation population that does is what any
# further inference or training choice for real CTs has to be made on.
#
#   scripts/prior_probe.sh [OUT] [CHECKPOINT]
#
# The validation sets matched to the real CTs' statistics (scripts/realistic_sets.sh:
# lidc seeds 71000…, --augment 16; full-chest seeds 81000…, --augment 13; 6 phantoms each,
# --heterogeneity 60, 64³, 10 views, kv-flat-panel-120kvp), made from the same seeds four
# ways: `base` (byte for byte the sets `val-real-lidc`, `val-real-fc`), `spread2.5`
# (--organ-spread 2.5: the heart's size, offset and turn and the diaphragm domes' heights
# from ranges 2.5 times as wide), `deform5` (--deform 5: the rendered phantom warped by a
# smooth random displacement field of 5 mm standard deviation per component) and `deform8`
# (--deform 8). CHECKPOINT
# (default the shipped model/checkpoints/lidc-full-chest) and the baselines at their
# defaults score every item from 1 and 2 views (no --train-data: PCA-MAP is not scored);
# scripts/prior_probe_table.py pairs each variant with `base` item by item. Phantoms only:
# no real CT is read. About 90 min on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-prior-probe}
checkpoint=${2:-model/checkpoints/lidc-full-chest}
cargo build --release --quiet
bin=$PWD/target/release/tomograf
export MIMALLOC_PURGE_DELAY=-1
common=(--size 64 --views 10 --split val --preset kv-flat-panel-120kvp --heterogeneity 60)
sets=()
for variant in "base" "spread2.5 --organ-spread 2.5" "deform5 --deform 5" "deform8 --deform 8"; do
    read -r vname vflags <<< "$variant"
    for pop in "lidc 71000 16" "full-chest 81000 13"; do
        read -r profile seed augment <<< "$pop"
        name=$profile-$vname
        # shellcheck disable=SC2086 # vflags: the variant's flags, word-split on purpose
        [ -f "$out/val/$name/manifest.jsonl" ] || $bin dataset -o "$out/val/$name" --phantoms 6 \
            --seed "$seed" --profile "$profile" --augment "$augment" "${common[@]}" $vflags
        [ -f "$out/eval/$name/results.csv" ] || $bin evaluate "$out/val/$name" \
            --checkpoint "$checkpoint" --views 1,2 -o "$out/eval/$name"
        sets+=("$name=$out/eval/$name")
    done
done
python3 scripts/prior_probe_table.py "${sets[@]}" | tee "$out/table.md"
