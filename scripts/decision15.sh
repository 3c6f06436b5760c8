#!/usr/bin/env bash
# Issue 47, decision 15 (docs/real-ct/decision15-RULE.txt, written before its candidate was run
# on any set): from one view, the shipped checkpoint's four averaged fits (p, decision 14)
# against the same with their drawn starting codes spread twice as wide (q:
# ensemble_code_sd = 2), on decision 9's sets, one view only, by decision 14's rule.
#
#   scripts/decision15.sh PROBE_OUT [OUT]
#
# PROBE_OUT: the folder of `scripts/prior_probe.sh` (its validation sets, PROBE_OUT/val/SET).
# p's scores are OUT/eval-p-SET (decision 14's folders serve as they are; made here with the
# shipped checkpoint when missing); q's ≈ 8 min per set on 2 cores. Resumable.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/realistic_sets.sh
decision_setup "$1" "${2:-decision15}"
sets="lidc-deform8 full-chest-deform8 lidc-base full-chest-base"
unwarped="lidc-base full-chest-base"
grep -q '^ensemble_code_sd = 1.0$' "$parent/config.toml" \
    || { echo "$parent is not decision 14's p (ensemble_code_sd = 1.0)" >&2; exit 1; }
if [ ! -d "$out/q" ]; then
    rm -rf "$out/q.tmp"
    cp -r "$parent" "$out/q.tmp"
    sed -i 's/^ensemble_code_sd = 1\.0$/ensemble_code_sd = 2.0/' "$out/q.tmp/config.toml"
    grep -q '^ensemble_code_sd = 2.0$' "$out/q.tmp/config.toml"
    mv "$out/q.tmp" "$out/q"
fi
score_on_sets p "$parent" 1
score_on_sets q "$out/q" 1
decide p "$out/eval-p-" q "$out/eval-q-" one-view
