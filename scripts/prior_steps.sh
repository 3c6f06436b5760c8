#!/usr/bin/env bash
# How long to train a prior (docs/model.md, "… trained on to 10 000 iterations", "… to
# 20 000", "The demo checkpoint trained on"): a checkpoint with its optimiser state against
# the same run resumed to TO iterations (a resumed run is the unbroken run), on validation
# phantoms only — the sets of `scripts/prior_mix.sh`: val-lidc (6 lidc, seeds 70000…),
# val-shape (the same, --augment 7), val-fc (6 full-chest, seeds 80000…),
# kv-flat-panel-120kvp, 1 and 2 views, the same inference settings (the checkpoint's own
# [infer], with the new iteration count). The rule, written before any score of the longer
# run is read: the higher mean TomoGRAF body PSNR over the sets and both view counts;
# paired differences with 95 % t-intervals beside it.
#
#   scripts/prior_steps.sh CHECKPOINT TRAIN TO [OUT] [SETS]
#       CHECKPOINT: a checkpoint with its optimiser state (state.json names its iteration);
#       TRAIN: its training set; TO: the iteration to train on to;
#       SETS: comma-separated, of val-lidc, val-shape, val-fc (default all three).
#   The shipped choices:
#       lidc-full-chest 5000 → 10 000 → 20 000 (TRAIN: prior_mix.sh's OUT/train-mix; the
#       5000-iteration one: git show 99b56d0a:model/checkpoints/lidc-full-chest/…);
#       demo 5000 → 10 000 on val-lidc (TRAIN: prior_mix.sh's OUT/train-lidc).
#   ≈ 6 min of training per 1000 iterations and 15 of scoring per set on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
ck0=$(realpath "$1")
train=$(realpath "$2")
to=$3
out=${4:-prior-steps}
sets=${5:-val-lidc,val-shape,val-fc}
from=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["iteration"])' "$ck0/state.json")
[ "$to" -gt "$from" ] || { echo "TO ($to) must exceed the checkpoint's $from iterations" >&2; exit 1; }
cargo build --release --quiet
bin=$PWD/target/release/tomograf
export MIMALLOC_PURGE_DELAY=-1
mkdir -p "$out"
if [ ! -d "$out/run/checkpoint" ]; then
    mkdir -p "$out/run"
    cp -r "$ck0" "$out/run/checkpoint"
    rm -f "$out/run/checkpoint/baselines.toml"
    cp "$ck0/config.toml" "$out/run/config.toml"
fi
for s in "val-lidc --seed 70000 --profile lidc" "val-shape --seed 70000 --profile lidc --augment 7" \
         "val-fc --seed 80000 --profile full-chest"; do
    set -- $s; name=$1; shift
    [[ ",$sets," == *",$name,"* ]] || continue
    [ -f "$out/$name/manifest.jsonl" ] || $bin dataset -o "$out/$name" --phantoms 6 --size 64 \
        --views 10 --split val --preset kv-flat-panel-120kvp "$@"
done
$bin train "$train" -o "$out/run" --config small --iterations "$to" --resume
# The checkpoint's inference settings, with the new iteration count.
python3 - "$out/run/checkpoint/config.toml" "$ck0/config.toml" "$from" "$to" <<'EOF2'
import re, sys
mine, shipped = (open(p).read() for p in sys.argv[1:3])
head = lambda t: t[: t.index("[infer]")]
same = lambda t: re.sub(r"(?m)^iterations = \d+$", "", head(t), count=1)
assert same(mine) == same(shipped), "the training settings differ"
new = shipped.replace(f"iterations = {sys.argv[3]}", f"iterations = {sys.argv[4]}", 1)
open(sys.argv[1], "w").write(new)
EOF2
for steps in "$from" "$to"; do
    ck=$ck0; [ "$steps" = "$to" ] && ck=$out/run/checkpoint
    for v in ${sets//,/ }; do
        [ -f "$out/eval-$steps-$v/results.csv" ] || $bin evaluate "$out/$v" --checkpoint "$ck" \
            --train-data "$train" --views 1,2 --no-baselines -o "$out/eval-$steps-$v"
    done
done
python3 - "$out" "$from" "$to" "$sets" <<'EOF2'
import csv, math, statistics as st, sys
out, a_it, b_it, sets = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4].split(",")
T95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365}
def load(steps, s, col):
    rows = csv.DictReader(open(f"{out}/eval-{steps}-{s}/results.csv"))
    return {(r["item"], r["views"]): float(r[col]) for r in rows if r["method"] == "TomoGRAF"}
def f(d):
    m, h = st.mean(d), T95[len(d) - 1] * st.stdev(d) / math.sqrt(len(d))
    return ("**%+.2f ± %.2f**" if abs(m) > h else "%+.2f ± %.2f") % (m, h)
A, B = f"{a_it} it.", f"{b_it} it."
print(f"| set, views | {A} body PSNR | {B} body PSNR | {B} − {A}, body (95 % t) "
      f"| {A} PSNR | {B} PSNR | {B} − {A} |")
print("|---|---:|---:|---:|---:|---:|---:|")
rule = {a_it: [], b_it: []}
for s in sets:
    a, b = load(a_it, s, "body_psnr_db"), load(b_it, s, "body_psnr_db")
    aw, bw = load(a_it, s, "psnr_db"), load(b_it, s, "psnr_db")
    for v in ["1", "2"]:
        ks = sorted(k for k in a if k[1] == v and k in b)
        ma, mb = st.mean(a[k] for k in ks), st.mean(b[k] for k in ks)
        rule[a_it].append(ma); rule[b_it].append(mb)
        print(f"| {s}, {v} | {ma:.2f} | {mb:.2f} | {f([b[k] - a[k] for k in ks])} | "
              f"{st.mean(aw[k] for k in ks):.2f} | {st.mean(bw[k] for k in ks):.2f} | "
              f"{f([bw[k] - aw[k] for k in ks])} |")
ma, mb = st.mean(rule[a_it]), st.mean(rule[b_it])
print(f"| mean (the rule) | {ma:.2f} | {mb:.2f} | | | | |")
print(f"\nThe rule chooses {b_it if mb > ma else a_it} iterations.")
EOF2
