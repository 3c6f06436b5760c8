#!/usr/bin/env python3
"""Decisions 20 and 21's tuning (docs/real-ct/decision20-RULE.txt, decision21-RULE.txt): the
spread-weighted blend with SART-TV from the mean given the weight W2 in place of W when the
fits' average explains the view below P dB, scored on validation phantoms from volumes written
once per phantom.

    python3 scripts/decision20_grid.py [--decision 21] [--check SET=EVAL_DIR …] TUNE_DIR

--decision picks the rule's grid (20, the default: W in {0.25, 0.5}; 21: W in {0, 0.25, 0.5});
both have W2 in {0.5, 0.75, 1} with W2 > W, S in {50, 100, 200} HU and P in {37, 38, 39, 40} dB.
--check SET=EVAL_DIR: a `tomograf evaluate` folder of the shipped checkpoint on set SET, one
view; the shipped setting's score of each of SET's phantoms must agree with TomoGRAF's body
PSNR there to 1e-3 dB (the two paths make the same volume), else the script stops.

TUNE_DIR/SET/ID/ is what scripts/decision18.sh (or realistic_sets.sh's tuning_volumes) wrote
with the shipped networks and no blend:
net.nii.gz (TomoGRAF's one-view volume, HU), sd.nii.gz (the four fits' spread, HU),
classical.nii.gz (SART-TV from the mean volume, HU), item.txt, and net.log, whose last line
gives the volume's projection PSNR per view ("PSNR per view [p] dB"). Each setting
(W, W2, S, P) blends as decision 18 does, (1 − w) × net + w × classical with
w = W' × sd² / (sd² + S²) voxel by voxel, W' = W2 when the mean of the PSNRs is below P and W
otherwise, and is scored by body PSNR as model/src/metrics.rs scores it
(decision18_grid.body_psnr). The shipped checkpoint q is W = W2 = 0.5, S = 100 HU. Prints
each phantom's PSNR per view, the mean body PSNR per set and over the phantoms per setting,
and the rule's choice: the highest mean, if above q's; else none. Then, for reading, the
network's volume and SART-TV from the mean alone (no blend), mean body PSNR per set.

numpy and nibabel.
"""
import argparse
import csv
import json
import pathlib
import re
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from decision18_grid import BODY_HU, body_psnr, load  # noqa: E402

WEIGHTS = {20: [0.25, 0.5], 21: [0.0, 0.25, 0.5]}
WEIGHTS_BELOW = [0.5, 0.75, 1.0]
SPREADS_HU = [50.0, 100.0, 200.0]
BELOW_DB = [37.0, 38.0, 39.0, 40.0]
SHIPPED = (0.5, 0.5, 100.0, None)


def view_psnr(log):
    """The mean of the "PSNR per view [a, b, …] dB" on the log's last such line."""
    lines = [m for m in re.finditer(r"PSNR per view \[([^\]]*)\] dB", log.read_text())]
    if not lines:
        sys.exit(f"{log}: no 'PSNR per view' line")
    return float(np.mean([float(x) for x in lines[-1].group(1).split(",")]))


def settings(weights):
    yield SHIPPED
    for w in weights:
        for w2 in WEIGHTS_BELOW:
            if w2 <= w:
                continue
            for s in SPREADS_HU:
                for p in BELOW_DB:
                    yield (w, w2, s, p)


