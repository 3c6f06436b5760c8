#!/usr/bin/env bash
# Issue 47, decision 13 (docs/real-ct/decision13-RULE.txt, written before its candidate was
# trained or scored): the shipped mixed checkpoint (g, 64 000 iterations) trained on with its
# own items and codes to 72 000 (h), against g, on decision 9's sets and by its rule.
#
#   scripts/decision13.sh PROBE_OUT TRAIN_SET [OUT]
#
# PROBE_OUT: the folder of `scripts/prior_probe.sh` (its validation sets, PROBE_OUT/val/SET);
# TRAIN_SET: g's training set, train-mixhet-d5 (`scripts/decision9.sh`'s, or the same 256
# items as `scripts/real_cts.sh` makes them, OUT/train-mixhet). h's run starts from a copy of
# the shipped checkpoint (a resumed run continues exactly as an unbroken one), is trained in
# OUT (≈ 25 min on 2 cores) and scored beside g (≈ 15 min each). Resumable.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/realistic_sets.sh
train=$(realpath "$2")
decision_setup "$1" "${3:-decision13}"
sets="lidc-deform8 full-chest-deform8 lidc-base full-chest-base"
unwarped="lidc-base full-chest-base"
grep -q '"iteration": 64000' "$parent/state.json" \
    || { echo "$parent is not g (64 000 iterations)" >&2; exit 1; }
grep -q '^ensemble' "$parent/config.toml" \
    && { echo "$parent averages fits from one view since decision 14: run this from the commit before" >&2; exit 1; }
if [ ! -d "$out/h" ]; then
    rm -rf "$out/h.tmp"
    mkdir -p "$out/h.tmp"
    cp -r "$parent" "$out/h.tmp/checkpoint"
    mv "$out/h.tmp" "$out/h"
fi
if [ ! -f "$out/h.done" ]; then
    $bin train "$train" -o "$out/h" --init "$parent" --resume --iterations 72000 \
        > "$out/h.log" 2>&1
    keep_parent_infer "$out/h/checkpoint/config.toml" "$parent/config.toml"
    touch "$out/h.done"
fi
score_on_sets g "$parent"
score_on_sets h "$out/h/checkpoint"
decide g "$out/eval-g-" h "$out/eval-h-"
