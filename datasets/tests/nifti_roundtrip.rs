//! NIfTI write → read round trips, the consistency of the sform and qform we write, and a
//! check of the header fields that end up in the file against the geometry computed by
//! hand. (The byte-level reading checks, independent of any NIfTI library, are in
//! `nifti_handmade.rs`.)

use glam::{DMat3, DVec3};
use std::path::Path;
use tomograf_datasets::nifti::{read_nifti, write_nifti};
use tomograf_sim::Volume;

fn volume(dims: [usize; 3], direction: DMat3) -> Volume {
    let n = dims[0] * dims[1] * dims[2];
    let data = (0..n)
        .map(|i| (i as f32 * 0.37 - 11.0) * (i % 7) as f32)
        .collect();
    Volume::new(
        dims,
        DVec3::new(0.7, 1.3, 2.9),
        DVec3::new(-123.25, 45.5, 310.75),
        direction,
        data,
    )
    .unwrap()
}

fn rotated() -> DMat3 {
    DMat3::from_axis_angle(DVec3::new(1.0, -2.0, 0.5).normalize(), 0.8)
}

fn reflected() -> DMat3 {
    DMat3::from_rotation_x(0.4) * DMat3::from_diagonal(DVec3::new(1.0, -1.0, 1.0))
}

fn assert_same(a: &Volume, b: &Volume) {
    assert_eq!(a.dims(), b.dims());
    // Geometry goes through f32 header fields: relative precision ~1e-7.
    assert!(
        (a.spacing() - b.spacing()).abs().max_element() < 1e-5,
        "{} {}",
        a.spacing(),
        b.spacing()
    );
    assert!(
        (a.origin() - b.origin()).abs().max_element() < 1e-4,
        "{} {}",
        a.origin(),
        b.origin()
    );
    assert!(
        a.direction().abs_diff_eq(b.direction(), 1e-6),
        "{} {}",
        a.direction(),
        b.direction()
    );
    assert_eq!(a.data(), b.data());
}

