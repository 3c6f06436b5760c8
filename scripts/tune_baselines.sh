#!/usr/bin/env bash
# The shipped checkpoint's baselines, tuned on validation phantoms (issue 48): SART-TV (from
# zero and from the mean) sweeps and TV step, PCA-MAP noise and component count, and FDK's
# ramp window, each searched on a grid and chosen by mean PSNR per view count on
#
#   val-lidc   4 lidc phantoms (seeds 70000…, disjoint from training seeds 0… and the demo's
#              test seeds 100000…), the demo's test protocol (64³, every 36° + AP + lateral,
#              kv-flat-panel-120kvp)
#
# with the mean volume and PCA-MAP prior of the checkpoint's 32 training phantoms. Writes
# OUT/tune/{baselines.toml,search.md,search.csv}; the committed copy of baselines.toml is
# model/checkpoints/demo/baselines.toml (what `tomograf demo` reads), of search.md
# docs/model-baselines/search.md. No test set is read.
#
#   scripts/tune_baselines.sh [OUT]        # about 45 min on 2 cores (resumable)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-tune-baselines}
mkdir -p "$out"
cargo build --release --quiet
bin=$PWD/target/release/tomograf
$bin dataset -o "$out/train" --phantoms 32 --size 64 --views 36 --profile lidc --split train
$bin dataset -o "$out/val-lidc" --phantoms 4 --seed 70000 --size 64 --views 10 --profile lidc \
    --split val --preset kv-flat-panel-120kvp
$bin tune-baselines "$out/val-lidc" --train-data "$out/train" --views 1,2,5,10 -o "$out/tune"
