#!/usr/bin/env bash
# A prior chosen on validation phantoms whose statistics match real CTs' (docs/model.md,
# "Validation that looks like the real CTs"; docs/real-ct/validation-real-stats.md).
#
#   scripts/prior_realistic.sh PARENT [OUT]
#
# PARENT: the mixed checkpoint the candidates are fine-tuned from, with its optimiser state
# (session 48's 20 000-iteration model/checkpoints/lidc-full-chest:
#   git archive cbdea1da model/checkpoints/lidc-full-chest | tar -x -C /tmp).
# 1. Two validation sets matched to the five real CTs' measured statistics
#    (scripts/tissue_stats.py: section depth and width, soft-tissue spread and texture), 6
#    phantoms each: lidc seeds 71000… with --augment 16, full-chest seeds 81000… with
#    --augment 13, both --heterogeneity 60 (64³, 10 views, kv-flat-panel-120kvp).
# 2. Candidates: (a) PARENT; (c) PARENT fine-tuned (`train --init`) to 24 000 iterations on
#    its 64 training phantoms plus the same 64 shape-augmented (--augment 11); (d) the same
#    with the augmented 64 also --heterogeneity 60. Both runs side by side, one thread each.
# 3. The rule, fixed before any score (scripts/validation_rule.py): mean TomoGRAF body PSNR
#    over the two sets × 1, 2 views; a challenger replaces (a) only with a resolved paired
#    lead (95 % t over the 24 pairs); among such, the highest.
# 4. The gate for the winner (scripts/refine_grid.sh): held-20 (shipped) vs 1-20-always,
#    the same rule, from 1 and 2 views; then (added after the real CTs were scored from 5
#    views, docs/real-ct/validation-real-stats.md, decision 3) from 5 and 10 views: the
#    winner there becomes `refine_always_from_views = 5` in the checkpoint's [infer].
# About 25 min of training and 60 of scoring on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
parent=$(realpath "$1")
out=${2:-prior-realistic}
mkdir -p "$out"
out=$(realpath "$out")
cargo build --release --quiet
bin=$PWD/target/release/tomograf
export MIMALLOC_PURGE_DELAY=-1
. scripts/realistic_sets.sh
val_real_sets
train_set train-lidc 0 lidc
train_set train-fc 300000 full-chest
train_set train-aug-lidc 0 lidc --augment 11
train_set train-aug-fc 300000 full-chest --augment 11
train_mixhet
python3 scripts/merge_sets.py "$out/train-mixaug" "$out/train-lidc" "$out/train-fc" \
    "$out/train-aug-lidc" "$out/train-aug-fc"
$bin --threads 1 train "$out/train-mixaug" -o "$out/c" --init "$parent" --resume \
    --iterations 24000 > "$out/c.log" 2>&1 &
$bin --threads 1 train "$out/train-mixhet" -o "$out/d" --init "$parent" --resume \
    --iterations 24000 > "$out/d.log" 2>&1
wait
# Each run's checkpoint keeps PARENT's inference settings.
for run in c d; do
    keep_parent_infer "$out/$run/checkpoint/config.toml" "$parent/config.toml"
done
for arm in "a:$parent" "c:$out/c/checkpoint" "d:$out/d/checkpoint"; do
    IFS=: read -r name ck <<< "$arm"
    for v in val-real-lidc val-real-fc; do
        [ -f "$out/eval-$name-$v/results.csv" ] || $bin evaluate "$out/val/$v" --checkpoint "$ck" \
            --views 1,2 --no-baselines -o "$out/eval-$name-$v"
    done
done
arm() { echo "$1=$out/eval-$1-val-real-lidc,$out/eval-$1-val-real-fc"; }
python3 scripts/validation_rule.py "$(arm a)" "$(arm c)" "$(arm d)" | tee "$out/decision-checkpoint.md"
winner=$(sed -n 's/^The rule chooses: \(.\)\.$/\1/p' "$out/decision-checkpoint.md")
case $winner in a) ck=$parent ;; *) ck=$out/$winner/checkpoint ;; esac
SETTINGS="held-20 1-20-always" TOMOGRAF=$bin scripts/refine_grid.sh "$ck" "$out/val" \
    "$out/grid" 1,2 2 > "$out/grid.md"
python3 scripts/validation_rule.py "held-20=$out/grid/held-20/val-real-lidc,$out/grid/held-20/val-real-fc" \
    "1-20-always=$out/grid/1-20-always/val-real-lidc,$out/grid/1-20-always/val-real-fc" \
    | tee "$out/decision-gate.md"
SETTINGS="held-20 1-20-always" TOMOGRAF=$bin scripts/refine_grid.sh "$ck" "$out/val" \
    "$out/grid-5" 5,10 2 > "$out/grid-5.md"
python3 scripts/validation_rule.py "held-20=$out/grid-5/held-20/val-real-lidc,$out/grid-5/held-20/val-real-fc" \
    "1-20-always=$out/grid-5/1-20-always/val-real-lidc,$out/grid-5/1-20-always/val-real-fc" \
    | tee "$out/decision-gate-5.md"
