#!/usr/bin/env bash
# The shipped mixed checkpoint trained longer, chosen (or not) on the validation phantoms
# matched to real CTs (docs/real-ct/validation-real-stats.md, decision 4).
#
#   scripts/prior_longer.sh [ITERATIONS] [OUT]
#
# The 24 000-iteration model/checkpoints/lidc-full-chest (candidate d of
# scripts/prior_realistic.sh; its loss was still falling) is continued (`train --init …
# --resume`, its optimiser state kept) to ITERATIONS (default 32 000) on its own training set
# (train-mixhet: 32 lidc + 32 full-chest phantoms and the same 64 with --augment 11
# --heterogeneity 60), then both are scored on the two validation sets of
# scripts/prior_realistic.sh (6 + 6 phantoms matched to the real CTs' statistics) from 1 and 2
# views, and scripts/validation_rule.py, fixed before any score, decides: the longer run
# replaces the shipped one only with a resolved paired lead in body PSNR. The shipped
# checkpoint's inference settings are kept. About 40 min of training (one thread) and 40 of
# scoring on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
iterations=${1:-32000}
out=${2:-prior-longer}
mkdir -p "$out"
out=$(realpath "$out")
parent=$PWD/model/checkpoints/lidc-full-chest
cargo build --release --quiet
bin=$PWD/target/release/tomograf
export MIMALLOC_PURGE_DELAY=-1
. scripts/realistic_sets.sh
val_real_sets
train_mixhet
# The shipped run scored on one thread while the longer one trains on the other.
score() { # NAME CHECKPOINT
    for v in val-real-lidc val-real-fc; do
        [ -f "$out/eval-$1-$v/results.csv" ] || $bin --threads 1 evaluate "$out/val/$v" \
            --checkpoint "$2" --views 1,2 --no-baselines -o "$out/eval-$1-$v"
    done
}
score shipped "$parent" > "$out/score-shipped.log" 2>&1 &
$bin --threads 1 train "$out/train-mixhet" -o "$out/longer" --init "$parent" --resume \
    --iterations "$iterations" > "$out/longer.log" 2>&1
wait
# The longer run keeps the shipped checkpoint's inference settings.
keep_parent_infer "$out/longer/checkpoint/config.toml" "$parent/config.toml"
score longer "$out/longer/checkpoint"
arm() { echo "$1=$out/eval-$1-val-real-lidc,$out/eval-$1-val-real-fc"; }
python3 scripts/validation_rule.py "$(arm shipped)" "$(arm longer)" | tee "$out/decision.md"