def check(rows, set_name, eval_dir):
    """Stops unless the shipped setting's score of every phantom of SET equals evaluate's."""
    n = 0
    for s, item_id, _, scores in rows:
        if s != set_name:
            continue
        f = pathlib.Path(eval_dir) / "items" / f"{item_id}.csv"
        want = [float(r["body_psnr_db"]) for r in csv.DictReader(f.open())
                if r["views"] == "1" and r["method"] == "TomoGRAF"]
        if len(want) != 1 or abs(scores[SHIPPED] - want[0]) > 1e-3:
            sys.exit(f"check {set_name}/{item_id}: {scores[SHIPPED]:.4f} dB here, {want} by evaluate")
        n += 1
    if n == 0:
        sys.exit(f"check {set_name}: no phantom of that set here")
    print(f"check: the shipped setting's body PSNR equals evaluate's ({eval_dir}) on {n} "
          f"phantom(s) of {set_name} to 1e-3 dB")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("tune_dir", type=pathlib.Path)
    ap.add_argument("--decision", type=int, choices=sorted(WEIGHTS), default=20)
    ap.add_argument("--check", action="append", default=[], metavar="SET=EVAL_DIR")
    args = ap.parse_args()
    tune = args.tune_dir
    rows = []  # (set, id, psnr per view, {setting: score})
    for d in sorted(p for p in tune.glob("*/*") if (p / "classical.nii.gz").is_file()):
        item = pathlib.Path((d / "item.txt").read_text().strip())
        window = json.loads((item / "item.json").read_text())["hu_window"]
        lo, hi = float(window["lo"]), float(window["hi"])
        truth = load(item / "ct.nii.gz")
        mask = truth > (BODY_HU - lo) / (hi - lo)
        net, sd, classical = (load(d / n) for n in ("net.nii.gz", "sd.nii.gz", "classical.nii.gz"))
        fit_db = view_psnr(d / "net.log")
        scores = {}
        for k in settings(WEIGHTS[args.decision]):
            w, w2, s, p = k
            weight = w2 if p is not None and fit_db < p else w
            wv = weight * sd**2 / (sd**2 + s**2)
            scores[k] = body_psnr((1 - wv) * net + wv * classical, truth, lo, hi, mask)
        scores["network"] = body_psnr(net, truth, lo, hi, mask)
        scores["classical"] = body_psnr(classical, truth, lo, hi, mask)
        rows.append((d.parent.name, d.name, fit_db, scores))
    if not rows:
        sys.exit(f"{tune}: no phantom with net.nii.gz, sd.nii.gz and classical.nii.gz")

    for c in args.check:
        check(rows, *c.split("=", 1))
    sets = sorted({r[0] for r in rows})
    print(f"# Decision {args.decision}, tuning\n")
    print("## The fits' average: projection PSNR of the one view (dB), per phantom\n")
    print("| set | " + " | ".join(f"#{i}" for i in range(max(
        sum(r[0] == s for r in rows) for s in sets))) + " |")
    print("|---|" + "---:|" * max(sum(r[0] == s for r in rows) for s in sets))
    for s in sets:
        print(f"| {s} | " + " | ".join(f"{r[2]:.2f}" for r in rows if r[0] == s) + " |")

    keys = [k for k in rows[0][3] if isinstance(k, tuple)]
    mean = {k: float(np.mean([r[3][k] for r in rows])) for k in keys}
    print(f"\n## TomoGRAF body PSNR (dB) from one view, mean over {len(rows)} phantoms\n")
    print("| W | W2 (below P) | S (HU) | P (dB) | " + " | ".join(sets) + " | all |")
    print("|---:|---:|---:|---:|" + "---:|" * (len(sets) + 1))
    for k in keys:
        per_set = [np.mean([r[3][k] for r in rows if r[0] == s]) for s in sets]
        label = f"{k[0]:g} (shipped)" if k == SHIPPED else f"{k[0]:g}"
        p = "—" if k[3] is None else f"{k[3]:g}"
        print(f"| {label} | {k[1]:g} | {k[2]:g} | {p} | "
              + " | ".join(f"{x:.3f}" for x in per_set) + f" | {mean[k]:.3f} |")
    best = max((k for k in keys if k != SHIPPED), key=lambda k: mean[k])
    print()
    name = f"W = {best[0]:g}, W2 = {best[1]:g}, S = {best[2]:g} HU, P = {best[3]:g} dB"
    if mean[best] > mean[SHIPPED]:
        print(f"chosen: {name} ({mean[best]:.3f} dB against {mean[SHIPPED]:.3f} as shipped)")
    else:
        print(f"chosen: none (the best, {name}, {mean[best]:.3f} dB, is not above "
              f"{mean[SHIPPED]:.3f} as shipped)")
    print("\n## Unblended: the network's volume and SART-TV from the mean, body PSNR (dB)\n")
    print("| set | network | SART-TV from the mean | difference |")
    print("|---|---:|---:|---:|")
    for s in sets:
        n, c = (np.mean([r[3][k] for r in rows if r[0] == s]) for k in ("network", "classical"))
        print(f"| {s} | {n:.2f} | {c:.2f} | {n - c:+.2f} |")


if __name__ == "__main__":
    main()
