#!/usr/bin/env python3
"""Decision 18's tuning (docs/real-ct/decision18-RULE.txt): the spread-weighted blend's
settings scored on validation phantoms from volumes written once per phantom.

    python3 scripts/decision18_grid.py TUNE_DIR [CHECK_EVAL_DIR …]

TUNE_DIR/SET/ID/ holds, for one validation item (its folder named in item.txt), what
scripts/decision18.sh wrote with the shipped checkpoint from one view: net.nii.gz (TomoGRAF's
volume, HU), sd.nii.gz (the four fits' voxel-wise standard deviation, HU:
`reconstruct --spread`) and classical.nii.gz (SART-TV from the checkpoint's mean volume, HU).
For each setting (W, S) of the rule's grid the blended volume is
(1 − w) × net + w × classical with w = W × sd² / (sd² + S²), voxel by voxel, as
model/src/reconstruct.rs makes it, and is scored by body PSNR as model/src/metrics.rs scores
it: the item's normalised ground truth (ct.nii.gz), the volume normalised by the item's HU
window and clamped to [0, 1], the RMSE over voxels whose truth is above −900 HU,
−20 log10(RMSE). Prints the mean over the phantoms per setting and the rule's choice: the
highest mean, if above W = 0's (TomoGRAF as shipped); else none.

With CHECK_EVAL_DIRs (`tomograf evaluate` folders of the same checkpoint on the same sets,
seed 0), W = 0's score of each phantom is checked against the one `evaluate` recorded
(TomoGRAF, one view): the two paths must agree to 1e-3 dB.

numpy and nibabel.
"""
import csv
import json
import pathlib
import sys

import nibabel as nib
import numpy as np

WEIGHTS = [0.25, 0.5, 0.75, 1.0]
SPREADS_HU = [25.0, 50.0, 100.0, 200.0]
BODY_HU = -900.0


def load(path):
    """A NIfTI volume as float64 numpy."""
    return np.asarray(nib.load(path).get_fdata(dtype=np.float64))


def body_psnr(volume_hu, truth, lo, hi, mask):
    v = np.clip((volume_hu - lo) / (hi - lo), 0.0, 1.0)
    rmse = np.sqrt(np.mean((v[mask] - truth[mask]) ** 2))
    return -20.0 * np.log10(rmse)


def main():
    tune = pathlib.Path(sys.argv[1])
    rows = []  # (set, id, {setting: score})
    for d in sorted(p for p in tune.glob("*/*") if (p / "classical.nii.gz").is_file()):
        item = pathlib.Path((d / "item.txt").read_text().strip())
        window = json.loads((item / "item.json").read_text())["hu_window"]
        lo, hi = float(window["lo"]), float(window["hi"])
        truth = load(item / "ct.nii.gz")
        mask = truth > (BODY_HU - lo) / (hi - lo)
        net, sd, classical = (load(d / n) for n in ("net.nii.gz", "sd.nii.gz", "classical.nii.gz"))
        scores = {(0.0, 0.0): body_psnr(net, truth, lo, hi, mask)}
        for w in WEIGHTS:
            for s in SPREADS_HU:
                wv = w * sd**2 / (sd**2 + s**2)
                scores[(w, s)] = body_psnr((1 - wv) * net + wv * classical, truth, lo, hi, mask)
        rows.append((d.parent.name, d.name, scores))
    if not rows:
        sys.exit(f"{tune}: no phantom with net.nii.gz, sd.nii.gz and classical.nii.gz")

    for ev in sys.argv[2:]:
        ev = pathlib.Path(ev)
        for set_name, item_id, scores in rows:
            f = ev / f"eval-q-{set_name}" / "items" / f"{item_id}.csv"
            if not f.is_file():
                continue
            for r in csv.DictReader(f.open()):
                if r["views"] == "1" and r["method"] == "TomoGRAF":
                    got, want = scores[(0.0, 0.0)], float(r["body_psnr_db"])
                    if abs(got - want) > 1e-3:
                        sys.exit(f"{set_name}/{item_id}: {got:.4f} dB here, {want:.4f} by evaluate")
                    print(f"check {set_name}/{item_id}: {got:.4f} dB = evaluate's {want:.4f}")

    settings = list(rows[0][2])
    mean = {k: float(np.mean([r[2][k] for r in rows])) for k in settings}
    sets = sorted({r[0] for r in rows})
    print(f"# Decision 18, tuning: TomoGRAF body PSNR (dB) from one view, mean over {len(rows)} "
          f"phantoms ({', '.join(sets)})\n")
    print("| W | S (HU) | " + " | ".join(sets) + " | all |")
    print("|---:|---:|" + "---:|" * (len(sets) + 1))
    for k in settings:
        per_set = [np.mean([r[2][k] for r in rows if r[0] == s]) for s in sets]
        label = "0 (shipped)" if k == (0.0, 0.0) else f"{k[0]:g}"
        spread = "—" if k == (0.0, 0.0) else f"{k[1]:g}"
        print(f"| {label} | {spread} | " + " | ".join(f"{x:.3f}" for x in per_set)
              + f" | {mean[k]:.3f} |")
    best = max((k for k in settings if k != (0.0, 0.0)), key=lambda k: mean[k])
    print()
    if mean[best] > mean[(0.0, 0.0)]:
        print(f"chosen: W = {best[0]:g}, S = {best[1]:g} HU ({mean[best]:.3f} dB against "
              f"{mean[(0.0, 0.0)]:.3f} as shipped)")
    else:
        print(f"chosen: none (the best, W = {best[0]:g}, S = {best[1]:g} HU, "
              f"{mean[best]:.3f} dB, is not above {mean[(0.0, 0.0)]:.3f} as shipped)")


if __name__ == "__main__":
    main()