fn list(dir: &Path) -> Vec<String> {
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn round_trip_rotated_reflected_and_identity() {
    let dir = tempfile::tempdir().unwrap();
    for (tag, d) in [
        ("rot", rotated()),
        ("refl", reflected()),
        ("id", DMat3::IDENTITY),
    ] {
        assert!(tag != "refl" || d.determinant() < 0.0);
        let v = volume([5, 4, 3], d);
        for ext in ["nii", "nii.gz"] {
            let path = dir.path().join(format!("{tag}.{ext}"));
            write_nifti(&path, &v).unwrap();
            assert_same(&v, &read_nifti(&path).unwrap());
        }
    }
    // Compressed output really is gzip; nothing but the outputs is left in the directory.
    assert_eq!(
        &std::fs::read(dir.path().join("rot.nii.gz")).unwrap()[..2],
        &[0x1f, 0x8b]
    );
    assert_eq!(list(dir.path()).len(), 6);
}

/// The qform we write must describe the same grid as the sform: zero the sform code
/// (bytes 254–255) and read again.
#[test]
fn written_qform_matches_sform() {
    let dir = tempfile::tempdir().unwrap();
    for d in [rotated(), reflected(), DMat3::IDENTITY] {
        let v = volume([3, 2, 4], d);
        let path = dir.path().join("q.nii");
        write_nifti(&path, &v).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[254..256].copy_from_slice(&0i16.to_le_bytes());
        std::fs::write(&path, &bytes).unwrap();
        assert_same(&v, &read_nifti(&path).unwrap());
    }
}

/// Reads the written header back with the `nifti` crate's parser and checks its fields
/// against the RAS affine computed by hand from the LPS volume, and its first bytes
/// against the NIfTI-1 layout (little-endian `sizeof_hdr` = 348).
#[test]
fn header_agrees_with_the_nifti_crate() {
    let dir = tempfile::tempdir().unwrap();
    for (d, qfac) in [(rotated(), 1.0), (reflected(), -1.0)] {
        let v = volume([5, 4, 3], d);
        let path = dir.path().join("x.nii.gz");
        write_nifti(&path, &v).unwrap();
        let h = nifti::NiftiHeader::from_file(&path).unwrap();
        assert_eq!(h.sizeof_hdr, 348);
        assert_eq!(h.endianness, nifti::Endianness::Little);
        assert_eq!(h.xyzt_units, 2); // mm
        assert_eq!((h.scl_slope, h.scl_inter), (1.0, 0.0));
        assert_eq!(&h.magic, b"n+1\0");
        assert_eq!(&h.dim[..4], &[3, 5, 4, 3]);
        assert_eq!((h.datatype, h.bitpix), (16, 32));
        assert_eq!((h.sform_code, h.qform_code), (1, 1));
        assert_eq!(h.vox_offset, 352.0);
        assert_eq!(h.pixdim[0], qfac);
        assert_eq!(&h.pixdim[1..4], &[0.7, 1.3, 2.9]);
        let flip = DVec3::new(-1.0, -1.0, 1.0);
        let lin = DMat3::from_diagonal(flip) * v.direction() * DMat3::from_diagonal(v.spacing());
        let t = v.origin() * flip;
        for (r, row) in [h.srow_x, h.srow_y, h.srow_z].iter().enumerate() {
            let want = [lin.x_axis[r], lin.y_axis[r], lin.z_axis[r], t[r]];
            for c in 0..4 {
                assert!((f64::from(row[c]) - want[c]).abs() < 1e-5, "srow[{r}][{c}]");
            }
        }
        assert_eq!(
            [h.quatern_x, h.quatern_y, h.quatern_z],
            [123.25, -45.5, 310.75]
        );
    }
}

/// An axis longer than 32767 voxels needs NIfTI-2, which the `nifti` crate cannot write:
/// a clear error naming the file and the limit, and nothing left on disk.
#[test]
fn axis_beyond_nifti1_limit_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let v = volume([40_000, 1, 2], rotated());
    for name in ["wide.nii", "wide.nii.gz"] {
        let e = write_nifti(&dir.path().join(name), &v)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(name) && e.contains("32767") && e.contains("NIfTI-2 is not supported"),
            "{e}"
        );
    }
    assert!(list(dir.path()).is_empty(), "{:?}", list(dir.path()));
    // The largest NIfTI-1 axis still round-trips.
    let edge = volume([32_767, 1, 2], rotated());
    let path = dir.path().join("edge.nii");
    write_nifti(&path, &edge).unwrap();
    assert_same(&edge, &read_nifti(&path).unwrap());
}

/// Upper-case `.GZ` still compresses, and a name without the usual extension is written
/// as a single file under exactly that name (the crate is never left to pick the name).
#[test]
fn output_name_is_kept_and_gz_is_case_insensitive() {
    let dir = tempfile::tempdir().unwrap();
    let v = volume([3, 2, 2], reflected());
    for name in ["UPPER.NII.GZ", "plain.vol", "noext"] {
        let path = dir.path().join(name);
        write_nifti(&path, &v).unwrap();
        assert_same(&v, &read_nifti(&path).unwrap());
        let gz = std::fs::read(&path).unwrap().starts_with(&[0x1f, 0x8b]);
        assert_eq!(gz, name.ends_with(".GZ"), "{name}");
    }
    assert_eq!(list(dir.path()), vec!["UPPER.NII.GZ", "noext", "plain.vol"]);
}

#[test]
fn overwrite_is_atomic_and_leaves_no_temp_files() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ct.nii.gz");
    write_nifti(&path, &volume([2, 2, 2], DMat3::IDENTITY)).unwrap();
    let v = volume([3, 3, 3], rotated());
    write_nifti(&path, &v).unwrap();
    assert_same(&v, &read_nifti(&path).unwrap());
    assert_eq!(list(dir.path()), vec!["ct.nii.gz"]);
    let e = write_nifti(&dir.path().join("missing/ct.nii"), &v).unwrap_err();
    assert!(e.to_string().contains("missing/ct.nii"), "{e}");
}
