#!/usr/bin/env python3
"""Tabulates a realism-gap study's evaluation cells, including a partial study (models
scored on some test sets or view counts only): mean ± std over the phantoms of each cell.

Usage: scripts/realism_table.py STUDY_DIR [metric]   (metric: psnr_db, ssim, rmse_hu,
body_psnr_db, …; default psnr_db). Reads STUDY_DIR/eval/<test set>/<cell>/results.csv as
written by `tomograf evaluate`; prints a Markdown table, rows method ← training set,
columns the test sets. A cell folder may carry the view counts it was scored at apart
(model-M-5-10: the 5- and 10-view rows of model M). Standard library only.
"""
import csv
import re
import statistics
import sys
from pathlib import Path

LEVELS = ["ideal-drr", "polychromatic", "noise-blur", "scatter", "scatter-corrected"]


def cells(study: Path):
    """(test set, cell name) → rows of its results.csv."""
    out = {}
    for test in LEVELS:
        for cell in sorted((study / "eval" / test).glob("*")):
            f = cell / "results.csv"
            if f.exists():
                with open(f, newline="") as fh:
                    out[(test, cell.name)] = list(csv.DictReader(fh))
    return out


def main():
    study = Path(sys.argv[1])
    metric = sys.argv[2] if len(sys.argv) > 2 else "psnr_db"
    data = cells(study)
    levels = [t for t in LEVELS if any(k[0] == t for k in data)]
    # (views, label) → test set → values
    table = {}
    for (test, cell), rows in data.items():
        for r in rows:
            method = r["method"]
            if cell.startswith("model-"):
                # A cell scored at some view counts apart is named model-M-5-10: strip them.
                train = re.sub(r"(-\d+)+$", "", cell[len("model-"):])
                if method.startswith("TomoGRAF"):
                    label = f"{method} ← {train}"
                elif method == "PCA-MAP prior":
                    label = f"PCA-MAP ← {train}"
                else:
                    continue  # mean volume, SART-TV from the mean: one row is enough
                    # (they depend on the training set only through its mean)
            elif method == "PCA-MAP prior":
                continue  # a classical cell given a training set only for its mean volume
            else:
                label = method
            key = (int(r["views"]), label)
            table.setdefault(key, {}).setdefault(test, []).append(float(r[metric]))
    # The mean volume and SART-TV from the mean of the ideal-drr training set.
    for (test, cell), rows in data.items():
        if cell != "model-ideal-drr":
            continue
        for r in rows:
            if r["method"] in ("mean training volume", "SART-TV from the mean"):
                key = (int(r["views"]), r["method"] + " ← ideal-drr")
                table.setdefault(key, {}).setdefault(test, []).append(float(r[metric]))
    print(f"| views | method | " + " | ".join(f"`{t}`" for t in levels) + " |")
    print("|---|---|" + "---|" * len(levels))
    for key in sorted(table, key=lambda k: (k[0], order(k[1]))):
        views, label = key
        vals = []
        for t in levels:
            v = table[key].get(t, [])
            if not v:
                vals.append("—")
            else:
                sd = statistics.stdev(v) if len(v) > 1 else 0.0
                fmt = "{:.3f} ± {:.3f}" if "ssim" in metric else "{:.2f} ± {:.2f}"
                vals.append(fmt.format(statistics.mean(v), sd) + ("" if len(v) == 8 else f" ({len(v)})"))
        print(f"| {views} | {label} | " + " | ".join(vals) + " |")


def order(label: str) -> tuple:
    first = ["TomoGRAF ←", "TomoGRAF (network only)", "PCA-MAP", "mean training", "SART-TV from",
             "FDK", "SART-TV"]
    for i, f in enumerate(first):
        if label.startswith(f):
            return (i, label)
    return (len(first), label)


if __name__ == "__main__":
    main()
