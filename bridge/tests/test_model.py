"""TomoGRAF from Python (`tomograf.reconstruct`, `tomograf.evaluate`) against the command
line (`tomograf reconstruct`, `tomograf evaluate`): the same item, checkpoint and seed give
the same volume bit for bit and the same scores, and progress is reported per iteration.
The shipped demo checkpoint (64³) with a few inference iterations keeps it to seconds."""

import numpy as np
import pytest

import tomograf
from conftest import ROOT

CHECKPOINT = ROOT / "model" / "checkpoints" / "demo"


@pytest.fixture(scope="module")
def test_set(tmp_path_factory, cli):
    """One held-out 64³ phantom, every 36° plus AP and lateral, as the demo makes it."""
    out = tmp_path_factory.mktemp("model") / "test-set"
    cli("dataset", "-o", out, "--phantoms", "1", "--seed", "100000", "--size", "64",
        "--views", "10", "--split", "test")
    return out


def test_reconstruct_is_the_cli_reconstruction(tmp_path, cli, test_set):
    item = test_set / "00000"
    cli("reconstruct", item, "--checkpoint", CHECKPOINT, "-o", tmp_path / "cli.nii.gz",
        "--views", "2", "--iterations", "4", "--seed", "3")
    reports = []
    rec = tomograf.reconstruct(item, CHECKPOINT, views=2, iterations=4, seed=3,
                               progress=lambda *r: reports.append(r))
    ours, theirs = rec["volume"], tomograf.Volume.load(tmp_path / "cli.nii.gz")
    assert ours.array.shape == theirs.array.shape == (64, 64, 64)
    assert ours.array.tobytes() == theirs.array.tobytes()
    # The NIfTI header holds the grid in float32.
    assert np.allclose(ours.spacing, theirs.spacing) and np.allclose(ours.origin, theirs.origin)
    assert 1 <= rec["iterations"] <= 4 and len(rec["psnr_db"]) == 2
    # HU of a chest: air near −1000 somewhere, soft tissue or bone above 0 somewhere.
    assert ours.array.min() < -800 and ours.array.max() > 0
    assert reports and all(r[0] == "iteration" and r[2] == 4 for r in reports)
    by_pose = tomograf.reconstruct(item, CHECKPOINT, poses=["ap", "lateral"], iterations=4,
                                   seed=3)
    assert by_pose["volume"].array.tobytes() == ours.array.tobytes()


def test_reconstruct_returns_the_ensembles_spread(tmp_path, cli, test_set):
    """The demo checkpoint fits once: no spread, no blend. The mixed one averages four fits
    from one view: its spread (HU) is the command line's `--spread` file bit for bit, ≥ 0 and
    not zero everywhere, and it reports the blend its settings chose."""
    item = test_set / "00000"
    single = tomograf.reconstruct(item, CHECKPOINT, iterations=2)
    assert single["spread"] is None and single["blend"] is None
    mixed = ROOT / "model" / "checkpoints" / "lidc-full-chest"
    cli("reconstruct", item, "--checkpoint", mixed, "-o", tmp_path / "v.nii.gz",
        "--iterations", "2", "--spread", tmp_path / "sd.nii.gz")
    result = tomograf.reconstruct(item, mixed, iterations=2)
    ours = result["spread"]
    theirs = tomograf.Volume.load(tmp_path / "sd.nii.gz")
    assert ours.array.tobytes() == theirs.array.tobytes()
    assert ours.array.min() >= 0 and ours.array.max() > 0
    # The checkpoint blends only when the views are explained below mean_sweeps_below_db =
    # 40 dB. This in-distribution phantom's view is explained above it after the sweeps: no
    # blend. With one sweep it is not, and the blend runs with mean_sweeps_weight_below.
    assert min(result["psnr_db"]) >= 40.0 and result["blend"] is None
    one_sweep = tomograf.reconstruct(item, mixed, iterations=2, refine=1)["blend"]
    assert one_sweep["views_psnr_db"] < 40.0 and one_sweep["weight"] == 0.75


def test_evaluate_scores_as_the_cli_does(tmp_path, cli, test_set):
    cli("evaluate", test_set, "--checkpoint", CHECKPOINT, "-o", tmp_path / "cli",
        "--views", "1", "--iterations", "3", "--no-baselines")
    result = tomograf.evaluate(test_set, tmp_path / "py", checkpoint=CHECKPOINT, views=[1],
                               iterations=3, classical=False)
    rows = {r["method"]: r for r in result["rows"]}
    cli_csv = (tmp_path / "cli" / "items" / "00000.csv").read_text().splitlines()
    assert "TomoGRAF" in rows and len(rows) == len(cli_csv) - 1
    header = cli_csv[0].split(",")
    for line in cli_csv[1:]:
        cells = dict(zip(header, line.split(",")))
        ours = rows[cells["method"]]
        for key in ["psnr_db", "ssim", "rmse_hu"]:
            assert ours[key] == pytest.approx(float(cells[key]), rel=1e-6), (cells["method"], key)
    assert "TomoGRAF" in result["markdown"]
    assert np.isfinite(rows["TomoGRAF"]["psnr_db"])


def test_evaluate_takes_tuned_baselines(tmp_path, cli, test_set):
    # A baselines.toml with 5 SART-TV sweeps and no TV for one view: the Python call scores
    # SART-TV as the command line does with the same file, and not as with the defaults.
    settings = tmp_path / "baselines.toml"
    settings.write_text(
        'tuned_on = "by hand"\nrule = "test"\n[views.1]\nfdk_window = "hann"\n'
        "[views.1.sart_tv]\nsweeps = 5\ntv_step = 0.0\n"
        "[views.1.sart_tv_from_mean]\nsweeps = 5\ntv_step = 0.0\n"
        "[views.1.pca_map]\nnoise = 0.1\n")
    cli("evaluate", test_set, "-o", tmp_path / "cli", "--views", "1", "--baselines", settings)
    cli("evaluate", test_set, "-o", tmp_path / "default", "--views", "1")
    result = tomograf.evaluate(test_set, tmp_path / "py", views=[1], baselines=settings)
    ours = {r["method"]: r["psnr_db"] for r in result["rows"] if r["item"] == "00000"}

    def cli_psnr(folder):
        lines = (tmp_path / folder / "items" / "00000.csv").read_text().splitlines()
        header = lines[0].split(",")
        return {c["method"]: float(c["psnr_db"])
                for c in (dict(zip(header, line.split(","))) for line in lines[1:])}

    tuned, default = cli_psnr("cli"), cli_psnr("default")
    for method in ["SART-TV", "FDK"]:
        assert ours[method] == pytest.approx(tuned[method], rel=1e-6)
        assert abs(tuned[method] - default[method]) > 1e-3, method
    with pytest.raises(ValueError, match="tuned for 1 view"):
        tomograf.evaluate(test_set, tmp_path / "py2", views=[2], baselines=settings)
    with pytest.raises(ValueError, match="baselines"):
        tomograf.evaluate(test_set, tmp_path / "py3", views=[1], baselines=tmp_path / "none.toml")


def test_bad_arguments_are_refused_by_name(tmp_path, test_set):
    with pytest.raises(ValueError, match="scatter_correction"):
        tomograf.reconstruct(test_set / "00000", CHECKPOINT, scatter_correction="magic")
    with pytest.raises(ValueError, match="tune"):
        tomograf.reconstruct(test_set / "00000", CHECKPOINT, tune="everything")
    with pytest.raises(ValueError):
        tomograf.reconstruct(tmp_path / "no-item", CHECKPOINT)
