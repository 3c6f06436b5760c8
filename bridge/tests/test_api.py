"""The Python API: round trips, conventions, closed-form checks and error messages."""

import numpy as np
import pytest

import tomograf as tg
from conftest import centroid, pinhole


def test_volume_array_round_trip_and_numpy_order():
    a = np.arange(4 * 3 * 2, dtype=np.float32).reshape(2, 3, 4)  # [k, j, i]
    v = tg.Volume(a, (1.0, 2.0, 3.0), origin=(10.0, 20.0, 30.0))
    assert v.dims == (4, 3, 2) and v.shape == (2, 3, 4)
    np.testing.assert_array_equal(v.array, a)
    assert v.spacing == (1.0, 2.0, 3.0) and v.origin == (10.0, 20.0, 30.0)
    # Voxel (i, j, k) = (3, 1, 0) sits at origin + spacing * ijk.
    assert v.index_to_world((3, 1, 0)) == pytest.approx((13.0, 22.0, 30.0))
    assert v.world_to_index((13.0, 22.0, 33.0)) == pytest.approx((3.0, 1.0, 1.0))
    # float64 and non-contiguous input is converted; default origin centres the grid.
    w = tg.Volume(np.asfortranarray(a.astype(np.float64)), (1.0, 1.0, 1.0))
    np.testing.assert_array_equal(w.array, a)
    assert w.centre == pytest.approx((0.0, 0.0, 0.0))
    np.testing.assert_array_equal(w.direction, np.eye(3))


def test_direction_rows_are_world_components():
    # Index axis i along world +y, j along world −x: columns of the matrix.
    d = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    v = tg.Volume(np.zeros((2, 2, 2), np.float32), (1, 1, 1), origin=(0, 0, 0), direction=d)
    np.testing.assert_allclose(v.direction, d, atol=1e-12)
    assert v.index_to_world((1, 0, 0)) == pytest.approx((0.0, 1.0, 0.0))


def test_nifti_round_trip(tmp_path):
    a = np.random.default_rng(1).normal(size=(5, 6, 7)).astype(np.float32)
    v = tg.Volume(a, (0.7, 0.8, 2.5), origin=(-3.0, 4.0, 5.0))
    p = tmp_path / "v.nii.gz"
    v.save_nifti(str(p))
    back = tg.Volume.load(str(p))
    np.testing.assert_array_equal(back.array, a)
    assert back.spacing == pytest.approx(v.spacing, rel=1e-6)
    assert back.origin == pytest.approx(v.origin, abs=1e-4)  # f32 header fields


def test_hu_to_mu_follows_the_formula():
    hu = np.array([[[-1200.0, -1000.0, 0.0, 1000.0]]], np.float32)
    mu = tg.Volume(hu, (1, 1, 1)).to_mu(mu_water_per_mm=0.02).array
    np.testing.assert_allclose(mu.ravel(), [0.0, 0.0, 0.02, 0.04], rtol=1e-6)
    # NIST XCOM/XAAMDI water, 60 keV: mu/rho = 0.2059 cm²/g → 0.02059 mm⁻¹ (table 0.5 %).
    assert tg.mu_water(60.0) == pytest.approx(0.02059, rel=5e-3)
    assert tg.Volume(hu, (1, 1, 1)).to_mu().array.ravel()[2] == pytest.approx(tg.mu_water(60.0), rel=1e-6)


def test_uniform_box_closed_form_chords():
    mu = float(np.float32(0.02))  # the value the f32 volume holds
    vol = tg.Volume(np.full((10, 12, 14), mu, np.float32), (2.0, 1.5, 1.0))  # 28 × 18 × 10 mm
    o = np.array([[-100.0, 0.3, 0.2], [0.1, -100.0, 0.2], [0.0, 0.0, -50.0]])
    d = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 2.0]])  # normalised inside
    for proj in ("siddon", "trilinear"):
        li = tg.line_integrals(vol, o, d, projector=proj, step_voxels=0.25)
        np.testing.assert_allclose(li, mu * np.array([28.0, 18.0, 10.0]), rtol=1e-5)
    # A segment that stops in the middle: half the x chord.
    li = tg.line_integrals(vol, o[:1], d[:1], t_min=0.0, t_max=100.0)
    assert li[0] == pytest.approx(mu * 14.0, rel=1e-9)


