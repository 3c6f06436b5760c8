#!/usr/bin/env python3
"""The prior probe's table (scripts/prior_probe.sh), from `tomograf evaluate` folders.

    python3 scripts/prior_probe_table.py NAME=EVAL_DIR [NAME=EVAL_DIR …]

NAME is `<population>-<variant>` (e.g. lidc-base, lidc-deform5). Per set and view count: the
mean body PSNR of TomoGRAF, its network alone, SART-TV from the mean and the mean volume,
on how many items the data-consistency sweeps ran (TomoGRAF's volume differs from the
network's), and the two differences issue 47's criteria ask about, paired over the items:
TomoGRAF − SART-TV from the mean and the network alone − the mean volume (body PSNR, dB,
mean ± the half-width of the 95 % t-interval; "ahead", "behind" or "tied"). Then, for each
variant of a population made from the same seeds as its `base`, how much the variant
moves TomoGRAF − SART-TV from the mean, paired item by item.
"""
import csv
import math
import statistics
import sys
from collections import defaultdict

# Two-sided 95 % Student t quantiles by degrees of freedom (published tables).
T95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306,
       9: 2.262, 10: 2.228, 11: 2.201, 12: 2.179, 13: 2.160, 14: 2.145, 15: 2.131}
TOMOGRAF, NETWORK = "TomoGRAF", "TomoGRAF (network only)"
SART_MEAN, MEAN = "SART-TV from the mean", "mean training volume"


def interval(d):
    mean = statistics.mean(d)
    half = T95.get(len(d) - 1, 1.96) * statistics.stdev(d) / math.sqrt(len(d))
    verdict = "tied" if abs(mean) <= half else ("ahead" if mean > 0 else "behind")
    return f"{mean:+.2f} ± {half:.2f} ({verdict})"


def load(folder):
    """{(views, method): {item: (body PSNR, PSNR)}}"""
    s = defaultdict(dict)
    for r in csv.DictReader(open(f"{folder}/results.csv")):
        s[(int(r["views"]), r["method"])][r["item"]] = (float(r["body_psnr_db"]), float(r["psnr_db"]))
    return s


def diff(s, v, a, b):
    items = sorted(set(s[(v, a)]) & set(s[(v, b)]))
    return {i: s[(v, a)][i][0] - s[(v, b)][i][0] for i in items}


sets = {}
for arg in sys.argv[1:] or sys.exit(__doc__):
    name, folder = arg.split("=", 1)
    sets[name] = load(folder)

print("| set | views | TomoGRAF | network alone | SART-TV from the mean | mean volume | sweeps ran "
      "| TomoGRAF − SART-TV from the mean | network alone − mean volume |")
print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
for name, s in sets.items():
    for v in sorted({k[0] for k in s}):
        m = {meth: statistics.mean(x[0] for x in s[(v, meth)].values())
             for meth in (TOMOGRAF, NETWORK, SART_MEAN, MEAN)}
        ran = sum(s[(v, TOMOGRAF)][i] != s[(v, NETWORK)][i] for i in s[(v, TOMOGRAF)])
        print(f"| {name} | {v} | {m[TOMOGRAF]:.2f} | {m[NETWORK]:.2f} | {m[SART_MEAN]:.2f} | "
              f"{m[MEAN]:.2f} | {ran} of {len(s[(v, TOMOGRAF)])} | "
              f"{interval(list(diff(s, v, TOMOGRAF, SART_MEAN).values()))} | "
              f"{interval(list(diff(s, v, NETWORK, MEAN).values()))} |")
print("\nBody PSNR in dB, means over the set's items; differences paired over them.\n")

pairs = []
for name in sets:
    population, _, variant = name.rpartition("-")
    if variant != "base" and f"{population}-base" in sets:
        pairs.append((f"{population}-base", name))
if pairs:
    print("| variant | views | (TomoGRAF − SART-TV from the mean) in the variant − in its base |")
    print("|---|---:|---:|")
    for base, wide in pairs:
        for v in sorted({k[0] for k in sets[wide]}):
            a, b = diff(sets[wide], v, TOMOGRAF, SART_MEAN), diff(sets[base], v, TOMOGRAF, SART_MEAN)
            d = [a[i] - b[i] for i in sorted(set(a) & set(b))]
            print(f"| {wide} against {base} | {v} | {interval(d)} |")
