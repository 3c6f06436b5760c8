#!/usr/bin/env bash
# Issue 47, decision 9 (docs/real-ct/decision9-RULE.txt, written before any candidate was
# scored): three candidates against the shipped mixed checkpoint (a), on the prior probe's
# sets where it fails as on the real CTs (W: lidc-deform8, full-chest-deform8) and as made
# (U: lidc-base, full-chest-base), 1 and 2 views, TomoGRAF body PSNR.
#
#   scripts/decision9.sh PROBE_OUT [OUT]
#
# PROBE_OUT: the folder of `scripts/prior_probe.sh` (its sets, and a's scores: its eval/).
#   b: a with [infer] mean_sweeps_weight = 0.4 (the blend with SART-TV from the mean);
#   c: a with [infer] refine_below_db = inf (the sweeps always run, from the configured start);
#   d: a fine-tuned (`train --init`) to 48 000 iterations on its training set plus the same
#      128 phantoms made with --deform 5, its parent's [infer] kept.
# Prints validation_rule.py over W and U together (rule (i)) and over U alone (rule (ii));
# the RULE file says how the two decide. b and c are scored first (≈ 40 min on 2 cores),
# then d is trained (≈ 1 h) and scored. Resumable: re-run after a kill.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/realistic_sets.sh
decision_setup "$1" "${2:-decision9}"
sets="lidc-deform8 full-chest-deform8 lidc-base full-chest-base"
unwarped="lidc-base full-chest-base"
for s in $sets; do
    [ -f "$probe/eval/$s/results.csv" ] || { echo "run scripts/prior_probe.sh $probe first" >&2; exit 1; }
done

# with_infer NAME LINE: a copy of the shipped checkpoint with LINE added to its [infer].
with_infer() {
    [ -d "$out/$1" ] && return
    rm -rf "$out/$1.tmp"
    cp -r "$parent" "$out/$1.tmp"
    python3 - "$out/$1.tmp/config.toml" "$2" <<'PY'
import sys
path, line = sys.argv[1:3]
text = open(path).read()
head, sep, tail = text.partition("[infer]\n")
assert sep, "no [infer] in " + path
key = line.split("=")[0].strip()
assert all(l.split("=")[0].strip() != key for l in tail.splitlines() if "=" in l), key
open(path, "w").write(head + sep + line + "\n" + tail)
PY
    mv "$out/$1.tmp" "$out/$1"
}
score() { # CANDIDATE CHECKPOINT
    for s in $sets; do
        [ -f "$out/eval-$1-$s/results.csv" ] || $bin evaluate "$probe/val/$s" --checkpoint "$2" \
            --views 1,2 --no-baselines -o "$out/eval-$1-$s"
    done
}
with_infer b "mean_sweeps_weight = 0.4"
with_infer c "refine_below_db = inf"
score b "$out/b"
score c "$out/c"

# d: the training set of the shipped checkpoint and the same phantoms warped by 5 mm.
train_mixhet
train_set train-d5-lidc 0 lidc --deform 5
train_set train-d5-fc 300000 full-chest --deform 5
train_set train-d5-ahet-lidc 0 lidc --augment 11 --heterogeneity 60 --deform 5
train_set train-d5-ahet-fc 300000 full-chest --augment 11 --heterogeneity 60 --deform 5
[ -f "$out/train-mixhet-d5/manifest.jsonl" ] || python3 scripts/merge_sets.py "$out/train-mixhet-d5" \
    "$out/train-lidc" "$out/train-fc" "$out/train-ahet-lidc" "$out/train-ahet-fc" \
    "$out/train-d5-lidc" "$out/train-d5-fc" "$out/train-d5-ahet-lidc" "$out/train-d5-ahet-fc"
if [ ! -f "$out/d.done" ]; then
    $bin train "$out/train-mixhet-d5" -o "$out/d" --init "$parent" --resume --iterations 48000 \
        > "$out/d.log" 2>&1
    keep_parent_infer "$out/d/checkpoint/config.toml" "$parent/config.toml"
    touch "$out/d.done"
fi
score d "$out/d/checkpoint"

# shellcheck disable=SC2086 # the set lists, word-split on purpose
{
    echo "## Rule (i): W and U together"
    python3 scripts/validation_rule.py "$(arm a "$probe/eval/" $sets)" "$(arm b "$out/eval-b-" $sets)" \
        "$(arm c "$out/eval-c-" $sets)" "$(arm d "$out/eval-d-" $sets)"
    echo "## Rule (ii): U alone"
    python3 scripts/validation_rule.py "$(arm a "$probe/eval/" $unwarped)" \
        "$(arm b "$out/eval-b-" $unwarped)" "$(arm c "$out/eval-c-" $unwarped)" \
        "$(arm d "$out/eval-d-" $unwarped)"
} | tee "$out/decision.md"
