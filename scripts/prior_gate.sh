#!/usr/bin/env bash
# The gate from two views chosen by views left out of the network's fit, for the shipped
# mixed checkpoint, on the validation phantoms matched to real CTs
# (docs/real-ct/validation-real-stats.md, decision 6).
#
#   scripts/prior_gate.sh [OUT]
#
# held-20 (the shipped [infer]: sweeps only when no view is explained, their start chosen by
# left-out views) against heldgate-20 (the same with refine_gate = "held-out": the left-out
# views also choose whether the sweeps run). Both score the two validation sets of
# scripts/prior_realistic.sh (6 + 6 phantoms) from 2 views — from 1 view nothing can be
# left out, from 5 the sweeps always run — one setting per core. The rule, fixed before
# any score (scripts/validation_rule.py): heldgate-20 replaces held-20 only with a resolved
# paired lead in body PSNR over the 12 pairs. About 15 min on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-prior-gate}
mkdir -p "$out"
out=$(realpath "$out")
ck=$PWD/model/checkpoints/lidc-full-chest
cargo build --release --quiet
bin=${TOMOGRAF:-$PWD/target/release/tomograf}
export MIMALLOC_PURGE_DELAY=-1
. scripts/realistic_sets.sh
val_real_sets
gate=$out/checkpoint-heldgate
if [ ! -d "$gate" ]; then
    cp -r "$ck" "$gate.tmp"
    sed -i 's/^\[infer\]$/[infer]\nrefine_gate = "held-out"/' "$gate.tmp/config.toml"
    grep -q '^refine_gate = "held-out"' "$gate.tmp/config.toml"
    mv "$gate.tmp" "$gate"
fi
score() { # NAME CHECKPOINT
    for v in val-real-lidc val-real-fc; do
        [ -f "$out/eval-$1-$v/results.csv" ] || $bin --threads 1 evaluate "$out/val/$v" \
            --checkpoint "$2" --views 2 --no-baselines -o "$out/eval-$1-$v"
    done
}
score held-20 "$ck" > "$out/score-held-20.log" 2>&1 &
score heldgate-20 "$gate" > "$out/score-heldgate-20.log" 2>&1
wait
arm() { echo "$1=$out/eval-$1-val-real-lidc,$out/eval-$1-val-real-fc"; }
python3 scripts/validation_rule.py "$(arm held-20)" "$(arm heldgate-20)" | tee "$out/decision.md"
