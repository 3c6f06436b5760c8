#!/usr/bin/env bash
# Issue 47, decision 12 (docs/real-ct/decision12-RULE.txt, written before its candidate was
# trained or scored): the shipped mixed checkpoint (e, 56 000 iterations) trained on with its
# own items and codes to 64 000 (g), against e, on decision 9's sets and by its rule.
#
#   scripts/decision12.sh PROBE_OUT D9_OUT D10_OUT [OUT]
#
# PROBE_OUT: the folder of `scripts/prior_probe.sh` (its validation sets); D9_OUT: that of
# `scripts/decision9.sh` (e's training set, train-mixhet-d5); D10_OUT: that of
# `scripts/decision10.sh` (e's run, OUT/e, and its scores, eval-e-*). g is trained in OUT from
# a copy of e's run (≈ 30 min on 2 cores) and scored (≈ 15 min). Resumable.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/realistic_sets.sh
d9=$(realpath "$2")
d10=$(realpath "$3")
decision_setup "$1" "${4:-decision12}"
sets="lidc-deform8 full-chest-deform8 lidc-base full-chest-base"
unwarped="lidc-base full-chest-base"
for s in $sets; do
    [ -f "$d10/eval-e-$s/results.csv" ] || { echo "run scripts/decision10.sh first" >&2; exit 1; }
done
# e's run must be the shipped checkpoint.
cmp -s "$d10/e/checkpoint/generator.bpk" "$parent/generator.bpk" \
    || { echo "$d10/e is not the shipped checkpoint" >&2; exit 1; }
if [ ! -d "$out/g" ]; then
    rm -rf "$out/g.tmp"
    cp -r "$d10/e" "$out/g.tmp"
    mv "$out/g.tmp" "$out/g"
fi
if [ ! -f "$out/g.done" ]; then
    $bin train "$d9/train-mixhet-d5" -o "$out/g" --init "$parent" --resume --iterations 64000 \
        > "$out/g.log" 2>&1
    keep_parent_infer "$out/g/checkpoint/config.toml" "$parent/config.toml"
    touch "$out/g.done"
fi
score_on_sets g "$out/g/checkpoint"
decide e "$d10/eval-e-" g "$out/eval-g-"
