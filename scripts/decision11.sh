#!/usr/bin/env bash
# Issue 47, decision 11 (docs/real-ct/decision11-RULE.txt, written before its candidate was
# trained or scored): the shipped mixed checkpoint (e, 56 000 iterations) fine-tuned to 64 000
# on its training set plus the same 128 phantoms warped by 8 mm (f), against e, on decision
# 9's sets and by its rule.
#
#   scripts/decision11.sh PROBE_OUT D9_OUT D10_OUT [OUT]
#
# PROBE_OUT: the folder of `scripts/prior_probe.sh` (its validation sets); D9_OUT: that of
# `scripts/decision9.sh` (e's training set, train-mixhet-d5, and its parts); D10_OUT: that of
# `scripts/decision10.sh` (e's scores, eval-e-*). The 128 warped phantoms are made in OUT
# (≈ 5 min), f is trained there (≈ 35 min on 2 cores) and scored (≈ 15 min). Resumable.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/realistic_sets.sh
d9=$(realpath "$2")
d10=$(realpath "$3")
decision_setup "$1" "${4:-decision11}"
sets="lidc-deform8 full-chest-deform8 lidc-base full-chest-base"
unwarped="lidc-base full-chest-base"
for s in $sets; do
    [ -f "$d10/eval-e-$s/results.csv" ] || { echo "run scripts/decision10.sh first" >&2; exit 1; }
done
grep -q "^iterations = 56000$" "$parent/config.toml" \
    || { echo "$parent is not decision 10's e (56 000 iterations)" >&2; exit 1; }
train_set train-d8-lidc 0 lidc --deform 8
train_set train-d8-fc 300000 full-chest --deform 8
train_set train-d8-ahet-lidc 0 lidc --augment 11 --heterogeneity 60 --deform 8
train_set train-d8-ahet-fc 300000 full-chest --augment 11 --heterogeneity 60 --deform 8
[ -f "$out/train-mixhet-d58/manifest.jsonl" ] || python3 scripts/merge_sets.py \
    "$out/train-mixhet-d58" "$d9/train-lidc" "$d9/train-fc" "$d9/train-ahet-lidc" \
    "$d9/train-ahet-fc" "$d9/train-d5-lidc" "$d9/train-d5-fc" "$d9/train-d5-ahet-lidc" \
    "$d9/train-d5-ahet-fc" "$out/train-d8-lidc" "$out/train-d8-fc" "$out/train-d8-ahet-lidc" \
    "$out/train-d8-ahet-fc"
if [ ! -f "$out/f.done" ]; then
    $bin train "$out/train-mixhet-d58" -o "$out/f" --init "$parent" --resume --iterations 64000 \
        > "$out/f.log" 2>&1
    keep_parent_infer "$out/f/checkpoint/config.toml" "$parent/config.toml"
    touch "$out/f.done"
fi
score_on_sets f "$out/f/checkpoint"
decide e "$d10/eval-e-" f "$out/eval-f-"
