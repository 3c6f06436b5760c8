#!/usr/bin/env python3
"""Per-pixel scatter: tomograf's matched-physics Monte Carlo against Mitsuba 3's volpath.

Both sides simulate the same physics — monoenergetic light, one homogeneous box medium
(extinction mu_t mm⁻¹, constant single-scattering albedo, isotropic phase), a point
source of intensity 1 and a flat detector — with different algorithms:

* **tomograf** (``tomograf.scatter_matched``): photons from the source, free flights in
  the box, forced detection to every pixel centre at every collision (the X-ray engine's
  estimator), images in photons per pixel per unit intensity with standard errors from
  batch tallies.
* **Mitsuba 3** (``llvm_ad_mono``, ``volpath``): the reverse direction. Rays start at each
  pixel centre with directions uniform in the cone subtending the box's bounding sphere;
  ``volpath`` tracks them through the medium (a ``homogeneous`` interior of a null-BSDF
  ``cube``) and connects each medium vertex to the ``point`` emitter (next-event
  estimation). A pixel's flux is ⟨L·cos γ·Ω_cone⟩·A (A the pixel area). A point light
  cannot be hit, so this is scatter only: ``max_depth = 2`` gives single scatter and
  ``max_depth = -1`` all orders (the convention measured in ../shared/notes/mitsuba.md).

Statistic: per pixel z = (tomograf − Mitsuba) / √(se_t² + se_m²) for the single-scatter
and the total-scatter images, for an isotropic and a Henyey–Greenstein (g = 0.5) phase;
they agree when rms z ∈ [0.9, 1.1] (400 pixels per image: the sampling sd of rms z is
≈ 0.035). Deliberately wrong models — tomograf with the albedo 10 % low, and tomograf
with an isotropic phase against Mitsuba's g = 0.5 — must fail the same statistic.

    python bridge/tests/scatter_mitsuba.py --json out.json
    python bridge/tests/scatter_mitsuba.py --spp 16384 --photons 2000000 --out docs/scatter.md
"""

from __future__ import annotations

import argparse
import glob
import json
import math
import os
import sys
import time

import numpy as np

ROWS = COLS = 20
PITCH = 10.0  # mm
SOURCE = np.array([0.0, 0.0, -300.0])
DET_Z = 150.0  # detector plane z, mm; normal +z
BOX_MIN = np.array([-40.0, -40.0, -25.0])
BOX_MAX = np.array([40.0, 40.0, 25.0])
MU_T = 0.02  # mm⁻¹
ALBEDO = 0.8


def detector():
    """Pixel (0, 0) centre and the steps u (along columns), v (along rows)."""
    origin = np.array([-(COLS - 1) / 2 * PITCH, -(ROWS - 1) / 2 * PITCH, DET_Z])
    return origin, np.array([PITCH, 0.0, 0.0]), np.array([0.0, PITCH, 0.0])


def tomograf_side(photons: int, albedo: float, seed: int, g: float = 0.0):
    import tomograf

    o, u, v = detector()
    t = time.time()
    single, multiple, se_s, se_t = tomograf.scatter_matched(
        SOURCE.tolist(), o.tolist(), u.tolist(), v.tolist(), ROWS, COLS,
        BOX_MIN.tolist(), BOX_MAX.tolist(), MU_T, albedo, g=g, photons=photons, seed=seed)
    return dict(single=single, total=single + multiple, single_se=se_s, total_se=se_t,
                seconds=time.time() - t)


