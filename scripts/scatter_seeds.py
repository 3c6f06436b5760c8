#!/usr/bin/env python3
"""The error of one Monte Carlo scatter view over many seeds, against a converged reference
(docs/scatter.md, "One view over many seeds").

    python3 scripts/scatter_seeds.py CT REFERENCE.npy [--photons 14000] [--seeds 16] [--first-seed 1]
        [--split 1] [--sparse] [--sampler latin-hypercube|sobol] [--cell-mm 8] [--cell-check 0]
        [--bin target/release/tomograf] > A.md
    python3 scripts/scatter_seeds.py --paired A.md B.md

CT: the NIfTI file `tomograf bench --scatter CT --reference-cache REFERENCE.npy` made its
reference for (view 0, AP). For each seed 1..SEEDS, renders the bench's scene (256² panel of
430 mm, SAD 1000 / SID 1500, kv-flat-panel-120kvp; Monte Carlo, 16² points, 8² for multiple
scatter, 8 mm cells or `--cell-mm` (0: full resolution); the history count and split given)
with `tomograf project --scene`, its `scatter` image written (the preset's acquisition seed =
the seed: the scatter histories are drawn from it), and prints per seed the image's mean over the reference's (the scatter's
overall level) and its relative RMS error with the reference's own noise removed in
quadrature (the bench's "converged scatter rms"), then the mean, standard deviation and
worst over the seeds. The bench scores each rung over 2–3 rounds; this asks how far those
rounds can be from the mean. `--paired A.md B.md` reads two such outputs (two binaries or
settings, the same seeds) and prints B − A per seed's error: the mean with its 95 %
t-interval. Standard library only.
"""
import argparse
import math
import pathlib
import statistics as st
import struct
import subprocess
import sys
import tempfile


def read_npy(path):
    """(shape, values) of a little-endian f4/f8 NPY file."""
    data = pathlib.Path(path).read_bytes()
    if data[:6] != b"\x93NUMPY":
        sys.exit(f"{path}: not an NPY file")
    major = data[6]
    hlen = struct.unpack("<H" if major == 1 else "<I", data[8:10] if major == 1 else data[8:12])[0]
    start = (10 if major == 1 else 12) + hlen
    header = eval(data[(10 if major == 1 else 12):start].decode("latin1"))  # a dict literal
    kind = {"<f4": "f", "<f8": "d"}.get(header["descr"])
    if kind is None or header["fortran_order"]:
        sys.exit(f"{path}: {header['descr']} (fortran {header['fortran_order']}); want <f4 or <f8, C order")
    n = math.prod(header["shape"])
    return header["shape"], struct.unpack(f"<{n}{kind}", data[start:start + n * struct.calcsize(kind)])


SCENE = """[volume]
path = "{ct}"
[detector]
rows = 256
cols = 256
pitch_mm = [1.6796875, 1.6796875]
[views]
poses = ["ap"]
[acquisition]
preset = "kv-flat-panel-120kvp"
seed = {seed}
[scatter]
model = "monte-carlo"
photons = {photons}
split = {split}
sparse_multiple = {sparse}
sampler = "{sampler}"
grid = 16
multiple_grid = 8
{cells}{check}images = ["scatter"]
[output]
formats = ["npy"]
"""


# Two-sided 95 % Student t quantiles by degrees of freedom.
T95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306,
       9: 2.262, 10: 2.228, 11: 2.201, 12: 2.179, 13: 2.160, 14: 2.145, 15: 2.131,
       16: 2.120, 17: 2.110, 18: 2.101, 19: 2.093, 20: 2.086, 25: 2.060, 30: 2.042}


def paired(a_md, b_md):
    """B − A per seed, from two outputs of this script."""
    def errors(path):
        rows = {}
        for line in pathlib.Path(path).read_text().splitlines():
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if len(cells) == 3 and cells[0].isdigit():
                rows[int(cells[0])] = float(cells[2].rstrip(" %"))
        return rows
    a, b = errors(a_md), errors(b_md)
    seeds = sorted(set(a) & set(b))
    if len(seeds) < 2:
        sys.exit(f"{a_md}, {b_md}: fewer than two seeds in common")
    d = [b[k] - a[k] for k in seeds]
    df = len(d) - 1
    t = T95.get(df) or T95[max(k for k in T95 if k <= df)]
    h = t * st.stdev(d) / math.sqrt(len(d))
    verdict = "resolved" if abs(st.mean(d)) > h else "not resolved"
    print(f"{b_md} − {a_md}, converged scatter rms over {len(d)} seeds: "
          f"{st.mean(d):+.2f} ± {h:.2f} points (95 % t; {verdict}); "
          f"means {st.mean(a[k] for k in seeds):.2f} % → {st.mean(b[k] for k in seeds):.2f} %")


