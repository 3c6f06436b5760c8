#!/usr/bin/env bash
# Issue 47, decision 19 (docs/real-ct/decision19-RULE.txt, written before any of its volumes was
# made, before any setting was scored and before its qualifying sets were made): the one-view
# ensemble's starting codes drawn wider ([infer] ensemble_code_sd = c in {2, 3}), the
# spread-weighted blend (mean_sweeps_weight W, mean_sweeps_spread S) re-tuned to them.
#
#   D18_OUT=DECISION18_OUT scripts/decision19.sh PROBE_OUT [OUT]
#
# PROBE_OUT: the folder of `scripts/prior_probe.sh` (W and U, PROBE_OUT/val/SET); D18_OUT:
# decision 18's (scripts/decision18.sh): its tune/ holds, per W and U phantom, the shipped
# networks' one-view volume and spread with c = 1 and SART-TV from the mean volume. Steps, each
# skipped when its output exists (resumable):
#   1. tuning data (OUT/tune/cC/SET/ID): per W and U phantom and c, the one-view volume and its
#      fits' spread with c and no blend (`reconstruct --spread`); ≈ 12 min a c on 2 cores;
#   2. the grid (scripts/decision19_grid.py → OUT/grid.md): the setting with the highest mean
#      body PSNR over the 24 phantoms, if above the shipped one's; else the script stops;
#   3. new sets W'' and U'' (OUT/val), the chosen setting as a checkpoint copy (OUT/r), and the
#      shipped checkpoint q and r scored from one view (OUT/eval-q-SET, OUT/eval-r-SET;
#      ≈ 15 min each);
#   4. the rule (scripts/validation_rule.py) → OUT/decision.md.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/realistic_sets.sh
decision_setup "$1" "${2:-decision19}"
d18=$(realpath "${D18_OUT:?set D18_OUT to the output folder of scripts/decision18.sh}")/tune
[ -d "$d18" ] || { echo "$d18: no decision 18 tuning data" >&2; exit 1; }
grep -q '"iteration": 72000' "$parent/state.json" \
    && grep -q '^ensemble = 4$' "$parent/config.toml" \
    && grep -q '^ensemble_code_sd = 1.0$' "$parent/config.toml" \
    && grep -q '^mean_sweeps_weight = 0.5$' "$parent/config.toml" \
    && grep -q '^mean_sweeps_spread = 0.032552083333333336$' "$parent/config.toml" \
    || { echo "$parent is not decision 18's q (72 000 it., 4 fits, c = 1, W = 0.5, S = 100 HU)" >&2; exit 1; }
py=${PYTHON:-python3}
"$py" -c "import numpy, nibabel" \
    || { echo "decision19_grid.py needs numpy and nibabel: PYTHON=/path/to/python" >&2; exit 1; }

# 1. Tuning data on W and U, two phantoms at a time on one thread each.
one_phantom() { # C SET ITEM_DIR
    local d=$out/tune/c$1/$2/$(basename "$3")
    [ -f "$d/sd.nii.gz" ] && return
    mkdir -p "$d"
    echo "$3" > "$d/item.txt"
    $bin --threads 1 reconstruct "$3" --checkpoint "$out/c$1" --views 1 -o "$d/net.nii.gz" \
        --spread "$d/sd.tmp.nii.gz" 2> "$d/net.log"
    mv "$d/sd.tmp.nii.gz" "$d/sd.nii.gz"
}
jobs=()
for c in 2 3; do
    # c, and no blend: the grid blends the volumes itself.
    variant "$out/c$c" "s/^ensemble_code_sd = 1.0\$/ensemble_code_sd = $c.0/; /^mean_sweeps_/d"
    for s in lidc-deform8 full-chest-deform8 lidc-base full-chest-base; do
        for item in "$probe/val/$s"/[0-9]*/; do
            jobs+=("$c $s ${item%/}")
        done
    done
done
for ((i = 0; i < ${#jobs[@]}; i += 2)); do
    # shellcheck disable=SC2086 # "C SET ITEM_DIR", word-split on purpose
    one_phantom ${jobs[i]} &
    if ((i + 1 < ${#jobs[@]})); then
        # shellcheck disable=SC2086
        one_phantom ${jobs[i + 1]} &
    fi
    wait
done

# 2. The grid.
"$py" scripts/decision19_grid.py "$d18" "$out/tune" | tee "$out/grid.md"
chosen=$(grep '^chosen: ' "$out/grid.md")
case "$chosen" in
    "chosen: none"*) echo "no setting is above the shipped one: q stays" | tee "$out/decision.md"; exit 0 ;;
esac
read -r c w s_hu < <(sed -E 's/^chosen: c = ([0-9.]+), W = ([0-9.]+), S = ([0-9.]+) HU.*/\1 \2 \3/' <<< "$chosen")
# The config holds S in normalised density: HU over the window's width (3072 HU here).
s_norm=$(python3 -c "print(repr($s_hu / 3072.0))")
c_f=$(python3 -c "print(repr(float($c)))")
w_f=$(python3 -c "print(repr(float($w)))")
variant "$out/r" "s/^ensemble_code_sd = 1.0\$/ensemble_code_sd = $c_f/; s/^mean_sweeps_weight = .*/mean_sweeps_weight = $w_f/; s/^mean_sweeps_spread = .*/mean_sweeps_spread = $s_norm/"

# 3. W'' and U'': new phantoms, made as scripts/prior_probe.sh makes its sets.
qualifying_sets 78000 88000
qualify_one_view q "$parent"
qualify_one_view r "$out/r"

# 4. The rule.
qualify_rule "$chosen" "''"
