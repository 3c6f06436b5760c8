#!/usr/bin/env python3
"""Where a reconstruction's error lies inside the body, by the ground truth's tissue class.

    python3 scripts/error_by_tissue.py ITEM NAME=VOLUME [NAME=VOLUME …]  (numpy, nibabel)

ITEM is a data-set item (its ct.nii.gz is the ground truth); each VOLUME is a NIfTI in HU on
the item's grid (`tomograf reconstruct … -o VOLUME`) or a checkpoint's `mean_volume.npy`
(stored as the item's CT is, (HU − lo)/(hi − lo), indexed [k][j][i]). The body and the
classes are those of scripts/tissue_stats.py. Prints, per volume and class, the voxels'
share of the body, the mean error (bias, HU), the RMSE (HU) and the class's share of the
body's squared error.
"""
import json
import pathlib
import sys

import nibabel as nib
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from tissue_stats import CLASSES, body_mask  # noqa: E402


def main(args):
    if len(args) < 2:
        sys.exit(__doc__)
    item = pathlib.Path(args[0])
    record = json.loads((item / "item.json").read_text())
    lo, hi = record["hu_window"]["lo"], record["hu_window"]["hi"]
    truth = np.asarray(nib.load(item / record["ct"]).dataobj, dtype=np.float64) * (hi - lo) + lo
    body = body_mask(truth)
    print("| volume | class | share of body | truth mean HU | bias (HU) | RMSE (HU) | share of squared error |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for arg in args[1:]:
        name, _, path = arg.partition("=")
        if path.endswith(".npy"):
            volume = np.load(path).astype(np.float64).transpose(2, 1, 0) * (hi - lo) + lo
        else:
            volume = np.asarray(nib.load(path).dataobj, dtype=np.float64)
        if volume.shape != truth.shape:
            sys.exit(f"{path}: grid {volume.shape} is not the item's {truth.shape}")
        error = volume - truth
        total = (error[body] ** 2).sum()
        print(f"| {name} | whole body | 100 % | {truth[body].mean():.0f} | {error[body].mean():+.0f} | "
              f"{np.sqrt((error[body] ** 2).mean()):.0f} | 1.00 |")
        for cls, a, b in CLASSES:
            k = body & (truth >= a) & (truth < b)
            e = error[k]
            print(f"| {name} | {cls} | {100 * k.sum() / body.sum():.0f} % | {truth[k].mean():.0f} | "
                  f"{e.mean():+.0f} | {np.sqrt((e ** 2).mean()):.0f} | {(e ** 2).sum() / total:.2f} |")


if __name__ == "__main__":
    main(sys.argv[1:])
