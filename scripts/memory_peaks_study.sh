#!/usr/bin/env bash
# Peak memory of `tomograf study` (docs/reliability.md, "Memory budget"): each stage run on
# its own in a fresh folder, then the whole study in another, under `/usr/bin/time -v`
# (maximum resident set), beside the study's own estimate ("study: estimated peak memory …").
#
#   scripts/memory_peaks_study.sh BIN [OUT] [THREADS]     # ≈ 10 min on 2 cores
set -euo pipefail
bin=$(realpath "$1")
out=${2:-memory-peaks-study}
threads=${3:-2}
mkdir -p "$out"
cd "$out"
rss() { awk '/Maximum resident/ {printf "%.0f", $6 / 1024}' "$1"; }
est() { sed -n 's/.*study: estimated peak memory \([0-9]*\) MiB.*/\1/p' "$1" | head -1; }
echo "| study | stage | estimated MiB | measured MiB | estimate / measured |"
echo "|---|---|---:|---:|---:|"
while IFS='|' read -r name args; do
    rm -rf "$name" "$name-all"
    for stage in data train evaluate report all; do
        dir=$name; [ "$stage" = all ] && dir=$name-all
        log=$name-$stage.log
        # shellcheck disable=SC2086
        /usr/bin/time -v "$bin" --threads "$threads" study $args --scale tiny -o "$dir" \
            --stage "$stage" > /dev/null 2> "$log"
        e=$(est "$log"); m=$(rss "$log")
        if [ -n "$e" ]; then r=$(awk -v e="$e" -v m="$m" 'BEGIN {printf "%.2f", e / m}'); else e=–; r=–; fi
        echo "| $name | $stage | $e | $m | $r |"
    done
done <<'LIST'
rg|realism-gap
rg-ideal|realism-gap --levels ideal-drr
ds|domain-shift
ds-lidc|domain-shift --shifts lidc,pacemaker
ds-fc|domain-shift --shifts full-chest
LIST
