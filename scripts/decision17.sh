#!/usr/bin/env bash
# Issue 47, decision 17 (docs/real-ct/decision17-RULE.txt, written before its candidate was
# trained or scored and before its new sets were made): the shipped checkpoint (p) fine-tuned
# to 72 000 iterations on its training set plus 64 phantoms cut to scan ranges (q), against p,
# on the scan-range sets C and decision 9's W and U, from 1 and 2 views.
#
#   scripts/decision17.sh PROBE_OUT [OUT]
#
# PROBE_OUT: the folder of `scripts/prior_probe.sh` (W and U, PROBE_OUT/val/SET). OUT gets the
# training sets (≈ 3 min), C (OUT/val), q's run (≈ 30 min on 2 cores), the scores
# (OUT/eval-NAME-SET, ≈ 5 min a set and checkpoint) and decision.md. Resumable.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/realistic_sets.sh
decision_setup "$1" "${2:-decision17}"
grep -q '"iteration": 64000' "$parent/state.json" && grep -q '^ensemble = 4$' "$parent/config.toml" \
    || { echo "$parent is not decision 14's p (64 000 iterations, ensemble = 4)" >&2; exit 1; }

# C: two sets of part-thorax scans, made after the rule.
common="--size 64 --views 10 --split val --preset kv-flat-panel-120kvp --heterogeneity 60"
# shellcheck disable=SC2086 # $common, word-split on purpose
for pop in "lidc 75000 16" "full-chest 85000 13"; do
    read -r profile seed augment <<< "$pop"
    [ -f "$out/val/$profile-range/manifest.jsonl" ] || $bin dataset -o "$out/val/$profile-range" \
        --phantoms 6 --seed "$seed" --profile "$profile" --augment "$augment" --scan-range 21 \
        --like "$parent" $common
done

# q's training set: p's (train-mixhet-d5, as decision 9 made it) and the same 64 augmented,
# heterogeneous phantoms as train-ahet-*, cut to scan ranges.
train_mixhet
train_set train-d5-lidc 0 lidc --deform 5
train_set train-d5-fc 300000 full-chest --deform 5
train_set train-d5-ahet-lidc 0 lidc --augment 11 --heterogeneity 60 --deform 5
train_set train-d5-ahet-fc 300000 full-chest --augment 11 --heterogeneity 60 --deform 5
train_set train-sr-lidc 0 lidc --augment 11 --heterogeneity 60 --scan-range 17
train_set train-sr-fc 300000 full-chest --augment 11 --heterogeneity 60 --scan-range 17
srcs=()
for s in train-lidc train-fc train-ahet-lidc train-ahet-fc train-d5-lidc train-d5-fc \
    train-d5-ahet-lidc train-d5-ahet-fc train-sr-lidc train-sr-fc; do
    srcs+=("$out/$s")
done
[ -f "$out/train-mixhet-d5-sr/manifest.jsonl" ] \
    || python3 scripts/merge_sets.py "$out/train-mixhet-d5-sr" "${srcs[@]}"

# A fine-tune (`train --init`): p's networks, the 256 items p learned codes for keep them,
# the 64 new ones get fresh codes, the mean volume is the 320 items'.
if [ ! -f "$out/q.done" ]; then
    $bin train "$out/train-mixhet-d5-sr" -o "$out/q" --init "$parent" --resume --iterations 72000 \
        > "$out/q.log" 2>&1
    keep_parent_infer "$out/q/checkpoint/config.toml" "$parent/config.toml"
    touch "$out/q.done"
fi

# Scores: C from OUT/val, W and U from PROBE_OUT/val.
ranged="lidc-range full-chest-range"
warped="lidc-deform8 full-chest-deform8"
unwarped="lidc-base full-chest-base"
for s in $ranged $warped $unwarped; do
    case " $ranged " in *" $s "*) from=$out/val/$s ;; *) from=$probe/val/$s ;; esac
    for arm in p:"$parent" q:"$out/q/checkpoint"; do
        [ -f "$out/eval-${arm%%:*}-$s/results.csv" ] || $bin evaluate "$from" \
            --checkpoint "${arm#*:}" --views 1,2 --no-baselines -o "$out/eval-${arm%%:*}-$s"
    done
done
# shellcheck disable=SC2086 # the set lists, word-split on purpose
{
    echo "## Rule (i): C, the scan-range sets"
    python3 scripts/validation_rule.py "$(arm p "$out/eval-p-" $ranged)" "$(arm q "$out/eval-q-" $ranged)"
    echo "## Rule (ii): W and U together"
    python3 scripts/validation_rule.py "$(arm p "$out/eval-p-" $warped $unwarped)" \
        "$(arm q "$out/eval-q-" $warped $unwarped)"
    echo "## Rule (iii): U alone"
    python3 scripts/validation_rule.py "$(arm p "$out/eval-p-" $unwarped)" "$(arm q "$out/eval-q-" $unwarped)"
} | tee "$out/decision.md"
