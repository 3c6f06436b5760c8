#!/usr/bin/env python3
"""Issue 47's criteria on an evaluation of real CTs, paired over its items.

    python3 scripts/real_ct_criteria.py [--items ITEMS_DIR] EVAL_DIR [EVAL_DIR …]

Reads EVAL_DIR/results.csv (`tomograf evaluate`) and prints, per view count, the paired
differences the issue asks about — TomoGRAF minus SART-TV from the mean (PSNR and SSIM,
whole volume and body) and the network alone minus the mean volume inside the body — as
mean ± the half-width of the 95 % t-interval over the items, with "ahead", "behind" or
"tied" (the interval covers zero). With --items (the evaluated data set), each EVAL_DIR
also gets a table per CT — PSNR dB / SSIM (body PSNR) of TomoGRAF, the network alone,
SART-TV from the mean and the mean volume, and TomoGRAF − SART-TV from the mean in the body —
each CT named by its source file (item.json).
"""
import json
import pathlib
import csv
import math
import statistics
import sys
from collections import defaultdict

# Two-sided 95 % Student t quantiles by degrees of freedom (published tables).
T95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306,
       9: 2.262, 10: 2.228, 11: 2.201, 12: 2.179, 13: 2.160, 14: 2.145, 15: 2.131}


def paired(a, b):
    common = sorted(set(a) & set(b))
    d = [a[k] - b[k] for k in common]
    if not d:
        return None
    mean = statistics.mean(d)
    half = T95.get(len(d) - 1, 1.96) * statistics.stdev(d) / math.sqrt(len(d)) if len(d) > 1 else None
    return mean, half, len(d)


def cell(p, digits):
    if p is None:
        return "–"
    mean, half, n = p
    if half is None:
        return f"{mean:+.{digits}f} (n = 1)"
    verdict = "tied" if abs(mean) <= half else ("ahead" if mean > 0 else "behind")
    return f"{mean:+.{digits}f} ± {half:.{digits}f} ({verdict})"


def names(items):
    """Item id → the name of the CT it was made from (its file or folder, extensions off)."""
    out = {}
    for d in sorted(pathlib.Path(items).iterdir()):
        meta = d / "item.json"
        if meta.is_file():
            src = json.loads(meta.read_text()).get("source", {}).get("path", d.name)
            out[d.name] = pathlib.Path(src).name.split(".")[0]
    return out


def per_item(scores, views, names):
    methods = ["TomoGRAF", "TomoGRAF (network only)", "SART-TV from the mean", "mean training volume"]
    print("| views | CT | TomoGRAF | network only | SART-TV from the mean | mean volume "
          "| TomoGRAF − SART-TV from the mean, body PSNR (dB) |")
    print("|---:|---|---|---|---|---|---:|")
    for v in views:
        for item in sorted(scores[(v, "TomoGRAF", "psnr_db")]):
            def fmt(m):
                s = lambda c: scores[(v, m, c)][item]
                return f"{s('psnr_db'):.2f} / {s('ssim'):.3f} ({s('body_psnr_db'):.2f})"
            diff = (scores[(v, "TomoGRAF", "body_psnr_db")][item]
                    - scores[(v, "SART-TV from the mean", "body_psnr_db")][item])
            print(f"| {v} | {names.get(item, item)} | " + " | ".join(fmt(m) for m in methods)
                  + f" | {diff:+.2f} |")
    print()


args = sys.argv[1:]
item_names = None
if args[:1] == ["--items"]:
    if len(args) < 2:
        sys.exit(__doc__)
    item_names = names(args[1])
    args = args[2:]
for folder in args or sys.exit(__doc__):
    scores = defaultdict(dict)  # (views, method, column) -> {item: value}
    for r in csv.DictReader(open(f"{folder}/results.csv")):
        for col in ("psnr_db", "ssim", "body_psnr_db", "body_ssim"):
            scores[(int(r["views"]), r["method"], col)][r["item"]] = float(r[col])
    views = sorted({k[0] for k in scores})
    print(f"{folder}\n")
    print("| views | TomoGRAF − SART-TV from the mean: PSNR (dB) | SSIM | body PSNR (dB) | body SSIM "
          "| network alone − mean volume, body PSNR (dB) |")
    print("|---:|---:|---:|---:|---:|---:|")
    for v in views:
        cols = [cell(paired(scores[(v, "TomoGRAF", c)], scores[(v, "SART-TV from the mean", c)]),
                     2 if "psnr" in c else 3)
                for c in ("psnr_db", "ssim", "body_psnr_db", "body_ssim")]
        net = cell(paired(scores[(v, "TomoGRAF (network only)", "body_psnr_db")],
                          scores[(v, "mean training volume", "body_psnr_db")]), 2)
        print(f"| {v} | " + " | ".join(cols) + f" | {net} |")
    print()
    if item_names is not None:
        per_item(scores, views, item_names)