def test_point_object_lands_where_the_pinhole_formula_says():
    # One dense voxel at a known [k, j, i] position; the image centroid must sit at the
    # pixel the documented pose/detector conventions give (computed in numpy only).
    a = np.zeros((21, 21, 21), np.float32)
    k, j, i = 16, 7, 15
    a[k, j, i] = 1.0
    vol = tg.Volume(a, (2.0, 2.0, 2.0))
    p = vol.index_to_world((i, j, k))
    assert p == pytest.approx((10.0, -6.0, 12.0))  # patient left, anterior, superior
    # The voxel images to ≈ 3.2 mm = 16 pixels of 0.2 mm: tolerance 0.5 pixel = 0.1 mm
    # (pixel sampling and the perspective asymmetry of the box stay below 0.05 mm; a
    # half-voxel shift would move it by 1.6 mm, a transposed array by far more).
    geom = tg.Geometry.cone(500.0, 800.0, tg.Detector(241, 321, 0.2))
    for theta, phi in ((0, 0), (90, 0), (30, 20)):
        r, c = centroid(tg.project(vol, geom.view(tg.Pose(theta, phi))))
        er, ec = pinhole(p, theta, phi, 500.0, 800.0, 241, 321, 0.2)
        assert abs(r - er) < 0.5 and abs(c - ec) < 0.5, (theta, phi, r, c, er, ec)
    # AP: patient's left appears on the image's right, the head at the top.
    r, c = centroid(tg.project(vol, geom.view("ap")))
    assert c > 160 + 50 and r < 120 - 50


def test_general_form_views_equal_the_set_up_views():
    vol = tg.thorax(dims=(48, 40, 24), spacing_mm=(7.0, 6.0, 13.0)).to_mu()
    for geom in (tg.Geometry.cone(1000, 1500, tg.Detector(20, 30, 12.0)),
                 tg.Geometry.parallel(tg.Detector(20, 30, 12.0))):
        view = geom.view(tg.Pose(25, -10))
        if view.beam == "cone":
            again = tg.View.cone(view.source, view.detector_origin, view.u, view.v, view.rows, view.cols)
        else:
            again = tg.View.parallel(view.direction, view.detector_origin, view.u, view.v, view.rows, view.cols)
        a = tg.project(vol, view)
        np.testing.assert_array_equal(a, tg.project(vol, again))
        o, d, t0, t1 = view.rays()
        np.testing.assert_allclose(tg.line_integrals(vol, o, d, t0, t1), a, rtol=1e-6, atol=1e-6)


def test_views_stack_quantities_and_determinism():
    vol = tg.thorax(dims=(48, 40, 24), spacing_mm=(7.0, 6.0, 13.0)).to_mu()
    geom = tg.Geometry.cone(1000, 1500, tg.Detector(16, 24, 16.0))
    poses = tg.arc(0, 90, 4)
    assert [p.theta_deg for p in poses] == [0, 90, 180, 270]
    li = tg.project(vol, geom.views(poses))
    assert li.shape == (4, 16, 24) and li.dtype == np.float32 and li.max() > 1.0
    t = tg.project(vol, geom.views(poses), quantity="transmission")
    np.testing.assert_allclose(t, np.exp(-li.astype(np.float64)), rtol=1e-6)
    i = tg.project(vol, geom.views(poses), quantity="intensity", i0=1e4)
    np.testing.assert_allclose(i, 1e4 * np.exp(-li.astype(np.float64)), rtol=1e-6)
    assert tg.project(vol, geom.views(poses)).tobytes() == li.tobytes()
    # Every exact Siddon tracer renders the same images to rounding; auto is the default.
    assert tg.project(vol, geom.views(poses), tracer="auto").tobytes() == li.tobytes()
    for tracer in ("scalar", "packets", "sheets", "columns"):
        np.testing.assert_allclose(tg.project(vol, geom.views(poses), tracer=tracer), li, rtol=1e-6, atol=1e-6)


