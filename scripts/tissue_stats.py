#!/usr/bin/env python3
"""Tissue statistics of data sets' CTs: how far a phantom population is from real anatomy.

    python3 scripts/tissue_stats.py NAME=DIR [NAME=DIR …]  (numpy, nibabel)

DIR is a data set (folders with item.json) or one item.

For every item of each data set (its `ct.nii.gz`, stored as (HU − lo)/(hi − lo) with the
window of its item.json) the body is every voxel that is not air connected to the edge of
its axial section (below −500 HU, the threshold of the items' own body masks). Per item:

* body fraction of the grid; the body's section width (left–right) and depth
  (antero-posterior) over the grid's, the median over the axial levels the body reaches —
  a body that fills its box at every level is 1.00 / 1.00;
* the lungs' extent along the body axis: the lowest and the highest axial level where lung
  (below −400 HU inside the body) fills more than 5 % of the section's body, as fractions of
  the grid's height (0: its inferior edge, 1: its superior one; items are in the patient
  frame, k → superior) — where the scan starts and stops relative to the lungs;
* per tissue class (the items' classes: lung/air < −400 HU, fat −400…−50, soft tissue
  −50…200, bone ≥ 200) the mean and standard deviation of HU inside the body (HU histogram
  moments), and the texture: the standard deviation of HU minus its 3×3×3 mean over the
  voxels whose whole neighbourhood is of the class (a class's fine structure and noise,
  free of its edges; "—" where no voxel's neighbourhood is all of the class).

Prints one markdown row per data set: each figure's mean over its items, and the range over
items in brackets.
"""
import json
import pathlib
import sys

import nibabel as nib
import numpy as np

CLASSES = [("lung/air", -np.inf, -400.0), ("fat", -400.0, -50.0),
           ("soft tissue", -50.0, 200.0), ("bone", 200.0, np.inf)]


def shifts():
    return [(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)]


def body_mask(hu):
    """Every voxel but the air (< −500 HU) connected to its axial section's edge."""
    air = hu < -500.0
    outside = np.zeros_like(air)
    outside[0, :, :] = air[0, :, :]
    outside[-1, :, :] = air[-1, :, :]
    outside[:, 0, :] = air[:, 0, :]
    outside[:, -1, :] = air[:, -1, :]
    while True:
        grown = outside.copy()
        grown[1:, :, :] |= outside[:-1, :, :]
        grown[:-1, :, :] |= outside[1:, :, :]
        grown[:, 1:, :] |= outside[:, :-1, :]
        grown[:, :-1, :] |= outside[:, 1:, :]
        grown &= air
        if (grown == outside).all():
            return ~outside
        outside = grown


def item_stats(item):
    record = json.loads((item / "item.json").read_text())
    lo, hi = record["hu_window"]["lo"], record["hu_window"]["hi"]
    hu = np.asarray(nib.load(item / record["ct"]).dataobj, dtype=np.float64) * (hi - lo) + lo
    body = body_mask(hu)
    local_mean = sum(np.roll(hu, s, axis=(0, 1, 2)) for s in shifts()) / 27.0
    residual = hu - local_mean
    width, depth = [], []
    for k in range(hu.shape[2]):
        section = body[:, :, k]
        if not section.any():
            continue
        i = np.flatnonzero(section.any(axis=1))
        j = np.flatnonzero(section.any(axis=0))
        width.append((i[-1] - i[0] + 1) / hu.shape[0])
        depth.append((j[-1] - j[0] + 1) / hu.shape[1])
    lung = body & (hu < -400.0)
    share = lung.sum(axis=(0, 1)) / np.maximum(body.sum(axis=(0, 1)), 1)
    levels = np.flatnonzero(share > 0.05)
    nz = hu.shape[2]
    low, high = ((levels[0] / nz, (levels[-1] + 1) / nz) if levels.size else (np.nan, np.nan))
    out = {"body": body.mean(), "width": np.median(width), "depth": np.median(depth),
           "lung_low": low, "lung_high": high}
    interior = np.zeros_like(body)
    interior[1:-1, 1:-1, 1:-1] = True
    for name, a, b in CLASSES:
        of_class = body & (hu >= a) & (hu < b)
        whole = of_class.copy()
        for s in shifts():
            whole &= np.roll(of_class, s, axis=(0, 1, 2))
        whole &= interior
        values = hu[of_class]
        out[name] = (values.mean(), values.std(),
                     residual[whole].std() if whole.sum() > 10 else np.nan)
    return out


def main(args):
    if not args:
        sys.exit(__doc__)
    header = ("| set | items | body fraction | section width / grid | section depth / grid | "
              "lungs from / to (height) | "
              + " | ".join(f"{c}: mean ± sd HU, texture" for c, _, _ in CLASSES) + " |")
    print(header)
    print("|---|---:|---:|---:|---:|---|" + "---|" * len(CLASSES))
    for arg in args:
        name, _, folder = arg.partition("=")
        folder = pathlib.Path(folder)
        items = ([folder] if (folder / "item.json").exists()
                 else sorted(p.parent for p in folder.glob("*/item.json")))
        if not items:
            sys.exit(f"{folder}: no items (folders with item.json)")
        stats = [item_stats(p) for p in items]

        def fig(get, fmt):
            v = [x for x in (get(s) for s in stats) if np.isfinite(x)]
            if not v:
                return "—"
            return f"{fmt(np.mean(v))} [{fmt(min(v))}–{fmt(max(v))}]" if len(stats) > 1 else fmt(v[0])

        pct = lambda x: f"{100 * x:.0f} %"
        two = lambda x: f"{x:.2f}"
        hu = lambda x: f"{x:.0f}"
        cells = [fig(lambda s: s["body"], pct), fig(lambda s: s["width"], two),
                 fig(lambda s: s["depth"], two),
                 f"{fig(lambda s: s['lung_low'], two)} / {fig(lambda s: s['lung_high'], two)}"]
        for c, _, _ in CLASSES:
            cells.append(f"{fig(lambda s: s[c][0], hu)} ± {fig(lambda s: s[c][1], hu)}, "
                         f"{fig(lambda s: s[c][2], hu)}")
        print(f"| {name} | {len(items)} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main(sys.argv[1:])
