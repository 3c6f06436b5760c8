#!/usr/bin/env bash
# Byte comparison of two tomograf binaries' outputs, for a change that must not change any
# output (a refactor, a crate split: docs/architecture.md): both binaries run the same jobs
# on one CT — a flat-panel AP view with the scatter estimate, a CBCT orbit, an ideal-DRR
# orbit, a one-phantom data set with real physics and scatter, SART-TV and FDK
# reconstructions, a reduced `validate tg195` (all four cases) and the trade-off ladder —
# and every file is compared by SHA-256 (wall-clock columns removed first).
#
#   scripts/compare_outputs.sh OLD_BINARY NEW_BINARY CT.nii[.gz] [WORK_DIR]
#
# Prints IDENTICAL and the file count, or the files that differ. About 10 min on 2 cores.
set -uo pipefail
old=$1 new=$2 ct=$3 out=${4:-$(mktemp -d)}
rm -rf "$out/old" "$out/new"
cd "$(dirname "$0")/.."
for v in old new; do
  exe=${!v}; d=$out/$v; mkdir -p "$d"
  run() { "$exe" --threads 2 "$@" >/dev/null 2>&1 || echo "$v: tomograf $* failed"; }
  run project "$ct" --view ap --pitch 2.6 --preset kv-flat-panel-120kvp --scatter estimate --format npy -o "$d/proj"
  run project "$ct" --arc 0:90:3 --pitch 5.2 --rows 64 --cols 64 --preset cbct-100kvp --format npy -o "$d/proj2"
  run project "$ct" --arc 0:360:12 --pitch 5.2 --rows 64 --cols 64 --format npy -o "$d/proj3"
  run dataset -o "$d/ds" --phantoms 1 --size 32 --views 10 --preset kv-flat-panel-120kvp --scatter estimate
  run reconstruct-classical "$d/proj3" --method sart-tv -o "$d/rc.nii.gz"
  run reconstruct-classical "$d/proj3" --method fdk -o "$d/fdk.nii.gz"
  run validate tg195 --cases 1,2,3,4.2 --photons-case1 20000 --photons-case2 20000 \
      --photons-case3 20000 --photons-case42 20000 -o "$d/tg"
  # tg195.md states run times; the figures are drawn from the CSV.
  sed -i '/seconds\|[0-9] s\b/d' "$d/tg/tg195.md" 2>/dev/null; rm -f "$d"/tg/*.png
  run tradeoff "$ct" --view ap --pitch 5.2 --rows 128 --cols 128 --preset kv-flat-panel-120kvp --report "$d/to"
  # The ladder's errors only (its setting names hold commas: the last two fields).
  python3 -c "import csv,sys; [print(r[0], r[1], r[-2], r[-1]) for r in csv.reader(open(sys.argv[1]))]" \
      "$d/to/tradeoff.csv" > "$d/to/errors.txt" 2>/dev/null
  rm -f "$d"/to/tradeoff.*
done
(cd "$out/old" && find . -type f | sort | xargs sha256sum) > "$out/old.sha"
(cd "$out/new" && find . -type f | sort | xargs sha256sum) > "$out/new.sha"
if diff "$out/old.sha" "$out/new.sha"; then echo "IDENTICAL: $(wc -l < "$out/old.sha") files"; fi