def test_analytic_thorax_line_integrals_match_a_fine_voxelisation():
    # Voxelisation error shrinks with the voxel: 2.5 mm voxels, mean |ΔL| well below 2 %
    # of the largest L (boundary voxels are the only error; they average out).
    geom = tg.Geometry.cone(1000, 1500, tg.Detector(24, 32, 15.0))
    view = geom.view("ap")
    exact = tg.thorax_line_integrals(view, tg.mu_water(60))
    vox = tg.project(tg.thorax(dims=(140, 100, 132), spacing_mm=(2.5, 2.5, 2.5)).to_mu(), view)
    assert np.mean(np.abs(vox - exact)) < 0.02 * exact.max()


def test_chest_phantoms_are_seeded():
    a = tg.chest(seed=3, dims=(40, 32, 30), spacing_mm=(9.0, 9.0, 11.0))
    b = tg.chest(seed=3, dims=(40, 32, 30), spacing_mm=(9.0, 9.0, 11.0))
    c = tg.chest(seed=4, dims=(40, 32, 30), spacing_mm=(9.0, 9.0, 11.0))
    assert a.array.tobytes() == b.array.tobytes() and a.array.tobytes() != c.array.tobytes()
    lo, hi = a.min_max()
    assert lo <= -1000 and hi > 300  # air and bone
    info = tg.describe_chest(seed=3, profile="full-chest", table=True)
    assert info["profile"] == "full-chest" and info["table_top_y_mm"] > 0 and 200 < info["width_mm"] < 500


@pytest.mark.parametrize(
    "call, exc, text",
    [
        (lambda: tg.Volume(np.full((2, 2, 2), np.nan, np.float32), (1, 1, 1)), ValueError, "non-finite value (NaN) at voxel (i=0, j=0, k=0)"),
        (lambda: tg.Volume(np.zeros((2, 2, 2), np.float32), (1, -1, 1)), ValueError, "spacing along axis 1 is -1 mm"),
        (lambda: tg.Volume(np.zeros((2, 2, 2)), (1, 1, 1), direction=np.ones((3, 3))), ValueError, "invalid volume"),
        (lambda: tg.Volume.load("/nonexistent/ct.nii.gz"), FileNotFoundError, "/nonexistent/ct.nii.gz: opening failed"),
        (lambda: tg.Geometry.cone(1000, 900, tg.Detector(4, 4, 1.0)), ValueError, "SID (900 mm) is smaller than SAD (1000 mm)"),
        (lambda: tg.Detector(0, 4, 1.0), ValueError, "empty detector"),
        (lambda: tg.Detector(4, 4, 0.0), ValueError, "column pitch is 0 mm"),
        (lambda: tg.arc(0, 5, 0), ValueError, "at least one view"),
        (lambda: tg.Pose.parse("sideways"), ValueError, "sideways"),
        (lambda: tg.mu_water(1e6), ValueError, "out of range"),
        (lambda: tg.chest(profile="torso"), ValueError, "unknown anatomy profile 'torso'"),
        (lambda: tg.View.parallel((0, 0, 0), (0, 0, 0), (1, 0, 0), (0, 1, 0), 2, 2), ValueError, "zero vector"),
        (lambda: tg.View.cone((0, 0, 0), (0, 0, 0), (1, 0, 0), (0, 1, 0), 2, 2), ValueError, "lies in the detector plane"),
    ],
)
def test_errors_carry_the_rust_message(call, exc, text):
    with pytest.raises(exc) as e:
        call()
    assert text in str(e.value)


