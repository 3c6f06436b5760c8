"""Independent readers: our NIfTI read by nibabel, our OpenEXR read by OpenImageIO,
and a NIfTI written by nibabel rendered by the `tomograf` CLI — values and orientation
checked against what the bridge says and against the documented conventions."""

import json

import nibabel as nib
import numpy as np
import OpenImageIO as oiio
import pytest

import tomograf as tg
from conftest import centroid, pinhole

LPS_TO_RAS = np.diag([-1.0, -1.0, 1.0])


def read_exr(path):
    inp = oiio.ImageInput.open(str(path))
    assert inp is not None, oiio.geterror()
    spec = inp.spec()
    img = inp.read_image(0, 0, 0, spec.nchannels, "float")
    inp.close()
    return spec, np.asarray(img)


def test_phantom_nifti_read_by_nibabel(tmp_path, cli):
    path = tmp_path / "thorax.nii.gz"
    cli("phantom", "-o", path, "--dims", "60,40,30", "--spacing", "6,7,11")
    img = nib.load(str(path))
    data = np.asarray(img.dataobj, dtype=np.float32)  # nibabel: [i, j, k]
    assert data.shape == (60, 40, 30)
    vol = tg.Volume.load(str(path))
    np.testing.assert_array_equal(data.transpose(2, 1, 0), vol.array)
    # The same voxels as the bridge's own phantom (same code, different path to disk).
    np.testing.assert_allclose(vol.array, tg.thorax(dims=(60, 40, 30), spacing_mm=(6, 7, 11)).array, atol=1e-3)
    # Affine: RAS from LPS, voxel centres as the bridge reports them.
    for ijk in ((0, 0, 0), (59, 0, 0), (3, 17, 29)):
        ras = img.affine @ np.array([*ijk, 1.0])
        np.testing.assert_allclose(ras[:3], LPS_TO_RAS @ np.array(vol.index_to_world(ijk)), atol=1e-3)
    # Index axes (i, j, k) run towards the patient's left, posterior, superior (LPS grid
    # stored with its RAS affine): nibabel names them L, P, S.
    assert nib.aff2axcodes(img.affine) == ("L", "P", "S")
    # Orientation: the phantom's dense marker sits at the patient's left, anterior,
    # superior side; nibabel's RAS coordinates of the densest voxels must say so.
    # The marker is the densest structure 50 mm or more off the midline.
    top = np.argwhere(data >= np.percentile(data, 99.9))
    pts = (img.affine @ np.c_[top, np.ones(len(top))].T)[:3].T
    marker = pts[np.abs(pts[:, 0]) > 50]
    assert len(marker), pts
    m = marker.mean(axis=0)
    assert m[0] < 0 and m[1] > 0 and m[2] > 0, m  # RAS: left (−R), anterior (+A), superior


def test_cli_exr_read_by_openimageio(tmp_path, cli):
    ct = tmp_path / "thorax.nii.gz"
    cli("phantom", "-o", ct, "--dims", "60,40,30", "--spacing", "6,7,11")
    out = tmp_path / "o"
    cli("project", ct, "--rows", "24", "--cols", "32", "--pitch", "14", "--view", "30,10",
        "--view", "ap", "--format", "exr,npy", "-o", out)
    spec, first = read_exr(out / "drr_000.exr")
    assert (spec.height, spec.width) == (24, 32) and spec.nchannels == 1
    side = json.loads((out / "drr.json").read_text())
    mu = tg.Volume.load(str(ct)).to_mu(energy_kev=60.0)
    for n in (0, 1):
        _, img = read_exr(out / f"drr_{n:03d}.exr")
        v = side["views"][n]
        view = tg.View.cone(v["beam"]["source"], v["detector_origin"], v["u"], v["v"], v["rows"], v["cols"])
        np.testing.assert_allclose(img[..., 0], tg.project(mu, view), rtol=1e-6, atol=1e-6)
        # The sidecar's geometry is the documented set-up at the volume's centre.
        geom = tg.Geometry.cone(1000, 1500, tg.Detector(24, 32, 14.0), isocentre=mu.centre)
        pose = tg.Pose(v["pose"]["theta_deg"], v["pose"]["phi_deg"])
        np.testing.assert_allclose(tg.project(mu, geom.view(pose)), img[..., 0], rtol=1e-6, atol=1e-6)


def test_nibabel_written_point_lands_where_the_conventions_say(tmp_path, cli):
    # A NIfTI written by nibabel (RAS affine), one dense voxel at the patient's left,
    # anterior, superior side; rendered by the CLI, read back with OpenImageIO.
    n, s = 21, 2.0
    data = np.zeros((n, n, n), np.float32)  # [i, j, k]
    ijk = (5, 13, 16)
    data[ijk] = 0.5  # mm⁻¹
    affine = np.diag([s, s, s, 1.0])
    affine[:3, 3] = -s * (n - 1) / 2
    ras = affine @ np.array([*ijk, 1.0])
    lps = LPS_TO_RAS @ ras[:3]
    assert lps[0] > 0 and lps[1] < 0 and lps[2] > 0  # left, anterior, superior
    path = tmp_path / "point.nii"
    nib.save(nib.Nifti1Image(data, affine), str(path))
    out = tmp_path / "o"
    rows, cols, pitch = 241, 321, 0.2
    for theta, phi in ((0, 0), (60, 15)):
        cli("project", path, "--units", "mu", "--isocentre", "0,0,0", "--sad", "500", "--sid", "800",
            "--rows", rows, "--cols", cols, "--pitch", pitch, "--view", f"{theta},{phi}",
            "--format", "exr", "-o", out)
        _, img = read_exr(out / "drr_000.exr")
        r, c = centroid(img[..., 0])
        er, ec = pinhole(lps, theta, phi, 500.0, 800.0, rows, cols, pitch)
        # 2 mm voxel → 16 pixels; 0.5 pixel = 0.1 mm tolerance (sampling and perspective
        # asymmetry < 0.05 mm; a mirrored axis would move it by tens of pixels).
        assert abs(r - er) < 0.5 and abs(c - ec) < 0.5, (theta, phi, r, c, er, ec)
        if theta == 0:
            assert c > cols / 2 and r < rows / 2  # AP: left on the image's right, head up


def test_dicom_series_loads_like_the_nifti(tmp_path, cli):
    cli("phantom", "-o", tmp_path / "t.nii.gz", "--dims", "30,20,12", "--spacing", "12,14,25")
    cli("phantom", "--dicom", "-o", tmp_path / "dcm", "--dims", "30,20,12", "--spacing", "12,14,25")
    a = tg.Volume.load(str(tmp_path / "t.nii.gz"))
    b = tg.Volume.load(str(tmp_path / "dcm"))
    assert a.dims == b.dims
    np.testing.assert_allclose(b.array, a.array, atol=0.5)  # DICOM stores HU rounded to int16
    np.testing.assert_allclose(b.origin, a.origin, atol=1e-3)
    np.testing.assert_allclose(b.spacing, a.spacing, rtol=1e-5)
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="empty: no DICOM files"):
        tg.Volume.load(str(tmp_path / "empty"))
