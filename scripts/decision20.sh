#!/usr/bin/env bash
# Issue 47, decision 20 (docs/real-ct/decision20-RULE.txt, written before its candidate existed
# in code, before any setting was scored and before its qualifying sets were made): the
# spread-weighted blend with SART-TV from the mean given the weight W2 in place of W when the
# fits' average explains the one view below P dB ([infer] mean_sweeps_below_db,
# mean_sweeps_weight_below).
#
#   PYTHON=… D18_OUT=DECISION18_OUT scripts/decision20.sh [OUT]
#
# D18_OUT: decision 18's folder (scripts/decision18.sh), whose tune/ holds per W and U phantom the
# shipped networks' one-view volume, its fits' spread, SART-TV from the mean volume and the log
# with the volume's projection PSNR. Steps, each skipped when its output exists (resumable):
#   1. the grid (scripts/decision20_grid.py → OUT/grid.md; ≈ 1 min): the setting with the
#      highest mean body PSNR over the 24 phantoms, if above the shipped one's; else the script
#      stops;
#   2. new sets W'' and U'' (OUT/val) and the shipped checkpoint q scored on them from one view
#      (OUT/eval-q-SET; ≈ 15 min on 2 cores); with STOP_AFTER_Q=1 the script stops here;
#   3. the chosen setting as a checkpoint copy (OUT/r), scored the same way (OUT/eval-r-SET);
#   4. the rule (scripts/validation_rule.py) → OUT/decision.md.
# BIN: the tomograf binary to use (default: target/release/tomograf, built here).
# q is decision 18's setting: since decision 21 shipped its r, run this from commit 41712143.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/realistic_sets.sh
out_arg=${1:-decision20}
decision_setup . "$out_arg"
bin=${BIN:-$bin}
d18=$(realpath "${D18_OUT:?set D18_OUT to the output folder of scripts/decision18.sh}")/tune
[ -d "$d18" ] || { echo "$d18: no decision 18 tuning data" >&2; exit 1; }
require_decision18_q
grid_python

# 1. The grid.
"$py" scripts/decision20_grid.py "$d18" | tee "$out/grid.md"
chosen=$(grep '^chosen: ' "$out/grid.md")
case "$chosen" in
    "chosen: none"*) echo "no setting is above the shipped one: q stays" | tee "$out/decision.md"; exit 0 ;;
esac

# 2. W'' and U'': new phantoms, made as scripts/prior_probe.sh makes its sets; q scored on them.
qualifying_sets 78000 88000
qualify_one_view q "$parent"
[ "${STOP_AFTER_Q:-0}" = 1 ] && { echo "q scored; stopping as STOP_AFTER_Q asks"; exit 0; }

# 3. r: q with the chosen setting (S in normalised density: HU over the window's 3072 HU).
blend_variant "$out/r" "$chosen"
qualify_one_view r "$out/r"

# 4. The rule.
qualify_rule "$chosen" "''"
