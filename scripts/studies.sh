#!/usr/bin/env bash
# Issue 48's studies, every run and both pooled reports, in one command:
#
#   scripts/studies.sh [OUT] [BIN]
#
# At `small` scale, the realism gap and the domain shift each with training seeds 0, 1 and 2
# (OUT/rg-s0 … OUT/ds-s2), then one report per study pooling its three seeds
# (OUT/rg-pooled, OUT/ds-pooled: every cell averages 3 × 8 test phantoms, the paired
# intervals cover the seeds); at `medium` scale, both studies once with seed 0
# (OUT/ds-medium-s0, OUT/rg-medium-s0). Each study resumes where it stopped (re-run the
# script after a kill: finished items, models and scores are kept), so the days this takes
# on a CPU may be spread over many runs; each report's compute table says what its runs
# cost. BIN defaults to target/release/tomograf (built here if missing).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-studies}
bin=${2:-target/release/tomograf}
[ -x "$bin" ] || cargo build --release
mkdir -p "$out"
run() {
    echo "== $(date -u +%FT%TZ) $*"
    "$bin" study "$@"
}
run realism-gap -o "$out/rg-s0" --scale small --seed 0
for s in 0 1 2; do run domain-shift -o "$out/ds-s$s" --scale small --seed "$s"; done
for s in 1 2; do run realism-gap -o "$out/rg-s$s" --scale small --seed "$s"; done
run realism-gap -o "$out/rg-pooled" --scale small --stage report \
    --pool "$out/rg-s0,$out/rg-s1,$out/rg-s2"
run domain-shift -o "$out/ds-pooled" --scale small --stage report \
    --pool "$out/ds-s0,$out/ds-s1,$out/ds-s2"
run domain-shift -o "$out/ds-medium-s0" --scale medium --seed 0
run realism-gap -o "$out/rg-medium-s0" --scale medium --seed 0
echo "reports: $out/{rg,ds}-pooled/report.md, $out/{ds,rg}-medium-s0/report.md"
