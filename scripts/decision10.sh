#!/usr/bin/env bash
# Issue 47, decision 10 (docs/real-ct/decision10-RULE.txt, written before its candidate was
# scored): decision 9's fine-tune d trained on to 56 000 iterations (e), against the shipped
# mixed checkpoint (a), on decision 9's sets and by its rule.
#
#   scripts/decision10.sh PROBE_OUT D9_OUT [OUT]
#
# PROBE_OUT: the folder of `scripts/prior_probe.sh` (its sets, and a's scores: its eval/);
# D9_OUT: that of `scripts/decision9.sh` (d's run and its training set). e is trained in OUT
# from a copy of d's run (≈ 30 min on 2 cores) and scored (≈ 15 min). Resumable.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/realistic_sets.sh
d9=$(realpath "$2")
decision_setup "$1" "${3:-decision10}"
[ -f "$d9/d.done" ] || { echo "run scripts/decision9.sh $d9 first" >&2; exit 1; }
if [ ! -d "$out/e" ]; then
    rm -rf "$out/e.tmp"
    cp -r "$d9/d" "$out/e.tmp"
    mv "$out/e.tmp" "$out/e"
fi
if [ ! -f "$out/e.done" ]; then
    $bin train "$d9/train-mixhet-d5" -o "$out/e" --init "$parent" --resume --iterations 56000 \
        > "$out/e.log" 2>&1
    keep_parent_infer "$out/e/checkpoint/config.toml" "$parent/config.toml"
    touch "$out/e.done"
fi
sets="lidc-deform8 full-chest-deform8 lidc-base full-chest-base"
unwarped="lidc-base full-chest-base"
score_on_sets e "$out/e/checkpoint"
decide a "$probe/eval/" e "$out/eval-e-"