def test_render_errors():
    hu = tg.thorax(dims=(8, 8, 8), spacing_mm=(40, 40, 40))
    view = tg.Geometry.cone(1000, 1500, tg.Detector(4, 4, 80.0)).view("ap")
    with pytest.raises(ValueError, match="negative values .* convert HU first with Volume.to_mu"):
        tg.project(hu, view)
    mu = hu.to_mu()
    with pytest.raises(ValueError, match="unknown projector 'raycast'"):
        tg.project(mu, view, projector="raycast")
    with pytest.raises(ValueError, match="trilinear step is 0 voxels"):
        tg.project(mu, view, projector="trilinear", step_voxels=0.0)
    with pytest.raises(ValueError, match="I0 = -1"):
        tg.project(mu, view, quantity="intensity", i0=-1.0)
    with pytest.raises(ValueError, match="unknown quantity 'dose'"):
        tg.project(mu, view, quantity="dose")
    with pytest.raises(ValueError, match="unknown tracer 'fast': use auto, scalar, packets, sheets or columns"):
        tg.project(mu, view, tracer="fast")
    with pytest.raises(ValueError, match=r"must have the same shape \(\.\.\., 3\)"):
        tg.line_integrals(mu, np.zeros((3, 3)), np.ones((2, 3)))
    with pytest.raises(ValueError, match="direction non-zero"):
        tg.line_integrals(mu, np.zeros((1, 3)), np.zeros((1, 3)))


def test_corrupt_file_is_a_value_error(tmp_path):
    p = tmp_path / "bad.nii"
    p.write_bytes(b"not a nifti file at all" * 20)
    with pytest.raises(ValueError, match="bad.nii"):
        tg.Volume.load(str(p))


def test_type_stubs_cover_the_module():
    import ast
    from pathlib import Path

    stub_path = Path(__file__).resolve().parents[1] / "python" / "tomograf" / "_native.pyi"
    stub = ast.parse(stub_path.read_text())
    declared = {n.name for n in stub.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
    public = {n for n in dir(tg._native) if not n.startswith("_")}
    assert declared == public
    # The package re-exports every public name of the compiled core.
    assert all(getattr(tg, n) is getattr(tg._native, n) for n in public)
    classes = {n.name: n for n in stub.body if isinstance(n, ast.ClassDef)}
    for name, node in classes.items():
        members = {m.name for m in node.body if isinstance(m, ast.FunctionDef)} - {"__init__"}
        actual = {m for m in dir(getattr(tg, name)) if not m.startswith("_")}
        assert members == actual, name


def test_the_docs_example_runs(tmp_path, monkeypatch):
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "python.md").read_text()
    block = re.search(r"## Example\n\n```python\n(.*?)```", text, re.S).group(1)
    monkeypatch.chdir(tmp_path)
    exec(compile(block.replace("/tmp/zeros.nii.gz", str(tmp_path / "zeros.nii.gz")), "python.md", "exec"), {})
    assert (tmp_path / "zeros.nii.gz").exists()


def test_rendering_releases_the_gil():
    # While a slow render runs in a worker thread, the main thread keeps executing Python.
    # With the GIL held for the whole render, no main-thread iteration could fall inside it.
    import threading
    import time

    mu = tg.Volume(np.full((48, 48, 48), 0.01, np.float32), (1.0, 1.0, 1.0))
    # One render long enough on fast CPUs too (about 0.4 s on an Intel Xeon with AVX-512 in
    # 2026; 96² pixels took 0.09 s there): the main thread must tick inside it.
    view = tg.Geometry.cone(500, 800, tg.Detector(192, 192, 0.5)).view(tg.Pose(20, 10))
    span = {}

    def work():
        span["start"] = time.perf_counter()
        tg.project(mu, view, projector="trilinear", step_voxels=0.05)
        span["end"] = time.perf_counter()

    t = threading.Thread(target=work)
    ticks = []
    t.start()
    while t.is_alive():
        ticks.append(time.perf_counter())
    t.join()
    assert span["end"] - span["start"] > 0.1, "render too fast to tell"
    inside = [x for x in ticks if span["start"] + 0.02 < x < span["end"] - 0.02]
    assert len(inside) > 100


