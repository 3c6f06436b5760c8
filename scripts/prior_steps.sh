#!/usr/bin/env bash
# How long to train the mixed-population prior (docs/model.md, "… trained on to 10 000
# iterations"): the 5000-iteration mixed checkpoint (as `scripts/prior_mix.sh` made it
# before 2026-11-30) against the same run resumed to 10 000 iterations (a resumed run is
# the unbroken run), on validation phantoms only — the sets of `scripts/prior_mix.sh`:
# val-lidc (6 lidc, seeds 70000…), val-shape (the same, --augment 7), val-fc (6 full-chest,
# seeds 80000…), kv-flat-panel-120kvp, 1 and 2 views, PCA-MAP and the mean volume from the
# mixed training set, the same inference settings. The rule, written before any score of
# the longer run was read: the higher mean TomoGRAF body PSNR over the three sets and both
# view counts (prior_mix.sh's rule); paired differences with 95 % t-intervals beside it.
#
#   scripts/prior_mix_steps.sh CHECKPOINT_5000 TRAIN_MIX [OUT]
#       CHECKPOINT_5000: a mixed checkpoint at 5000 iterations with its optimiser state
#       (the shipped one before 2026-11-30: git show 99b56d0a:model/checkpoints/…);
#       TRAIN_MIX: its training set (prior_mix.sh's OUT/train-mix).
#   ≈ 30 min of training and 40 of scoring on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
ck5=$(realpath "$1")
train=$(realpath "$2")
out=${3:-prior-mix-steps}
cargo build --release --quiet
bin=$PWD/target/release/tomograf
export MIMALLOC_PURGE_DELAY=-1
mkdir -p "$out"
if [ ! -d "$out/run/checkpoint" ]; then
    mkdir -p "$out/run"
    cp -r "$ck5" "$out/run/checkpoint"
    cp "$ck5/config.toml" "$out/run/config.toml"
fi
for s in "val-lidc --seed 70000 --profile lidc" "val-shape --seed 70000 --profile lidc --augment 7" \
         "val-fc --seed 80000 --profile full-chest"; do
    set -- $s; name=$1; shift
    [ -f "$out/$name/manifest.jsonl" ] || $bin dataset -o "$out/$name" --phantoms 6 --size 64 \
        --views 10 --split val --preset kv-flat-panel-120kvp "$@"
done
$bin train "$train" -o "$out/run" --config small --iterations 10000 --resume
# The 5000-iteration checkpoint's inference settings, with the new iteration count.
python3 - "$out/run/checkpoint/config.toml" "$ck5/config.toml" <<'EOF2'
import re, sys
mine, shipped = (open(p).read() for p in sys.argv[1:3])
head = lambda t: t[: t.index("[infer]")]
same = lambda t: re.sub(r"(?m)^iterations = \d+$", "", head(t), count=1)
assert same(mine) == same(shipped), "the training settings differ"
open(sys.argv[1], "w").write(shipped.replace("iterations = 5000", "iterations = 10000", 1))
EOF2
for steps in 5k 10k; do
    ck=$ck5; [ $steps = 10k ] && ck=$out/run/checkpoint
    for v in val-lidc val-shape val-fc; do
        [ -f "$out/eval-$steps-$v/results.csv" ] || $bin evaluate "$out/$v" --checkpoint "$ck" \
            --train-data "$train" --views 1,2 --no-baselines -o "$out/eval-$steps-$v"
    done
done
python3 - "$out" <<'EOF2'
import csv, math, statistics as st, sys
out = sys.argv[1]
T95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365}
def load(steps, s, col):
    rows = csv.DictReader(open(f"{out}/eval-{steps}-{s}/results.csv"))
    return {(r["item"], r["views"]): float(r[col]) for r in rows if r["method"] == "TomoGRAF"}
def f(d):
    m, h = st.mean(d), T95[len(d) - 1] * st.stdev(d) / math.sqrt(len(d))
    return ("**%+.2f ± %.2f**" if abs(m) > h else "%+.2f ± %.2f") % (m, h)
print("| set, views | 5k body PSNR | 10k body PSNR | 10k − 5k, body (95 % t) | 5k PSNR | 10k PSNR | 10k − 5k |")
print("|---|---:|---:|---:|---:|---:|---:|")
rule = {"5k": [], "10k": []}
for s in ["val-lidc", "val-shape", "val-fc"]:
    a, b = load("5k", s, "body_psnr_db"), load("10k", s, "body_psnr_db")
    aw, bw = load("5k", s, "psnr_db"), load("10k", s, "psnr_db")
    for v in ["1", "2"]:
        ks = sorted(k for k in a if k[1] == v and k in b)
        ma, mb = st.mean(a[k] for k in ks), st.mean(b[k] for k in ks)
        rule["5k"].append(ma); rule["10k"].append(mb)
        print(f"| {s}, {v} | {ma:.2f} | {mb:.2f} | {f([b[k] - a[k] for k in ks])} | "
              f"{st.mean(aw[k] for k in ks):.2f} | {st.mean(bw[k] for k in ks):.2f} | "
              f"{f([bw[k] - aw[k] for k in ks])} |")
m5, m10 = st.mean(rule["5k"]), st.mean(rule["10k"])
print(f"| mean (the rule) | {m5:.2f} | {m10:.2f} | | | | |")
print(f"\nThe rule chooses {'10 000' if m10 > m5 else '5000'} iterations.")
EOF2
