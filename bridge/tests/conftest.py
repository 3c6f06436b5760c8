"""Shared helpers for the bridge tests."""

import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def pinhole(p_lps, theta_deg, phi_deg, sad, sid, rows, cols, pitch, iso=(0.0, 0.0, 0.0)):
    """(row, col) of world point p on the detector, from the documented conventions only
    (README: pose formula, pixel (0,0) top-left in beam's-eye view) — no tomograf code."""
    t, f = np.radians(theta_deg), np.radians(phi_deg)
    s = np.array([np.sin(t) * np.cos(f), -np.cos(t) * np.cos(f), np.sin(f)])
    w = np.array([-np.sin(t) * np.sin(f), np.cos(t) * np.sin(f), np.cos(f)])
    u, v = np.cross(-s, w), -w
    iso = np.asarray(iso, float)
    src = iso + sad * s
    d = np.asarray(p_lps, float) - src
    # Intersect the plane through iso − (sid − sad)·s with normal s.
    lam = sid / np.dot(d, -s)
    hit = src + lam * d - (iso - (sid - sad) * s)
    return (rows - 1) / 2 + np.dot(hit, v) / pitch, (cols - 1) / 2 + np.dot(hit, u) / pitch


def centroid(img):
    img = np.asarray(img, float)
    r, c = np.indices(img.shape)
    return (r * img).sum() / img.sum(), (c * img).sum() / img.sum()


@pytest.fixture(scope="session")
def cli_path():
    """The path of the `tomograf` command line (TOMOGRAF_BIN, else target/release/tomograf)."""
    exe = os.environ.get("TOMOGRAF_BIN") or str(ROOT / "target" / "release" / "tomograf")
    if not Path(exe).exists():
        exe = shutil.which("tomograf") or exe
    if not Path(exe).exists():
        pytest.fail(f"tomograf CLI not found at {exe}: run `cargo build --release` or set TOMOGRAF_BIN")
    return str(Path(exe).resolve())


@pytest.fixture(scope="session")
def cli(cli_path):
    """Runs the `tomograf` command line; fails the test on a non-zero exit."""
    exe = cli_path

    def run(*args):
        out = subprocess.run([exe, *map(str, args)], capture_output=True, text=True)
        assert out.returncode == 0, out.stderr
        return out

    return run
