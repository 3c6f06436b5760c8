#!/usr/bin/env bash
# Issue 47, decision 21 (docs/real-ct/decision21-RULE.txt, written before any of its settings
# was scored, before its tuning volumes on the warped sets and its qualifying sets were made):
# decision 20's lever — the blend with SART-TV from the mean given the weight W2 in place of W
# when the fits' average explains the one view below P dB — tuned and qualified on lidc
# phantoms warped by 12 and 16 mm, whose one-view profile is the real CTs'
# (docs/real-ct/warp-probe.md), with phantoms as made as the guard.
#
#   PYTHON=… PROBE_OUT=… WARP_OUT=… scripts/decision21.sh [OUT]
#
# PROBE_OUT: scripts/prior_probe.sh's folder (its sets as made, PROBE_OUT/val/POP-base);
# WARP_OUT: scripts/warp_probe.sh's folder (its sets, WARP_OUT/val, and the shipped
# checkpoint's scores on them, WARP_OUT/eval). Steps, each skipped when its output exists
# (resumable):
#   1. tuning volumes (OUT/tune; realistic_sets.sh's tuning_volumes) on the lidc phantoms warped
#      by 12 and 16 mm and the lidc and full-chest phantoms as made, 24 in all (≈ 15 min on 2
#      cores);
#   2. the grid (scripts/decision20_grid.py --decision 21 → OUT/grid.md; ≈ 2 min), after
#      checking that the shipped setting scores the warped sets' phantoms as `evaluate` did: the
#      setting with the highest mean body PSNR over the 24, if above the shipped one's; else
#      the script stops;
#   3. new sets W3 and U3 (OUT/val) and the shipped checkpoint q and r = q with the chosen
#      setting scored on them from one view (OUT/eval-q-SET, OUT/eval-r-SET; ≈ 15 min each);
#   4. the rule (scripts/validation_rule.py) → OUT/decision.md, whose last line is the verdict:
#      r is taken when (i) r − q over W3 is resolved ahead and (ii) over U3 not resolved behind
#      (validation_rule.py's own last line under (ii) names q whenever r does not also lead there).
# BIN: the tomograf binary to use (default: target/release/tomograf, built here).
# q is decision 18's setting: since decision 21 shipped its r, run this from commit 41712143.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/realistic_sets.sh
decision_setup . "${1:-decision21}"
bin=${BIN:-$bin}
probe=$(realpath "${PROBE_OUT:?set PROBE_OUT to the output folder of scripts/prior_probe.sh}")
warp=$(realpath "${WARP_OUT:?set WARP_OUT to the output folder of scripts/warp_probe.sh}")
require_decision18_q
grid_python

# 1. Tuning volumes.
for s in lidc-deform12 lidc-deform16; do tuning_volumes "$s" "$warp/val/$s"; done
for s in lidc-base full-chest-base; do tuning_volumes "$s" "$probe/val/$s"; done

# 2. The grid.
"$py" scripts/decision20_grid.py --decision 21 "$out/tune" \
    --check "lidc-deform12=$warp/eval/lidc-deform12" \
    --check "lidc-deform16=$warp/eval/lidc-deform16" | tee "$out/grid.md"
chosen=$(grep '^chosen: ' "$out/grid.md")
case "$chosen" in
    "chosen: none"*) echo "no setting is above the shipped one: q stays" | tee "$out/decision.md"; exit 0 ;;
esac

# 3. W3 and U3: new phantoms; q and r scored on them from one view.
common=(--size 64 --views 10 --split val --preset kv-flat-panel-120kvp --heterogeneity 60)
for spec in "lidc-deform12 lidc 79000 16 --deform 12" "lidc-deform16 lidc 79100 16 --deform 16" \
    "lidc-base lidc 79200 16" "full-chest-base full-chest 89000 13"; do
    read -r name profile seed augment flags <<< "$spec"
    # shellcheck disable=SC2086 # flags, word-split on purpose
    [ -f "$out/val/$name/manifest.jsonl" ] || $bin dataset -o "$out/val/$name" --phantoms 6 \
        --seed "$seed" --profile "$profile" --augment "$augment" "${common[@]}" $flags
done
qualifying_warped="lidc-deform12 lidc-deform16"
qualifying_unwarped="lidc-base full-chest-base"
qualify_one_view q "$parent"
blend_variant "$out/r" "$chosen"
qualify_one_view r "$out/r"

# 4. The rule: (i) over W3, (ii) over U3.
# shellcheck disable=SC2086 # the set lists, word-split on purpose
{
    echo "$chosen"
    echo "## Rule (i): W3 (lidc warped by 12 and 16 mm)"
    python3 scripts/validation_rule.py "$(arm q "$out/eval-q-" $qualifying_warped)" \
        "$(arm r "$out/eval-r-" $qualifying_warped)"
    echo "## Rule (ii): U3 (as made)"
    python3 scripts/validation_rule.py "$(arm q "$out/eval-q-" $qualifying_unwarped)" \
        "$(arm r "$out/eval-r-" $qualifying_unwarped)"
} | tee "$out/decision.md"
i_ok=$(sed -n '/^## Rule (i)/,/^## Rule (ii)/p' "$out/decision.md" | grep -c '^- r − q: .*(resolved, ahead)' || true)
ii_bad=$(sed -n '/^## Rule (ii)/,$p' "$out/decision.md" | grep -c '^- r − q: .*(resolved, behind)' || true)
if [ "$i_ok" = 1 ] && [ "$ii_bad" = 0 ]; then
    echo "Decision 21: r is taken ((i) resolved ahead over W3, (ii) not resolved behind over U3)."
else
    echo "Decision 21: q stays ((i) resolved ahead over W3: $i_ok; (ii) resolved behind over U3: $ii_bad)."
fi | tee -a "$out/decision.md"
