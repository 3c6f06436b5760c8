#!/usr/bin/env bash
# Render time of each exact Siddon tracer (`--tracer`, docs/projector.md "Which tracer") on
# one CT: the AP view, the lateral view, a 30° view and a 72-view orbit (ms per view, as
# `project` prints it, the volume's loading excluded), ideal DRR, 256² detector. The
# tracers are interleaved (A, B, C, … then again) ROUNDS times and the median is printed.
# Usage: scripts/tracer_table.sh CT [TOMOGRAF_BIN] [ROUNDS]
set -euo pipefail
ct=$1
bin="${2:-target/release/tomograf}"
rounds=${3:-3}
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
tracers="auto scalar packets sheets columns"
jobs=("--view ap" "--view lateral" "--view 30" "--arc 0:5:72")
names=("AP" "lateral" "30°" "72-view orbit")
for j in "${!jobs[@]}"; do
  for r in $(seq "$rounds"); do
    for t in $tracers; do
      "$bin" project "$ct" ${jobs[$j]} --rows 256 --cols 256 --tracer "$t" --format npy \
        -o "$work/o" 2>&1 | grep -o '([0-9.]* ms per view' | tr -d '(' | awk -v t="$t" -v j="$j" '{print j, t, $1}' >> "$work/times"
    done
  done
done
python3 - "$work/times" "${names[@]}" <<'PY'
import sys, statistics as st
path, names = sys.argv[1], sys.argv[2:]
rows = [l.split() for l in open(path)]
tracers = ["auto", "scalar", "packets", "sheets", "columns"]
print("| view | " + " | ".join(tracers) + " |")
print("|---|" + "---:|" * len(tracers))
for j, name in enumerate(names):
    cells = []
    for t in tracers:
        v = [float(r[2]) for r in rows if r[0] == str(j) and r[1] == t]
        cells.append(f"{st.median(v):.1f}" if v else "–")
    print(f"| {name} | " + " | ".join(cells) + " |")
PY
