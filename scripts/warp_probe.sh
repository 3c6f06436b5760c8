#!/usr/bin/env bash
# How far must validation phantoms be warped before SART-TV from the mean is as good as the
# shipped prior inside the body from one view, as it is on the real CTs (docs/model.md,
# "Decision 18")? Decisions 18-20 tuned and qualified on phantoms warped by 8 mm, where it
# still trails by 1-3 dB; a lever that trusts the classical estimate more where the prior is
# wrong (decision 20) cannot show there what it would do on the real CTs.
#
#   scripts/warp_probe.sh [OUT] [CHECKPOINT]
#
# The validation sets of scripts/prior_probe.sh (lidc seeds 71000…, --augment 16; full-chest
# seeds 81000…, --augment 13; 6 phantoms each, --heterogeneity 60, 64³, 10 views,
# kv-flat-panel-120kvp) warped by 8 (byte for byte prior_probe.sh's deform8), 12 and 16 mm;
# CHECKPOINT (default the shipped model/checkpoints/lidc-full-chest) and the baselines at their
# defaults score every item from one view; scripts/prior_probe_table.py tabulates TomoGRAF −
# SART-TV from the mean and the network alone − the mean volume per set. Phantoms only: no
# real CT is read. Resumable; about 35 min on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-warp-probe}
checkpoint=${2:-model/checkpoints/lidc-full-chest}
cargo build --release --quiet
bin=$PWD/target/release/tomograf
export MIMALLOC_PURGE_DELAY=-1
common=(--size 64 --views 10 --split val --preset kv-flat-panel-120kvp --heterogeneity 60)
sets=()
for mm in 8 12 16; do
    for pop in "lidc 71000 16" "full-chest 81000 13"; do
        read -r profile seed augment <<< "$pop"
        name=$profile-deform$mm
        [ -f "$out/val/$name/manifest.jsonl" ] || $bin dataset -o "$out/val/$name" --phantoms 6 \
            --seed "$seed" --profile "$profile" --augment "$augment" "${common[@]}" --deform "$mm"
        [ -f "$out/eval/$name/results.csv" ] || $bin evaluate "$out/val/$name" \
            --checkpoint "$checkpoint" --views 1 -o "$out/eval/$name"
        sets+=("$name=$out/eval/$name")
    done
done
python3 scripts/prior_probe_table.py "${sets[@]}" | tee "$out/table.md"