def main():
    if len(sys.argv) == 4 and sys.argv[1] == "--paired":
        return paired(sys.argv[2], sys.argv[3])
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("ct")
    ap.add_argument("reference")
    ap.add_argument("--photons", type=int, default=14000)
    ap.add_argument("--seeds", type=int, default=16)
    ap.add_argument("--first-seed", type=int, default=1,
                    help="seeds FIRST .. FIRST + SEEDS − 1 (fresh seeds for a confirmation)")
    ap.add_argument("--split", type=int, default=1)
    ap.add_argument("--sparse", action="store_true",
                    help="sparse_multiple = true (each later collision scores a quarter of the points)")
    ap.add_argument("--sampler", default="latin-hypercube", choices=["latin-hypercube", "sobol"])
    ap.add_argument("--cell-mm", type=float, default=8.0)
    ap.add_argument("--cell-check", type=int, default=0,
                    help="cell_check = K: one scored path in K also traced at full resolution "
                         "and each component scaled by the ratio (0: none)")
    ap.add_argument("--bin", default="target/release/tomograf")
    a = ap.parse_args()
    shape, ref2 = read_npy(a.reference)
    if len(shape) != 3 or shape[0] != 2:
        sys.exit(f"{a.reference}: shape {shape}; want the bench's cache (2 halves × rows × cols)")
    n = shape[1] * shape[2]
    h0, h1 = ref2[:n], ref2[n:]
    ref = [0.5 * (x + y) for x, y in zip(h0, h1)]
    ref_sq = sum(r * r for r in ref)
    noise2 = sum((x - y) ** 2 for x, y in zip(h0, h1)) / 4 / ref_sq
    ct = str(pathlib.Path(a.ct).resolve())
    print(f"{a.ct}, AP, {a.photons} histories" + (f" split ×{a.split}" if a.split > 1 else "")
          + (", sparse multiple" if a.sparse else "") + f", {a.sampler} start"
          + ", 16² points (8² multiple), "
          + (f"{a.cell_mm:g} mm cells" if a.cell_mm > 0 else "full resolution")
          + (f", cells checked on 1 path in {a.cell_check}" if a.cell_check > 0 else "")
          + f"; reference {a.reference} "
          f"(its own noise {100 * math.sqrt(noise2):.2f} %)\n")
    print("| seed | level (mean / reference's) | converged scatter rms |\n|---:|---:|---:|")
    errs, levels = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(a.first_seed, a.first_seed + a.seeds):
            scene = pathlib.Path(tmp, "scene.toml")
            cells = f"detection_cell_mm = {a.cell_mm}\n" if a.cell_mm > 0 else ""
            scene.write_text(SCENE.format(ct=ct, seed=seed, photons=a.photons, split=a.split,
                                          sparse=str(a.sparse).lower(), sampler=a.sampler,
                                          cells=cells,
                                          check=f"cell_check = {a.cell_check}\n"
                                          if a.cell_check > 0 else ""))
            out = pathlib.Path(tmp, f"out{seed}")
            subprocess.run([a.bin, "project", "--scene", str(scene), "-o", str(out)],
                           check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            sh, img = read_npy(out / "drr_scatter.npy")
            if math.prod(sh) != n:
                sys.exit(f"seed {seed}: scatter image {sh} against the reference's {shape[1:]}")
            e2 = sum((x - r) ** 2 for x, r in zip(img, ref)) / ref_sq
            err = 100 * math.sqrt(max(e2 - noise2, 0.0))
            level = sum(img) / sum(ref)
            errs.append(err)
            levels.append(level)
            print(f"| {seed} | {level:.4f} | {err:.2f} % |")
    print(f"\nOver {a.seeds} seeds: converged scatter rms {st.mean(errs):.2f} % (sd {st.stdev(errs):.2f}, "
          f"worst {max(errs):.2f} %); level {st.mean(levels):.4f} (sd {st.stdev(levels):.4f}).")


if __name__ == "__main__":
    main()
