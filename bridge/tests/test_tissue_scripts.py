"""scripts/tissue_stats.py and scripts/error_by_tissue.py on an item whose answers are known
by construction: an elliptic body of fat around soft tissue with a lung, bone beside it, in
air, stored as items store their CT ((HU − lo)/(hi − lo), lo −1024, hi 2048)."""
import json
import subprocess
import sys
from pathlib import Path

import nibabel as nib
import numpy as np
import pytest

SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"
LO, HI = -1024.0, 2048.0
N = 32


def write_item(folder: Path, hu: np.ndarray) -> Path:
    folder.mkdir(parents=True)
    nib.save(nib.Nifti1Image(((hu - LO) / (HI - LO)).astype(np.float32), np.eye(4)),
             folder / "ct.nii.gz")
    (folder / "item.json").write_text(json.dumps({"ct": "ct.nii.gz", "hu_window": {"lo": LO, "hi": HI}}))
    return folder


def phantom():
    """Body: the ellipse |x/12|² + |y/8|² ≤ 1 about the grid's centre on every level but the
    last four (air); fat −100 HU, soft tissue 40 inside |x/8|² + |y/5|² ≤ 1, a lung −800
    (a hole in the section: still body) inside a 3-voxel radius at x = −3, bone 400 on a
    2×2 column at x = +4."""
    i, j = np.meshgrid(np.arange(N) - 15.5, np.arange(N) - 15.5, indexing="ij")
    hu = np.full((N, N, N), -1000.0)
    section = np.full((N, N), -1000.0)
    section[(i / 12) ** 2 + (j / 8) ** 2 <= 1] = -100.0
    section[(i / 8) ** 2 + (j / 5) ** 2 <= 1] = 40.0
    section[(i + 3) ** 2 + j ** 2 <= 9] = -800.0
    section[(i >= 3.5) & (i <= 5.5) & (np.abs(j) <= 1)] = 400.0
    hu[:, :, : N - 4] = section[:, :, None]
    return hu, section


def run(*args):
    out = subprocess.run([sys.executable, *map(str, args)], check=True, capture_output=True, text=True)
    return out.stdout


def test_tissue_stats_reports_what_the_item_was_made_of(tmp_path):
    hu, section = phantom()
    item = write_item(tmp_path / "item", hu)
    rows = [r for r in run(SCRIPTS / "tissue_stats.py", f"made={item}").splitlines() if r.startswith("| made")]
    cells = [c.strip() for c in rows[0].strip("|").split("|")]
    body = (section > -1000).sum() * (N - 4) / N**3
    assert cells[2] == f"{100 * body:.0f} %"
    # Width 24 and depth 16 voxels of 32 at every level the body reaches.
    assert cells[3] == f"{24 / 32:.2f}" and cells[4] == f"{16 / 32:.2f}"
    # The lung fills more than 5 % of every section the body reaches: levels 0 … N − 5 of N.
    assert cells[5] == f"{0:.2f} / {(N - 4) / N:.2f}"
    # Each class is uniform: its mean is its value, its spread and texture zero.
    assert cells[6].startswith("-800 ± 0,") and cells[7].startswith("-100 ± 0, 0")
    assert cells[8] == "40 ± 0, 0" and cells[9].startswith("400 ± 0,")


def test_error_by_tissue_splits_a_known_error(tmp_path):
    hu, section = phantom()
    item = write_item(tmp_path / "item", hu)
    wrong = hu.copy()
    wrong[hu == -100.0] += 30.0  # fat 30 HU too dense, nothing else wrong
    nib.save(nib.Nifti1Image(wrong.astype(np.float32), np.eye(4)), tmp_path / "r.nii.gz")
    mean = np.ascontiguousarray(((hu - LO) / (HI - LO)).transpose(2, 1, 0)).astype(np.float32)
    np.save(tmp_path / "mean.npy", mean)
    out = run(SCRIPTS / "error_by_tissue.py", item, f"r={tmp_path / 'r.nii.gz'}", f"m={tmp_path / 'mean.npy'}")
    rows = {tuple(c.strip() for c in r.strip("|").split("|")[:2]): [c.strip() for c in r.strip("|").split("|")]
            for r in out.splitlines() if r.startswith("| r ") or r.startswith("| m ")}
    assert rows[("r", "fat")][4:7] == ["+30", "30", "1.00"]
    assert rows[("r", "soft tissue")][4:7] == ["+0", "0", "0.00"]
    # The mean volume stored as a checkpoint stores it ([k][j][i], normalised) is the truth.
    assert rows[("m", "whole body")][4:6] in (["+0", "0"], ["-0", "0"])


def test_error_by_tissue_refuses_another_grid(tmp_path):
    hu, _ = phantom()
    item = write_item(tmp_path / "item", hu)
    nib.save(nib.Nifti1Image(np.zeros((N, N, N - 1), np.float32), np.eye(4)), tmp_path / "r.nii.gz")
    with pytest.raises(subprocess.CalledProcessError) as e:
        run(SCRIPTS / "error_by_tissue.py", item, f"r={tmp_path / 'r.nii.gz'}")
    assert "is not the item's" in e.value.stderr
