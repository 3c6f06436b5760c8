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
common="--size 64 --views 10 --split val --preset kv-flat-panel-120kvp --heterogeneity 60"
[ -f "$out/val/val-real-lidc/manifest.jsonl" ] || $bin dataset -o "$out/val/val-real-lidc" \
    --phantoms 6 --seed 71000 --profile lidc --augment 16 $common
[ -f "$out/val/val-real-fc/manifest.jsonl" ] || $bin dataset -o "$out/val/val-real-fc" \
    --phantoms 6 --seed 81000 --profile full-chest --augment 13 $common
train() { # NAME SEED PROFILE EXTRA…
    local name=$1 seed=$2 profile=$3; shift 3
    [ -f "$out/$name/manifest.jsonl" ] || $bin dataset -o "$out/$name" --phantoms 32 \
        --seed "$seed" --size 64 --views 36 --profile "$profile" --split train "$@"
}
train train-lidc 0 lidc
train train-fc 300000 full-chest
train train-ahet-lidc 0 lidc --augment 11 --heterogeneity 60
train train-ahet-fc 300000 full-chest --augment 11 --heterogeneity 60
[ -f "$out/train-mixhet/manifest.jsonl" ] || python3 scripts/merge_sets.py "$out/train-mixhet" \
    "$out/train-lidc" "$out/train-fc" "$out/train-ahet-lidc" "$out/train-ahet-fc"
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
python3 - "$out/longer/checkpoint/config.toml" "$parent/config.toml" <<'EOF'
import re, sys
mine, parent = (open(p).read() for p in sys.argv[1:3])
head = lambda t: t[: t.index("[infer]")]
same = lambda t: re.sub(r"(?m)^iterations = \d+$", "", head(t), count=1)
assert same(mine) == same(parent), "the training settings differ"
trained = re.search(r"(?m)^iterations = (\d+)$", mine).group(1)
open(sys.argv[1], "w").write(re.sub(r"(?m)^iterations = \d+$", f"iterations = {trained}", parent, count=1))
EOF
score longer "$out/longer/checkpoint"
arm() { echo "$1=$out/eval-$1-val-real-lidc,$out/eval-$1-val-real-fc"; }
python3 scripts/validation_rule.py "$(arm shipped)" "$(arm longer)" | tee "$out/decision.md"
