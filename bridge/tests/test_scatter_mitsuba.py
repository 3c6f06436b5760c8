"""Per-pixel scatter against Mitsuba 3 (matched physics), in its own Python process (a
wrong libLLVM aborts the process that loads drjit). Method and statistic:
scatter_mitsuba.py."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
SPP = int(os.environ.get("TOMOGRAF_SCATTER_MITSUBA_SPP", "8192"))
PHOTONS = int(os.environ.get("TOMOGRAF_SCATTER_MITSUBA_PHOTONS", "200000"))


@pytest.fixture(scope="module")
def rows(tmp_path_factory):
    out = tmp_path_factory.mktemp("scatter_mitsuba") / "agreement.json"
    proc = subprocess.run(
        [sys.executable, str(HERE / "scatter_mitsuba.py"), "--spp", str(SPP),
         "--photons", str(PHOTONS), "--json", str(out)],
        capture_output=True, text=True, timeout=600,
    )
    if not out.exists():
        pytest.fail(f"scatter_mitsuba.py died (exit {proc.returncode}):\n{proc.stdout}\n{proc.stderr}")
    return json.loads(out.read_text())["rows"]


def describe(r):
    return (f"{r['phase']} {r['case']} / {r['model']}: rms z {r['rms_z']:.3f}, mean z {r['mean_z']:+.3f}, "
            f"max |z| {r['max_abs_z']:.2f}, {r['pixels']} px, centre {r['centre_tomograf']:.4e} "
            f"vs {r['centre_mitsuba']:.4e}")


def test_single_and_total_scatter_agree_pixel_by_pixel(rows):
    agree = [r for r in rows if r["expect"] == "agree"]
    assert {(r["phase"], r["case"]) for r in agree} == {
        (p, c) for p in ("isotropic", "Henyey–Greenstein g = 0.5") for c in ("single", "total")}
    for r in agree:
        # 400 pixels: the sampling sd of rms z is ≈ 0.035, so [0.9, 1.1] is ≈ 3 sd wide.
        assert 0.9 <= r["rms_z"] <= 1.1, describe(r)
        # The check must be sharp: a few per cent per pixel on the Mitsuba side.
        assert r["median_rel_se_mitsuba"] < 0.03, describe(r)


def test_a_wrong_albedo_or_phase_is_rejected_by_the_same_statistic(rows):
    wrong = [r for r in rows if r["expect"] == "reject"]
    assert {r["model"] for r in wrong} == {"wrong: albedo 10 % low", "wrong: isotropic phase"}
    assert len(wrong) == 4
    for r in wrong:
        assert r["rms_z"] > 3.0, describe(r)
