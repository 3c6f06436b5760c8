#!/usr/bin/env bash
# The shipped mixed checkpoint trained longer, chosen (or not) on the validation phantoms
# matched to real CTs (docs/real-ct/validation-real-stats.md, decisions 4 and 5).
#
#   scripts/prior_longer.sh [ITERATIONS] [OUT] [SETS]
#
# model/checkpoints/lidc-full-chest is continued to ITERATIONS (default 40 000) on its own
# training set (train-mixhet: 32 lidc + 32 full-chest phantoms and the same 64 with
# --augment 11 --heterogeneity 60) with everything it learned kept: the run folder
# OUT/longer starts as a copy of the checkpoint and its metrics, and `train --resume` goes
# on from there — generator, discriminators, optimiser states and the per-item codes (the
# resume checks that the items are the ones the codes were learned for, same ids in the
# same order). Then both are scored on the two validation sets of scripts/prior_realistic.sh
# (6 + 6 phantoms matched to the real CTs' statistics) from 1 and 2 views, and
# scripts/validation_rule.py, fixed before any score, decides: the longer run replaces the
# shipped one only with a resolved paired lead in body PSNR. About 50 min per 8000
# iterations of training (one thread) and 10 min of scoring per checkpoint on 2 cores.
# SETS: `small` (default; the 6 + 6 phantoms, decision 5) or `large` (decision 7: 18 + 18
# phantoms of the same populations on seeds of their own, val_real_sets_large; about
# 20 min of scoring per checkpoint on 2 cores).
#
# Decision 4 (24 000 → 32 000 iterations) was made with the script of commit 888f7a47,
# which continued with `train --init` and so drew fresh codes (the generator loss jumped
# 0.050 → 0.157 and took ~2000 iterations to recover); decision 5 keeps the codes.
set -euo pipefail
cd "$(dirname "$0")/.."
iterations=${1:-40000}
out=${2:-prior-longer}
sets=${3:-small}
mkdir -p "$out"
out=$(realpath "$out")
parent=$PWD/model/checkpoints/lidc-full-chest
cargo build --release --quiet
bin=$PWD/target/release/tomograf
export MIMALLOC_PURGE_DELAY=-1
. scripts/realistic_sets.sh
case $sets in
    small) val_real_sets; names="val-real-lidc val-real-fc" ;;
    large) val_real_sets_large; names="val-real-lidc-18 val-real-fc-18" ;;
    *) echo "SETS: small or large, not $sets" >&2; exit 2 ;;
esac
train_mixhet
# The shipped run scored on one thread while the longer one trains on the other.
score() { # NAME CHECKPOINT
    for v in $names; do
        [ -f "$out/eval-$1-$v/results.csv" ] || $bin --threads 1 evaluate "$out/val/$v" \
            --checkpoint "$2" --views 1,2 --no-baselines -o "$out/eval-$1-$v"
    done
}
score shipped "$parent" > "$out/score-shipped.log" 2>&1 &
if [ ! -d "$out/longer/checkpoint" ]; then
    mkdir -p "$out/longer"
    cp -r "$parent" "$out/longer/checkpoint"
    cp "$parent-metrics.csv" "$out/longer/metrics.csv"
fi
$bin --threads 1 train "$out/train-mixhet" -o "$out/longer" --resume \
    --iterations "$iterations" > "$out/longer.log" 2>&1
wait
# The longer run keeps the shipped checkpoint's inference settings (a no-op check when
# resuming its copy).
keep_parent_infer "$out/longer/checkpoint/config.toml" "$parent/config.toml"
score longer "$out/longer/checkpoint"
arm() { local s="" v; for v in $names; do s="$s,$out/eval-$1-$v"; done; echo "$1=${s#,}"; }
python3 scripts/validation_rule.py "$(arm shipped)" "$(arm longer)" | tee "$out/decision.md"
