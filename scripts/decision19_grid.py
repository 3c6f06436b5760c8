#!/usr/bin/env python3
"""Decision 19's tuning (docs/real-ct/decision19-RULE.txt): the one-view ensemble's starting
codes drawn wider (ensemble_code_sd = c) with the spread-weighted blend re-tuned, scored on
validation phantoms from volumes written once per phantom.

    python3 scripts/decision19_grid.py D18_TUNE_DIR TUNE_DIR

D18_TUNE_DIR/SET/ID/ is what scripts/decision18.sh wrote with c = 1 and no blend (net.nii.gz,
sd.nii.gz, classical.nii.gz: SART-TV from the mean volume, which no c changes; item.txt);
TUNE_DIR/cC/SET/ID/ what scripts/decision19.sh wrote with c = C and no blend (net.nii.gz,
sd.nii.gz). Each setting (c, W, S) blends as decision 18 does, (1 − w) × net + w × classical
with w = W × sd² / (sd² + S²) voxel by voxel, and is scored by body PSNR as
model/src/metrics.rs scores it (decision18_grid.body_psnr). The shipped checkpoint q is
c = 1, W = 0.5, S = 100 HU. Prints the mean per set and over the phantoms per setting and the
rule's choice: the highest mean among c ≠ 1, if above q's; else none. Then, for reading, the
fits' mean spread inside the body (HU) per set and c.

numpy and nibabel.
"""
import json
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from decision18_grid import BODY_HU, body_psnr, load  # noqa: E402

WEIGHTS = [0.25, 0.5, 0.75, 1.0]
SPREADS_HU = [25.0, 50.0, 100.0, 200.0, 400.0]
SHIPPED = (1.0, 0.5, 100.0)


def main():
    d18, tune = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
    code_sds = sorted(float(p.name[1:]) for p in tune.glob("c*") if p.is_dir())
    if not code_sds:
        sys.exit(f"{tune}: no cC folder")
    rows = []  # (set, id, {setting: score})
    spreads = []  # (set, {c: mean spread in the body, HU})
    for d in sorted(p for p in d18.glob("*/*") if (p / "classical.nii.gz").is_file()):
        item = pathlib.Path((d / "item.txt").read_text().strip())
        window = json.loads((item / "item.json").read_text())["hu_window"]
        lo, hi = float(window["lo"]), float(window["hi"])
        truth = load(item / "ct.nii.gz")
        mask = truth > (BODY_HU - lo) / (hi - lo)
        classical = load(d / "classical.nii.gz")

        def blended(net, sd, w, s):
            wv = w * sd**2 / (sd**2 + s**2)
            return body_psnr((1 - wv) * net + wv * classical, truth, lo, hi, mask)

        sd1 = load(d / "sd.nii.gz")
        scores = {SHIPPED: blended(load(d / "net.nii.gz"), sd1, 0.5, 100.0)}
        spread = {1.0: float(sd1[mask].mean())}
        for c in code_sds:
            cd = tune / f"c{c:g}" / d.parent.name / d.name
            if not (cd / "sd.nii.gz").is_file():
                sys.exit(f"{cd}: no sd.nii.gz (scripts/decision19.sh makes it)")
            net, sd = load(cd / "net.nii.gz"), load(cd / "sd.nii.gz")
            spread[c] = float(sd[mask].mean())
            for w in WEIGHTS:
                for s in SPREADS_HU:
                    scores[(c, w, s)] = blended(net, sd, w, s)
        rows.append((d.parent.name, d.name, scores))
        spreads.append((d.parent.name, spread))
    if not rows:
        sys.exit(f"{d18}: no phantom with net.nii.gz, sd.nii.gz and classical.nii.gz")

    settings = list(rows[0][2])
    mean = {k: float(np.mean([r[2][k] for r in rows])) for k in settings}
    sets = sorted({r[0] for r in rows})
    print(f"# Decision 19, tuning: TomoGRAF body PSNR (dB) from one view, mean over {len(rows)} "
          f"phantoms ({', '.join(sets)})\n")
    print("| c | W | S (HU) | " + " | ".join(sets) + " | all |")
    print("|---:|---:|---:|" + "---:|" * (len(sets) + 1))
    for k in settings:
        per_set = [np.mean([r[2][k] for r in rows if r[0] == s]) for s in sets]
        label = f"{k[0]:g} (shipped)" if k == SHIPPED else f"{k[0]:g}"
        print(f"| {label} | {k[1]:g} | {k[2]:g} | " + " | ".join(f"{x:.3f}" for x in per_set)
              + f" | {mean[k]:.3f} |")
    best = max((k for k in settings if k != SHIPPED), key=lambda k: mean[k])
    print()
    if mean[best] > mean[SHIPPED]:
        print(f"chosen: c = {best[0]:g}, W = {best[1]:g}, S = {best[2]:g} HU ({mean[best]:.3f} dB "
              f"against {mean[SHIPPED]:.3f} as shipped)")
    else:
        print(f"chosen: none (the best, c = {best[0]:g}, W = {best[1]:g}, S = {best[2]:g} HU, "
              f"{mean[best]:.3f} dB, is not above {mean[SHIPPED]:.3f} as shipped)")
    print("\n### The fits' spread: mean inside the body (HU), mean over the set's phantoms\n")
    cs = [1.0, *code_sds]
    print("| set | " + " | ".join(f"c = {c:g}" for c in cs) + " |")
    print("|---|" + "---:|" * len(cs))
    for s in sets:
        print(f"| {s} | " + " | ".join(
            f"{np.mean([sp[c] for n, sp in spreads if n == s]):.1f}" for c in cs) + " |")


if __name__ == "__main__":
    main()
