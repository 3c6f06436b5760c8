#!/usr/bin/env python3
"""Where the one-view fits disagree, beside where TomoGRAF is wrong.

    python3 scripts/spread_figure.py OUT.png TITLE ITEM_DIR RECON.nii.gz SPREAD.nii.gz

ITEM_DIR: a data-set item (ct.nii.gz, [0, 1] over item.json's HU window). RECON, SPREAD:
`tomograf reconstruct ITEM_DIR --views 1 -o RECON --spread SPREAD` (both HU). Draws the
truth, the reconstruction, the fits' spread (standard deviation across them, HU) and
|reconstruction − truth| (HU) through the grid's centre (coronal and axial), and prints,
inside the body (truth above −900 HU), the mean spread, the mean |error| and Spearman's rank
correlation between the two over voxels. Needs numpy, nibabel and matplotlib.
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import nibabel as nib
import numpy as np


def ranks(x):
    order = np.argsort(x, kind="stable")
    r = np.empty(len(x))
    r[order] = np.arange(len(x))
    return r


def main():
    if len(sys.argv) != 6:
        sys.exit(__doc__)
    out, title, item, recon, spread = sys.argv[1:]
    window = json.load(open(f"{item}/item.json"))["hu_window"]
    lo, hi = window["lo"], window["hi"]
    truth = nib.load(f"{item}/ct.nii.gz").get_fdata() * (hi - lo) + lo
    rec = np.clip(nib.load(recon).get_fdata(), lo, hi)
    sd = nib.load(spread).get_fdata()
    err = np.abs(rec - truth)
    body = truth > -900.0
    a, b = sd[body], err[body]
    rho = np.corrcoef(ranks(a), ranks(b))[0, 1]
    print(f"{title}: inside the body, mean spread {a.mean():.1f} HU, mean |error| {b.mean():.1f} HU, "
          f"Spearman rank correlation {rho:.2f} over {body.sum()} voxels")

    n = truth.shape
    cuts = [("coronal", lambda v: v[:, n[1] // 2, :].T, "lower"),
            ("axial", lambda v: v[:, :, n[2] // 2].T, "upper")]
    cols = [("truth", truth, "gray", -1000, 600, "HU"),
            ("TomoGRAF, 1 view", rec, "gray", -1000, 600, "HU"),
            ("spread of the 4 fits", sd, "magma", 0, 200, "standard deviation (HU)"),
            ("|TomoGRAF − truth|", err, "magma", 0, 600, "|error| (HU)")]
    fig, axes = plt.subplots(2, 4, figsize=(13, 6.6), layout="constrained")
    for r, (cut, take, origin) in enumerate(cuts):
        for c, (name, vol, cmap, vmin, vmax, label) in enumerate(cols):
            ax = axes[r][c]
            im = ax.imshow(take(vol), cmap=cmap, vmin=vmin, vmax=vmax, origin=origin)
            ax.set_title(f"{name} ({cut})", fontsize=9)
            ax.set_xlabel("voxel")
            if c == 0:
                ax.set_ylabel("voxel")
            if r == 1:
                fig.colorbar(im, ax=[axes[0][c], axes[1][c]], label=label, shrink=0.7,
                             location="bottom")
    fig.suptitle(f"{title}: where the one-view fits disagree and where the result is wrong "
                 f"(body: Spearman {rho:.2f})", fontsize=11)
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    main()