def test_acquire_gives_seeded_detector_images_close_to_the_drr():
    hu = tg.thorax(dims=(48, 40, 24), spacing_mm=(7.0, 6.0, 13.0))
    geom = tg.Geometry.cone(1000, 1500, tg.Detector(16, 24, 16.0))
    views = geom.views([tg.Pose(0, 0), tg.Pose(90, 0)])
    a = tg.acquire(hu, views, seed=3)
    assert a.shape == (2, 16, 24) and a.dtype == np.float32
    assert np.isfinite(a).all()
    assert np.array_equal(a, tg.acquire(hu, views, seed=3))
    assert not np.array_equal(a, tg.acquire(hu, views, seed=4))
    # 120 kVp behind the body is close to the 60 keV DRR (within 15 % on the body).
    drr = tg.project(hu.to_mu(60.0), views)
    body = drr > 1.0
    assert abs(a[body].sum() / drr[body].sum() - 1.0) < 0.15
    raw = tg.acquire(hu, views[0], signal="raw", kvp=100, energy_bins=10)
    assert raw.shape == (16, 24) and (raw == np.round(raw)).all()
    assert "kv-flat-panel-120kvp" in tg.presets()
    with pytest.raises(ValueError, match="unknown acquisition preset 'nope'"):
        tg.acquire(hu, views, preset="nope")
    with pytest.raises(ValueError, match="tube potential 30 kV"):
        tg.acquire(hu, views, kvp=30)


def test_dose_is_a_seeded_volume_in_gray_proportional_to_the_exposure():
    hu = tg.thorax(dims=(24, 20, 12), spacing_mm=(14.0, 12.0, 26.0))
    views = tg.Geometry.cone(1000, 1500, tg.Detector(8, 8, 48.0)).views(
        [tg.Pose(0, 0), tg.Pose(90, 0)]
    )
    d = tg.dose(hu, views, photons=20000, seed=1)
    assert d.dims == hu.dims and d.spacing == hu.spacing
    gy = d.array
    assert np.isfinite(gy).all() and (gy >= 0).all() and gy.max() > 0
    # Air has no mass and gets no dose; the same seed gives the same bytes.
    assert gy[hu.array < -990].max() == 0.0
    np.testing.assert_array_equal(gy, tg.dose(hu, views, photons=20000, seed=1).array)
    # The same histories at twice the mAs: twice the dose.
    twice = tg.dose(hu, views, mas=2.0, photons=20000, seed=1).array
    np.testing.assert_allclose(twice, 2.0 * gy, rtol=1e-6)
    with pytest.raises(ValueError, match="photons = 0"):
        tg.dose(hu, views, photons=0)


def test_acquire_warns_of_photon_starvation_and_names_mas():
    hu = tg.thorax(dims=(48, 40, 24), spacing_mm=(7.0, 6.0, 13.0))
    view = tg.Geometry.cone(1000, 1500, tg.Detector(16, 24, 16.0)).view(tg.Pose(90, 0))
    with pytest.warns(UserWarning, match=r"photon starvation.*mas = 0.0001 now: mas="):
        tg.acquire(hu, view, mas=1e-4, signal="log-line-integral")
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tg.acquire(hu, view)  # the preset's exposure starves nothing


def test_acquire_takes_the_detector_names_of_the_cli():
    hu = tg.thorax(dims=(48, 40, 24), spacing_mm=(7.0, 6.0, 13.0))
    view = tg.Geometry.cone(1000, 1500, tg.Detector(16, 24, 16.0)).view(tg.Pose(0, 0))
    assert {"perfect-absorber", "ideal", "noiseless-csi"} <= set(tg.detector_models())
    perfect = tg.acquire(hu, view, detector="perfect-absorber")
    csi = tg.acquire(hu, view, detector="noiseless-csi")
    # Both noiseless: the same call gives the same image whatever the seed.
    assert np.array_equal(csi, tg.acquire(hu, view, detector="noiseless-csi", seed=9))
    assert np.array_equal(perfect, tg.acquire(hu, view, detector="ideal"))
    # CsI's η(E) hardens the recorded beam: more attenuation behind the body (docs/detector.md:
    # +3.4 % behind 200 mm of water).
    body = perfect > 1.0
    ratio = csi[body].sum() / perfect[body].sum()
    assert 1.005 < ratio < 1.10, ratio
    with pytest.raises(ValueError, match="unknown detector model 'csi'"):
        tg.acquire(hu, view, detector="csi")
