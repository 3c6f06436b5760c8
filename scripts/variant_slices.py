#!/usr/bin/env python3
"""Orthogonal slices of one item of each phantom variant (scripts/prior_probe.sh's sets).

    python3 scripts/variant_slices.py OUT.png LABEL=ITEM_DIR [LABEL=ITEM_DIR …]

Each ITEM_DIR is a data-set item (its ct.nii.gz, [0, 1] over the item's HU window, shown in
HU); one row per item: coronal, sagittal and axial slices through the grid's centre, one
HU colour bar. Needs numpy, nibabel and matplotlib.
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import nibabel as nib

if len(sys.argv) < 3:
    sys.exit(__doc__)
out, rows = sys.argv[1], [a.split("=", 1) for a in sys.argv[2:]]
fig, axes = plt.subplots(len(rows), 3, figsize=(9.5, 2.9 * len(rows)), squeeze=False,
                         layout="constrained")
for r, (label, item) in enumerate(rows):
    meta = json.load(open(f"{item}/item.json"))
    window = meta["hu_window"]
    lo, hi = (window["lo"], window["hi"]) if isinstance(window, dict) else window
    v = nib.load(f"{item}/ct.nii.gz").get_fdata() * (hi - lo) + lo
    n = v.shape
    views = [("coronal", v[:, n[1] // 2, :].T), ("sagittal", v[n[0] // 2, :, :].T),
             ("axial", v[:, :, n[2] // 2].T)]
    for c, (name, img) in enumerate(views):
        ax = axes[r][c]
        im = ax.imshow(img, cmap="gray", vmin=-1000, vmax=600, origin="lower" if c < 2 else "upper")
        ax.set_title(f"{label}: {name}", fontsize=9)
        ax.set_xlabel("voxel")
        if c == 0:
            ax.set_ylabel("voxel")
fig.colorbar(im, ax=[a for row in axes for a in row], label="HU", shrink=0.6)
fig.suptitle("One validation phantom (lidc, seed 71000) as made and warped; 64³ item", fontsize=11)
fig.savefig(out, dpi=80)
