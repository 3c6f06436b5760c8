#!/usr/bin/env bash
# How much of a one-view score on a real CT is the inference seed's: the shipped mixed
# checkpoint (or CHECKPOINT) scored from one view with inference seeds 1…4 beside the seed-0
# scores of scripts/real_cts.sh, network only (`evaluate --no-baselines`; its rows of SART-TV
# from the mean come from the checkpoint's own mean volume and do not depend on the seed).
#
#   scripts/real_ct_seeds.sh REAL_CTS_OUT OUT [CHECKPOINT]
#
# REAL_CTS_OUT: the folder of scripts/real_cts.sh (its items/ and eval-mixed/). Writes
# OUT/seedN/ (evaluate folders) and OUT/seeds.md (per CT: TomoGRAF's body PSNR per seed, their
# mean and standard deviation, and SART-TV from the mean). ≈ 4 min a seed on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
rc=$(realpath "$1")
mkdir -p "$2"
out=$(realpath "$2")
checkpoint=${3:-model/checkpoints/lidc-full-chest}
cargo build --release --quiet
bin=$PWD/target/release/tomograf
for s in 1 2 3 4; do
    [ -f "$out/seed$s/results.csv" ] && continue
    for k in 0 1; do
        $bin --threads 1 evaluate "$rc/items" --checkpoint "$checkpoint" --views 1 --no-baselines \
            --seed "$s" -o "$out/seed$s" --shard "$k/2" &
    done
    wait
    $bin evaluate "$rc/items" --checkpoint "$checkpoint" --views 1 --no-baselines --seed "$s" \
        -o "$out/seed$s" --merge
done
python3 - "$rc" "$out" <<'PY' | tee "$out/seeds.md"
import csv, json, pathlib, statistics as st, sys
rc, out = map(pathlib.Path, sys.argv[1:])
names = {}
for line in (rc / "items" / "manifest.jsonl").read_text().splitlines():
    r = json.loads(line)
    src = r.get("source") or {}
    names[r["id"]] = pathlib.Path(src.get("path", r["id"])).name
def body(folder, item, method):
    for r in csv.DictReader((folder / "items" / f"{item}.csv").open()):
        if r["views"] == "1" and r["method"] == method:
            return float(r["body_psnr_db"])
folders = [rc / "eval-mixed"] + [out / f"seed{s}" for s in range(1, 5)]
print("TomoGRAF's body PSNR (dB) from one view by inference seed (seed 0: scripts/real_cts.sh)\n")
print("| CT | seed 0 | 1 | 2 | 3 | 4 | mean ± SD | SART-TV from the mean | mean − SART-TV from the mean |")
print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
for item in sorted(names):
    v = [body(f, item, "TomoGRAF") for f in folders]
    ref = body(rc / "eval-mixed", item, "SART-TV from the mean")
    m = st.mean(v)
    print(f"| {names[item]} | " + " | ".join(f"{x:.2f}" for x in v)
          + f" | {m:.2f} ± {st.stdev(v):.2f} | {ref:.2f} | {m - ref:+.2f} |")
PY
