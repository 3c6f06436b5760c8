"""Mitsuba 3 cross-validation, run in its own Python process (a wrong libLLVM aborts the
process that loads drjit). The statistics and cases are in mitsuba_agreement.py."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
SPP = int(os.environ.get("TOMOGRAF_MITSUBA_SPP", "1024"))


@pytest.fixture(scope="module")
def rows(tmp_path_factory):
    out = tmp_path_factory.mktemp("mitsuba") / "agreement.json"
    proc = subprocess.run(
        [sys.executable, str(HERE / "mitsuba_agreement.py"), "--spp", str(SPP), "--json", str(out)],
        capture_output=True, text=True, timeout=900,
    )
    if not out.exists():
        pytest.fail(f"mitsuba_agreement.py died (exit {proc.returncode}):\n{proc.stdout}\n{proc.stderr}")
    return json.loads(out.read_text())["rows"]


def describe(r):
    return (f"{r['case']} / {r['model']}: rms z {r['rms_z']:.3f}, mean z {r['mean_z']:+.3f}, "
            f"max |z| {r['max_abs_z']:.2f}, {r['pixels']} px, missed-pixel dev {r['missed_max_dev']:.1e}")


def test_every_correct_case_agrees_to_monte_carlo_noise(rows):
    agree = [r for r in rows if r["expect"] == "agree"]
    # Siddon/nearest at 3 cone poses + parallel, trilinear at 3 poses, the sensor path.
    assert len(agree) == 8
    assert sum(r["pixels"] for r in agree) > 30000
    for r in agree:
        assert 0.9 <= r["rms_z"] <= 1.1, describe(r)
        assert abs(r["mean_z"]) < 0.05, describe(r)
        assert r["missed_max_dev"] < 1e-6, describe(r)


def test_every_wrong_model_is_rejected_by_the_same_statistic(rows):
    wrong = [r for r in rows if r["expect"] == "reject"]
    kinds = {r["model"] for r in wrong} | {r["case"].split(", ")[-1] for r in wrong}
    for needed in ("wrong: volume shifted ½ voxel along x", "wrong: transposed axes",
                   "wrong: image flipped top–bottom", "wrong: fov across pixel centres"):
        assert needed in kinds, kinds
    for r in wrong:
        assert r["rms_z"] > 5.0, describe(r)
