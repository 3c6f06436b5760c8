#!/usr/bin/env python3
"""A choice on validation by a rule fixed beforehand: the first candidate stays unless another
beats it by a resolved paired difference.

    python3 scripts/validation_rule.py [--method M] [--metric body_psnr_db] \\
        NAME=EVAL_DIR[,EVAL_DIR …] NAME=… …

Each candidate is a name and its evaluation folders (`tomograf evaluate -o …`, one per
validation set, in the same order for every candidate; each folder's `items/*.csv` are read,
so a finished `results.csv` is not needed). For method M (default "TomoGRAF") and the metric
(default body PSNR), prints each candidate's mean per set and view count, its score (the
mean over the sets' and view counts' means) and its paired difference from the first
candidate over every (set, item, view count) pair both scored, with a 95 % t-interval. The
rule: a challenger replaces the first only if that difference is positive and its interval
excludes zero; among such challengers the highest score wins. --views keeps only those view
counts (default: every view count scored). Standard library only.
"""
import csv
import math
import pathlib
import statistics as st
import sys

# Two-sided 95 % Student t quantiles by degrees of freedom (beyond 30: the normal's 1.96
# is within 2 %; 40 and 60 tabulated).
T95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306,
       9: 2.262, 10: 2.228, 11: 2.201, 12: 2.179, 13: 2.160, 14: 2.145, 15: 2.131,
       16: 2.120, 17: 2.110, 18: 2.101, 19: 2.093, 20: 2.086, 21: 2.080, 22: 2.074,
       23: 2.069, 24: 2.064, 25: 2.060, 26: 2.056, 27: 2.052, 28: 2.048, 29: 2.045,
       30: 2.042, 40: 2.021, 60: 2.000}


def t95(df):
    if df in T95:
        return T95[df]
    below = max(k for k in T95 if k <= df) if df > 0 else 1
    return T95[below]


def load(folder, method, metric, views=None):
    """{(set, item, views): value} of one evaluation folder (only `views`, a set of view
    counts as strings, when given)."""
    out = {}
    files = sorted(pathlib.Path(folder).glob("items/*.csv"))
    if not files:
        sys.exit(f"{folder}: no items/*.csv (not an evaluation folder, or nothing scored)")
    for f in files:
        for r in csv.DictReader(open(f)):
            if r["method"] == method and (views is None or r["views"] in views):
                out[(pathlib.Path(folder).name, r["item"], r["views"])] = float(r[metric])
    return out


def main(argv):
    method, metric, keep_views, specs = "TomoGRAF", "body_psnr_db", None, []
    it = iter(argv)
    for a in it:
        if a == "--method":
            method = next(it)
        elif a == "--metric":
            metric = next(it)
        elif a == "--views":
            keep_views = set(next(it).split(","))
        elif "=" in a:
            name, dirs = a.split("=", 1)
            specs.append((name, dirs.split(",")))
        else:
            sys.exit(__doc__)
    if len(specs) < 2:
        sys.exit(__doc__)
    n_sets = {len(d) for _, d in specs}
    if len(n_sets) != 1:
        sys.exit("every candidate needs as many evaluation folders (one per set)")
    # Set k of every candidate is keyed by the first candidate's folder name.
    data = {}
    for name, dirs in specs:
        vals = {}
        for k, d in enumerate(dirs):
            key_set = pathlib.Path(specs[0][1][k]).name
            for (_, item, views), v in load(d, method, metric, keep_views).items():
                vals[(key_set, item, views)] = v
        data[name] = vals
    first = specs[0][0]
    cells = sorted({(s, v) for (s, _, v) in data[first]})
    names = [n for n, _ in specs]
    print(f"{method}, {metric}: mean per set and view count\n")
    print("| set | views | " + " | ".join(names) + " |")
    print("|---|---:|" + "---:|" * len(names))
    score = {n: [] for n in names}
    for s, v in cells:
        row = []
        for n in names:
            xs = [x for (ss, _, vv), x in data[n].items() if ss == s and vv == v]
            m = st.mean(xs) if xs else float("nan")
            score[n].append(m)
            row.append(f"{m:.2f} (n={len(xs)})")
        print(f"| {s} | {v} | " + " | ".join(row) + " |")
    print("| score (mean of the cells) | | " + " | ".join(
        f"{st.mean(score[n]):.3f}" for n in names) + " |")
    print(f"\nPaired difference from {first} over (set, item, view count) pairs, 95 % t:\n")
    winners = []
    for n in names[1:]:
        common = sorted(set(data[n]) & set(data[first]))
        d = [data[n][k] - data[first][k] for k in common]
        if len(d) < 2:
            print(f"- {n}: {len(d)} common pair(s), no interval")
            continue
        m = st.mean(d)
        h = t95(len(d) - 1) * st.stdev(d) / math.sqrt(len(d))
        resolved = m - h > 0
        print(f"- {n} − {first}: {m:+.3f} ± {h:.3f} over {len(d)} pairs"
              + (" (resolved, ahead)" if resolved else (" (resolved, behind)" if m + h < 0
                                                        else " (not resolved)")))
        if resolved:
            winners.append(n)
    choice = max(winners, key=lambda n: st.mean(score[n])) if winners else first
    print(f"\nThe rule chooses: {choice}.")


if __name__ == "__main__":
    main(sys.argv[1:])
