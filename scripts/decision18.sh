#!/usr/bin/env bash
# Issue 47, decision 18 (docs/real-ct/decision18-RULE.txt, written before its candidate existed
# in code, before any setting was scored and before its qualifying sets were made): SART-TV
# from the mean blended in voxel by voxel where the shipped checkpoint's four one-view fits
# disagree ([infer] mean_sweeps_weight W, mean_sweeps_spread S).
#
#   scripts/decision18.sh PROBE_OUT [OUT]
#
# PROBE_OUT: the folder of `scripts/prior_probe.sh` (W and U, PROBE_OUT/val/SET). Steps, each
# skipped when its output exists (resumable):
#   1. tuning data (OUT/tune/SET/ID): per W and U phantom, the shipped checkpoint's one-view
#      volume and its fits' spread (`reconstruct --spread`), and SART-TV from its mean volume
#      (the same checkpoint with ensemble = 1 and mean_sweeps_weight = 1); ≈ 20 min on 2 cores;
#   2. the grid (scripts/decision18_grid.py → OUT/grid.md): the setting with the highest mean
#      body PSNR over the 24 phantoms, if above the shipped one's; else the script stops;
#   3. new sets W' and U' (OUT/val), the chosen setting as a checkpoint copy (OUT/r), and both
#      checkpoints scored from one view (OUT/eval-q-SET, OUT/eval-r-SET; ≈ 20 min each);
#   4. the rule (scripts/validation_rule.py) → OUT/decision.md.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/realistic_sets.sh
decision_setup "$1" "${2:-decision18}"
grep -q '"iteration": 72000' "$parent/state.json" && grep -q '^ensemble = 4$' "$parent/config.toml" \
    || { echo "$parent is not decision 17's q (72 000 iterations, ensemble = 4)" >&2; exit 1; }
# Since decision 18 the shipped checkpoint carries r's setting: q is the commit before (e826753a).
! grep -q '^mean_sweeps_spread' "$parent/config.toml" \
    || { echo "$parent already carries decision 18's blend: run this from commit e826753a" >&2; exit 1; }
py=${PYTHON:-python3}
"$py" -c "import numpy, nibabel" \
    || { echo "decision18_grid.py needs numpy and nibabel: PYTHON=/path/to/python" >&2; exit 1; }

# SART-TV from the mean alone: one fit (its volume is not used) and the blend's weight 1.
variant "$out/classical" 's/^ensemble = 4$/ensemble = 1/; $a mean_sweeps_weight = 1.0'

# 1. Tuning data on W and U, two phantoms at a time on one thread each.
one_phantom() { # SET ITEM_DIR
    local d=$out/tune/$1/$(basename "$2")
    [ -f "$d/classical.nii.gz" ] && return
    mkdir -p "$d"
    echo "$2" > "$d/item.txt"
    $bin --threads 1 reconstruct "$2" --checkpoint "$parent" --views 1 -o "$d/net.nii.gz" \
        --spread "$d/sd.nii.gz" 2> "$d/net.log"
    $bin --threads 1 reconstruct "$2" --checkpoint "$out/classical" --views 1 --iterations 1 \
        -o "$d/classical.tmp.nii.gz" 2> "$d/classical.log"
    mv "$d/classical.tmp.nii.gz" "$d/classical.nii.gz"
}
tuning="lidc-deform8 full-chest-deform8 lidc-base full-chest-base"
jobs=()
for s in $tuning; do
    for item in "$probe/val/$s"/[0-9]*/; do
        jobs+=("$s ${item%/}")
    done
done
for ((i = 0; i < ${#jobs[@]}; i += 2)); do
    # shellcheck disable=SC2086 # "SET ITEM_DIR", word-split on purpose
    one_phantom ${jobs[i]} &
    if ((i + 1 < ${#jobs[@]})); then
        # shellcheck disable=SC2086
        one_phantom ${jobs[i + 1]} &
    fi
    wait
done

# 2. The grid. CHECK: decision 17's scores of the same checkpoint on the same sets, if given.
"$py" scripts/decision18_grid.py "$out/tune" ${D17_OUT:+"$D17_OUT"} | tee "$out/grid.md"
chosen=$(grep '^chosen: ' "$out/grid.md")
case "$chosen" in
    "chosen: none"*) echo "no setting is above the shipped one: q stays" | tee "$out/decision.md"; exit 0 ;;
esac
w=$(sed -E 's/^chosen: W = ([0-9.]+), S = ([0-9.]+) HU.*/\1/' <<< "$chosen")
s_hu=$(sed -E 's/^chosen: W = ([0-9.]+), S = ([0-9.]+) HU.*/\2/' <<< "$chosen")
# The config holds S in normalised density: HU over the window's width (3072 HU here).
s_norm=$(python3 -c "print(repr($s_hu / 3072.0))")
variant "$out/r" "\$a mean_sweeps_weight = $w\nmean_sweeps_spread = $s_norm"

# 3. W' and U': new phantoms, made as scripts/prior_probe.sh makes its sets.
common=(--size 64 --views 10 --split val --preset kv-flat-panel-120kvp --heterogeneity 60)
for variant_flags in "base" "deform8 --deform 8"; do
    read -r vname vflags <<< "$variant_flags"
    for pop in "lidc 77000 16" "full-chest 87000 13"; do
        read -r profile seed augment <<< "$pop"
        # shellcheck disable=SC2086 # vflags, word-split on purpose
        [ -f "$out/val/$profile-$vname/manifest.jsonl" ] || $bin dataset -o "$out/val/$profile-$vname" \
            --phantoms 6 --seed "$seed" --profile "$profile" --augment "$augment" "${common[@]}" $vflags
    done
done
warped="lidc-deform8 full-chest-deform8"
unwarped="lidc-base full-chest-base"
for s in $warped $unwarped; do
    for arm in q:"$parent" r:"$out/r"; do
        [ -f "$out/eval-${arm%%:*}-$s/results.csv" ] || $bin evaluate "$out/val/$s" \
            --checkpoint "${arm#*:}" --views 1 --no-baselines -o "$out/eval-${arm%%:*}-$s"
    done
done

# 4. The rule.
# shellcheck disable=SC2086 # the set lists, word-split on purpose
{
    echo "$chosen"
    echo "## Rule (i): W' and U' together"
    python3 scripts/validation_rule.py "$(arm q "$out/eval-q-" $warped $unwarped)" \
        "$(arm r "$out/eval-r-" $warped $unwarped)"
    echo "## Rule (ii): U' alone"
    python3 scripts/validation_rule.py "$(arm q "$out/eval-q-" $unwarped)" "$(arm r "$out/eval-r-" $unwarped)"
} | tee "$out/decision.md"