def mitsuba_side(spp: int, seed: int, g: float = 0.0):
    os.environ.setdefault("DRJIT_LIBLLVM_PATH",
                          next(iter(sorted(glob.glob("/usr/lib/*/libLLVM.so.19*"))), ""))
    import drjit as dr
    import mitsuba as mi

    mi.set_variant("llvm_ad_mono")
    centre = (BOX_MIN + BOX_MAX) / 2
    half = (BOX_MAX - BOX_MIN) / 2
    T = mi.ScalarTransform4f
    scene_dict = {
        "type": "scene",
        "box": {
            "type": "cube",
            "to_world": T().translate(centre.tolist()).scale(half.tolist()),
            "bsdf": {"type": "null"},
            "interior": {
                "type": "homogeneous",
                "sigma_t": MU_T,
                "albedo": ALBEDO,
                "phase": {"type": "isotropic"} if g == 0.0 else {"type": "hg", "g": g},
            },
        },
        "light": {"type": "point", "position": SOURCE.tolist(), "intensity": 1.0},
    }
    scene = mi.load_dict(scene_dict)
    o, u, v = detector()
    normal = np.cross(u, v)
    normal /= np.linalg.norm(normal)
    area = float(np.linalg.norm(np.cross(u, v)))
    radius = float(np.linalg.norm(half))
    out = {}
    t0 = time.time()
    for name, depth in (("single", 2), ("total", -1)):
        integrator = mi.load_dict({"type": "volpath", "max_depth": depth})
        n = ROWS * COLS * spp
        pix = np.repeat(np.arange(ROWS * COLS), spp)
        r, c = pix // COLS, pix % COLS
        p = o[None, :] + c[:, None] * u[None, :] + r[:, None] * v[None, :]
        # Directions uniform in the cone from the pixel to the box's bounding sphere.
        rng = np.random.default_rng(seed + depth + 7)
        axis = centre[None, :] - p
        dist = np.linalg.norm(axis, axis=1, keepdims=True)
        axis /= dist
        cos_cone = np.sqrt(1.0 - (radius / dist[:, 0]) ** 2)
        mu = cos_cone + (1.0 - cos_cone) * rng.random(n)
        phi = 2 * math.pi * rng.random(n)
        helper = np.where(np.abs(axis[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        e1 = np.cross(axis, helper)
        e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
        e2 = np.cross(axis, e1)
        s = np.sqrt(np.maximum(0.0, 1 - mu * mu))[:, None]
        d = axis * mu[:, None] + (e1 * np.cos(phi)[:, None] + e2 * np.sin(phi)[:, None]) * s
        weight = 2 * math.pi * (1 - cos_cone) * np.abs(d @ normal) * area
        sampler = mi.load_dict({"type": "independent"})
        sampler.seed(seed + depth, n)
        ray = mi.Ray3f(mi.Point3f(*[mi.Float(p[:, k]) for k in range(3)]),
                       mi.Vector3f(*[mi.Float(d[:, k]) for k in range(3)]))
        spec, _, _ = integrator.sample(scene, sampler, ray, None, True)
        dr.eval(spec)
        radiance = np.array(spec[0], dtype=np.float64)
        x = (radiance * weight).reshape(ROWS * COLS, spp)
        mean = x.mean(axis=1)
        se = x.std(axis=1, ddof=1) / math.sqrt(spp)
        out[name] = mean.reshape(ROWS, COLS)
        out[name + "_se"] = se.reshape(ROWS, COLS)
    out["seconds"] = time.time() - t0
    return out


def compare(t, m, key):
    z = (t[key] - m[key]) / np.sqrt(t[key + "_se"] ** 2 + m[key + "_se"] ** 2)
    return dict(rms_z=float(np.sqrt(np.mean(z * z))), mean_z=float(np.mean(z)),
                max_abs_z=float(np.max(np.abs(z))), pixels=int(z.size),
                median_rel_se_tomograf=float(np.median(t[key + "_se"] / t[key])),
                median_rel_se_mitsuba=float(np.median(m[key + "_se"] / m[key])),
                centre_tomograf=float(t[key][ROWS // 2, COLS // 2]),
                centre_mitsuba=float(m[key][ROWS // 2, COLS // 2]))


def run(spp: int, photons: int, seed: int = 1):
    rows = []
    for phase, g in (("isotropic", 0.0), ("Henyey–Greenstein g = 0.5", 0.5)):
        m = mitsuba_side(spp, seed, g)
        cases = [("matched", ALBEDO, "agree")]
        if g == 0.0:
            cases.append(("wrong: albedo 10 % low", 0.9 * ALBEDO, "reject"))
        else:
            cases.append(("wrong: isotropic phase", ALBEDO, "reject"))
        for model, albedo, expect in cases:
            t = tomograf_side(photons, albedo, seed, g if expect == "agree" else 0.0)
            for key in ("single", "total"):
                row = compare(t, m, key)
                row.update(case=key, phase=phase, model=model, expect=expect, spp=spp,
                           photons=photons, seconds_tomograf=t["seconds"],
                           seconds_mitsuba=m["seconds"])
                rows.append(row)
    return rows


def table(rows):
    head = ("| phase | image | tomograf model | expected | rms z | mean z | max abs z | pixels | "
            "centre: tomograf | centre: Mitsuba | median rel. se (t / M) |\n"
            "|---|---|---|---|---|---|---|---|---|---|---|\n")
    body = "".join(
        f"| {r['phase']} | {r['case']} scatter | {r['model']} | {r['expect']} | {r['rms_z']:.3f} | "
        f"{r['mean_z']:+.3f} | {r['max_abs_z']:.2f} | {r['pixels']} | {r['centre_tomograf']:.4e} | "
        f"{r['centre_mitsuba']:.4e} | {100 * r['median_rel_se_tomograf']:.2f} % / "
        f"{100 * r['median_rel_se_mitsuba']:.2f} % |\n" for r in rows)
    return head + body


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=2048)
    ap.add_argument("--photons", type=int, default=200_000)
    ap.add_argument("--json")
    ap.add_argument("--out", help="a markdown file whose scatter-mitsuba table to replace")
    a = ap.parse_args()
    t = time.time()
    rows = run(a.spp, a.photons)
    text = table(rows)
    took = time.time() - t
    print(text)
    print(f"{took:.1f} s")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"rows": rows, "seconds": took}, f, indent=1)
    if a.out:
        doc = open(a.out).read()
        start, end = "<!-- scatter-mitsuba-table -->", "<!-- /scatter-mitsuba-table -->"
        block = (f"{start}\n{text}\nProduced by `python bridge/tests/scatter_mitsuba.py --spp {a.spp} "
                 f"--photons {a.photons} --out docs/scatter.md` in {took:.0f} s.\n{end}")
        i, j = doc.index(start), doc.index(end) + len(end)
        open(a.out, "w").write(doc[:i] + block + doc[j:])


if __name__ == "__main__":
    sys.exit(main())
