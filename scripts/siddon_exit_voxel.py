"""Which voxel a cone-beam ray leaves the volume through, and its contribution (mm * mu).

Used by compare_plastimatch.py to explain pixels where plastimatch (which drops each
ray's last voxel) differs from tomograf. Pure numpy, independent of tomograf's tracer:
all plane crossings are collected and the last segment inside the grid is looked up.
The grid is LPS-identity with voxel (i, j, k) centred at iso + ((i, j, k) - (n - 1)/2) * spacing.
"""
import numpy as np


def exit_voxel_contribution(mu, spacing, iso, sad, sid, n, pitch, row, col):
    dims = np.array(mu.shape, dtype=float)
    sp = np.array(spacing, dtype=float)
    src = iso + np.array([0.0, -sad, 0.0])
    det_centre = src + np.array([0.0, sid, 0.0])
    px = det_centre + np.array([(col - (n - 1) / 2) * pitch, 0.0, -(row - (n - 1) / 2) * pitch])
    # Grid coordinates: voxel (i, j, k) = [i, i+1) x ...
    g0 = (src - iso) / sp + dims / 2.0
    gd = (px - src) / sp
    ts = [0.0, 1.0]
    lo, hi = 0.0, 1.0
    for a in range(3):
        if gd[a] == 0:
            continue
        t1, t2 = (0 - g0[a]) / gd[a], (dims[a] - g0[a]) / gd[a]
        lo, hi = max(lo, min(t1, t2)), min(hi, max(t1, t2))
        ts += list((np.arange(int(dims[a]) + 1) - g0[a]) / gd[a])
    # Distinct crossings: a ray leaving through an edge or corner crosses two planes at
    # (nearly) the same t; merged, so that no rounding-sized last segment stands in for
    # the exit voxel.
    ts = np.sort(np.array([t for t in ts if lo <= t <= hi]))
    if len(ts) > 1:
        ts = ts[np.concatenate(([True], np.diff(ts) > 1e-12))]
    if len(ts) < 2:
        return 0.0
    a, b = ts[-2], ts[-1]
    mid = g0 + 0.5 * (a + b) * gd
    i, j, k = np.clip(np.floor(mid).astype(int), 0, dims.astype(int) - 1)
    length = (b - a) * np.linalg.norm(px - src)
    return float(mu[i, j, k]) * length
