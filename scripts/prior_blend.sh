#!/usr/bin/env bash
# Decision 8 of docs/real-ct/validation-real-stats.md: TomoGRAF's final volume shrunk towards
# SART-TV from the mean ([infer] mean_sweeps_weight = w), scored on validation sets with the
# shipped checkpoint. For each weight, a copy of the checkpoint with that weight in [infer],
# `tomograf evaluate --no-baselines` on every set (4 shards each, JOBS at a time, one thread
# each), merged; then scripts/validation_rule.py with w = 0 (the first weight) as the shipped.
#
#   scripts/prior_blend.sh SETS OUT "0 0.2 0.4" 1,2 [JOBS]
#
# SETS: a folder of validation sets (each a folder with manifest.jsonl; scripts/realistic_sets.sh
# makes them). A set already scored for a weight (OUT/w<w>/<set>/results.csv) is kept.
# TOMOGRAF: the binary (default target/release/tomograf); CK: the checkpoint
# (default model/checkpoints/lidc-full-chest).
set -euo pipefail
sets=$(realpath "$1") out=$2 weights=$3 views=$4 jobs=${5:-$(nproc)}
bin=$(realpath "${TOMOGRAF:-target/release/tomograf}")
ck=$(realpath "${CK:-model/checkpoints/lidc-full-chest}")
mkdir -p "$out"
cmds=() merges=()
for w in $weights; do
  copy="$out/checkpoint-w$w"
  if [ ! -d "$copy" ]; then
    cp -r "$ck" "$copy.tmp"
    sed -i '/^mean_sweeps_weight/d' "$copy.tmp/config.toml"
    # The key goes right after the [infer] header, so it lands in that table.
    sed -i "s/^\[infer\]\$/[infer]\nmean_sweeps_weight = $w/" "$copy.tmp/config.toml"
    grep -q "^mean_sweeps_weight = $w\$" "$copy.tmp/config.toml"
    mv "$copy.tmp" "$copy"
  fi
  for set in "$sets"/*/; do
    [ -f "$set/manifest.jsonl" ] || continue
    name=$(basename "$set") dir="$out/w$w/$name"
    [ -f "$dir/results.csv" ] && continue
    for shard in 0 1 2 3; do
      cmds+=("$bin --threads 1 evaluate $set --checkpoint $copy --no-baselines --views $views --shard $shard/4 -o $dir")
    done
    merges+=("$bin evaluate $set -o $dir --merge")
  done
done
if [ ${#cmds[@]} -gt 0 ]; then
  printf '%s\n' "${cmds[@]}" | xargs -P "$jobs" -I{} sh -c '{} > /dev/null 2>> '"$out"'/errors.log'
  for m in "${merges[@]}"; do $m > /dev/null; done
fi
arms=()
for w in $weights; do
  dirs=$(for set in "$sets"/*/; do [ -f "$set/manifest.jsonl" ] && echo "$out/w$w/$(basename "$set")"; done | paste -sd,)
  arms+=("w$w=$dirs")
done
python3 scripts/validation_rule.py "${arms[@]}"
