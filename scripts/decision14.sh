#!/usr/bin/env bash
# Issue 47, decision 14 (docs/real-ct/decision14-RULE.txt, written before its candidate was run
# on any set): from one view, four fits averaged (p: the shipped checkpoint g with [infer]
# ensemble = 4, ensemble_max_views = 1) against g's single fit, on decision 9's sets and by
# its rule, one view only (p's two-view volumes are g's by construction).
#
#   scripts/decision14.sh PROBE_OUT [OUT]
#
# PROBE_OUT: the folder of `scripts/prior_probe.sh` (its validation sets, PROBE_OUT/val/SET).
# g's scores are OUT/eval-g-SET (made here from one view when missing; decision 13's, from
# one and two views, serve as they are: the rule reads the one-view rows). p's: ≈ 8 min per
# set on 2 cores (four fits per phantom). Resumable.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/realistic_sets.sh
decision_setup "$1" "${2:-decision14}"
sets="lidc-deform8 full-chest-deform8 lidc-base full-chest-base"
unwarped="lidc-base full-chest-base"
grep -q '"iteration": 64000' "$parent/state.json" \
    || { echo "$parent is not g (64 000 iterations)" >&2; exit 1; }
grep -q '^ensemble' "$parent/config.toml" \
    && { echo "$parent already averages fits: decision 14 was taken" >&2; exit 1; }
if [ ! -d "$out/p" ]; then
    rm -rf "$out/p.tmp"
    cp -r "$parent" "$out/p.tmp"
    python3 - "$out/p.tmp/config.toml" <<'PY'
import sys
path = sys.argv[1]
head, sep, tail = open(path).read().partition("[infer]\n")
assert sep, "no [infer] in " + path
lines = "ensemble = 4\nensemble_code_sd = 1.0\nensemble_max_views = 1\n"
open(path, "w").write(head + sep + lines + tail)
PY
    mv "$out/p.tmp" "$out/p"
fi
for s in $sets; do
    [ -f "$out/eval-g-$s/results.csv" ] || $bin evaluate "$probe/val/$s" \
        --checkpoint "$parent" --views 1 --no-baselines -o "$out/eval-g-$s"
    [ -f "$out/eval-p-$s/results.csv" ] || $bin evaluate "$probe/val/$s" \
        --checkpoint "$out/p" --views 1 --no-baselines -o "$out/eval-p-$s"
done
# shellcheck disable=SC2086 # the set lists, word-split on purpose
{
    echo "## Rule (i): W and U together, one view"
    python3 scripts/validation_rule.py --views 1 \
        "$(arm g "$out/eval-g-" $sets)" "$(arm p "$out/eval-p-" $sets)"
    echo "## Rule (ii): U alone, one view"
    python3 scripts/validation_rule.py --views 1 \
        "$(arm g "$out/eval-g-" $unwarped)" "$(arm p "$out/eval-p-" $unwarped)"
} | tee "$out/decision.md"
