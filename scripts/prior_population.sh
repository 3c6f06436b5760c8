#!/usr/bin/env bash
# Another training population for a trained prior (docs/model.md, "A shape-augmented
# population, fine-tuned: rejected on validation"): a checkpoint with its optimiser state
# against (b) the same run resumed on its own training set to TO iterations and (c) the
# checkpoint fine-tuned (`train --init`) on TRAIN_NEW to TO iterations, on validation phantoms
# only — the sets of `scripts/prior_steps.sh` (val-lidc, val-shape, val-fc; 6 each, 1 and 2
# views, the checkpoint's own [infer] settings, --no-baselines). The rule, written before any
# score: the highest mean TomoGRAF body PSNR over the sets and both view counts; paired
# differences with 95 % t-intervals beside it.
#
#   scripts/prior_population.sh CHECKPOINT TRAIN TRAIN_NEW TO [OUT]
#       CHECKPOINT: a checkpoint with its optimiser state; TRAIN: its training set;
#       TRAIN_NEW: the other population (a data set made alike: same size, preset, window);
#       TO: the iteration both runs train on to.
#   Session 48's run: model/checkpoints/lidc-full-chest (20 000 it.), TRAIN = prior_mix.sh's
#   train-mix, TRAIN_NEW = train-mix with the same 64 phantoms again shape-augmented
#   (`tomograf dataset … --augment 11`, merged by scripts/merge_sets.py), TO = 24000.
#   ≈ 6 min of training per 1000 iterations per run and 15 of scoring per set on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
ck0=$(realpath "$1")
train=$(realpath "$2")
train_new=$(realpath "$3")
to=$4
out=${5:-prior-population}
cargo build --release --quiet
bin=$PWD/target/release/tomograf
export MIMALLOC_PURGE_DELAY=-1
mkdir -p "$out"
for s in "val-lidc --seed 70000 --profile lidc" "val-shape --seed 70000 --profile lidc --augment 7" \
         "val-fc --seed 80000 --profile full-chest"; do
    set -- $s; name=$1; shift
    [ -f "$out/$name/manifest.jsonl" ] || $bin dataset -o "$out/$name" --phantoms 6 --size 64 \
        --views 10 --split val --preset kv-flat-panel-120kvp "$@"
done
if [ ! -d "$out/resumed/checkpoint" ]; then
    mkdir -p "$out/resumed"
    cp -r "$ck0" "$out/resumed/checkpoint"
    rm -f "$out/resumed/checkpoint/baselines.toml"
fi
# The two runs side by side, one thread each.
$bin --threads 1 train "$train" -o "$out/resumed" --resume --iterations "$to" &
$bin --threads 1 train "$train_new" -o "$out/fine-tuned" --init "$ck0" --resume --iterations "$to"
wait
# Each run's checkpoint keeps the shipped inference settings.
for run in resumed fine-tuned; do
    python3 - "$out/$run/checkpoint/config.toml" "$ck0/config.toml" "$to" <<'EOF2'
import re, sys
mine, shipped = (open(p).read() for p in sys.argv[1:3])
head = lambda t: t[: t.index("[infer]")]
same = lambda t: re.sub(r"(?m)^iterations = \d+$", "", head(t), count=1)
assert same(mine) == same(shipped), "the training settings differ"
new = re.sub(r"(?m)^iterations = \d+$", f"iterations = {sys.argv[3]}", shipped, count=1)
open(sys.argv[1], "w").write(new)
EOF2
done
for arm in "checkpoint:$ck0:$train" "resumed:$out/resumed/checkpoint:$train" \
           "fine-tuned:$out/fine-tuned/checkpoint:$train_new"; do
    IFS=: read -r name ck data <<< "$arm"
    for v in val-lidc val-shape val-fc; do
        [ -f "$out/eval-$name-$v/results.csv" ] || $bin evaluate "$out/$v" --checkpoint "$ck" \
            --train-data "$data" --views 1,2 --no-baselines -o "$out/eval-$name-$v"
    done
done
python3 - "$out" <<'EOF2' | tee "$out/validation.md"
import csv, math, statistics as st, sys
out = sys.argv[1]
T95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365}
arms = ["checkpoint", "resumed", "fine-tuned"]
def load(arm, s):
    rows = csv.DictReader(open(f"{out}/eval-{arm}-{s}/results.csv"))
    return {(r["item"], r["views"]): float(r["body_psnr_db"]) for r in rows if r["method"] == "TomoGRAF"}
def f(d):
    m, h = st.mean(d), T95[len(d) - 1] * st.stdev(d) / math.sqrt(len(d))
    return ("**%+.2f ± %.2f**" if abs(m) > h else "%+.2f ± %.2f") % (m, h)
print("| set, views | (a) checkpoint, body PSNR | (b) resumed | (c) fine-tuned on TRAIN_NEW "
      "| b − a (95 % t) | c − a | c − b |")
print("|---|---:|---:|---:|---:|---:|---:|")
rule = {a: [] for a in arms}
for s in ["val-lidc", "val-shape", "val-fc"]:
    d = {a: load(a, s) for a in arms}
    for v in ["1", "2"]:
        ks = sorted(k for k in d["checkpoint"] if k[1] == v)
        m = [st.mean(d[a][k] for k in ks) for a in arms]
        for a, x in zip(arms, m):
            rule[a].append(x)
        diff = lambda x, y: f([d[x][k] - d[y][k] for k in ks])
        print(f"| {s}, {v} | {m[0]:.2f} | {m[1]:.2f} | {m[2]:.2f} | "
              f"{diff('resumed', 'checkpoint')} | {diff('fine-tuned', 'checkpoint')} | "
              f"{diff('fine-tuned', 'resumed')} |")
means = {a: st.mean(rule[a]) for a in arms}
print("| mean (the rule) | " + " | ".join(f"{means[a]:.2f}" for a in arms) + " | | | |")
print(f"\nThe rule chooses: {max(arms, key=means.get)}.")
EOF2
