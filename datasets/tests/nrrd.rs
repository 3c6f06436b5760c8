//! NRRD volumes: the files are written here by hand from the format's specification
//! (teem's NRRD0004: magic, `field: value` lines, an empty line, the samples with the first
//! axis fastest), so the reader is checked against the format, not against itself. One
//! 4 × 3 × 2 volume stored four ways — LPS raw little-endian int16, RAS gzip big-endian
//! float, a detached header, and an oblique LAS frame — must read as the same world volume.

use flate2::Compression;
use flate2::write::GzEncoder;
use glam::{DMat3, DVec3};
use std::io::Write;
use std::path::{Path, PathBuf};
use tomograf_datasets::DatasetError;
use tomograf_datasets::nrrd::read_nrrd;

const DIMS: [usize; 3] = [4, 3, 2];

/// HU of voxel (i, j, k): all distinct.
fn hu(i: usize, j: usize, k: usize) -> i16 {
    (100 * i + 10 * j + 1000 * k) as i16 - 1000
}

fn samples() -> Vec<i16> {
    let mut v = Vec::new();
    for k in 0..DIMS[2] {
        for j in 0..DIMS[1] {
            for i in 0..DIMS[0] {
                v.push(hu(i, j, k));
            }
        }
    }
    v
}

fn write(dir: &Path, name: &str, header: &str, data: &[u8]) -> PathBuf {
    let p = dir.join(name);
    let mut f = std::fs::File::create(&p).unwrap();
    f.write_all(header.as_bytes()).unwrap();
    f.write_all(b"\n").unwrap();
    f.write_all(data).unwrap();
    p
}

fn gzip(data: &[u8]) -> Vec<u8> {
    let mut e = GzEncoder::new(Vec::new(), Compression::default());
    e.write_all(data).unwrap();
    e.finish().unwrap()
}

/// The LPS file: voxels of 0.7 × 0.8 × 2.5 mm along +x, +y, +z from (−10, 20, 30).
const LPS: &str = "NRRD0004\n# a comment\ntype: short\ndimension: 3\n\
    space: left-posterior-superior\nsizes: 4 3 2\n\
    space directions: (0.7,0,0) (0,0.8,0) (0,0,2.5)\nkinds: domain domain domain\n\
    endian: little\nencoding: raw\nspace origin: (-10,20,30)\n";

fn lps_bytes() -> Vec<u8> {
    samples().iter().flat_map(|v| v.to_le_bytes()).collect()
}

#[test]
fn an_lps_file_reads_as_written() {
    let dir = tempfile::tempdir().unwrap();
    let v = read_nrrd(&write(dir.path(), "ct.nrrd", LPS, &lps_bytes())).unwrap();
    assert_eq!(v.dims(), DIMS);
    assert_eq!(v.spacing(), DVec3::new(0.7, 0.8, 2.5));
    assert_eq!(v.origin(), DVec3::new(-10.0, 20.0, 30.0));
    assert_eq!(v.direction(), DMat3::IDENTITY);
    let want: Vec<f32> = samples().iter().map(|&s| f32::from(s)).collect();
    assert_eq!(v.data(), want.as_slice());
}

#[test]
fn ras_gzip_big_endian_float_is_the_same_world_volume() {
    // The same grid told in RAS: x and y of every vector and of the origin change sign.
    let header = "NRRD0005\ntype: float\ndimension: 3\nspace: RAS\nsizes: 4 3 2\n\
        space directions: (-0.7,0,0) (0,-0.8,0) (0,0,2.5)\nendian: big\nencoding: gzip\n\
        space origin: (10,-20,30)\nspace units: \"mm\" \"mm\" \"mm\"\n";
    let raw: Vec<u8> = samples()
        .iter()
        .flat_map(|&v| f32::from(v).to_be_bytes())
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let a = read_nrrd(&write(dir.path(), "a.nrrd", LPS, &lps_bytes())).unwrap();
    let b = read_nrrd(&write(dir.path(), "b.nrrd", header, &gzip(&raw))).unwrap();
    assert_eq!(a.data(), b.data());
    assert_eq!(a.spacing(), b.spacing());
    assert_eq!(a.origin(), b.origin());
    assert_eq!(a.direction(), b.direction());
}

#[test]
fn a_detached_header_reads_its_data_file() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("ct.raw"), lps_bytes()).unwrap();
    let header = LPS.replace("encoding: raw\n", "encoding: raw\ndata file: ct.raw\n");
    // A detached header ends at its last line; nothing follows.
    let p = dir.path().join("ct.nhdr");
    std::fs::write(&p, format!("{header}\n")).unwrap();
    let a = read_nrrd(&write(dir.path(), "a.nrrd", LPS, &lps_bytes())).unwrap();
    let b = read_nrrd(&p).unwrap();
    assert_eq!(a.data(), b.data());
    assert_eq!(a.origin(), b.origin());
}

#[test]
fn an_oblique_las_frame_becomes_lps_directions() {
    // Index axis i runs along (1, 1, 0)/√2 in LAS, j along (−1, 1, 0)/√2, k along z:
    // in LPS the y components change sign.
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let header = format!(
        "NRRD0004\ntype: int16\ndimension: 3\nspace: left-anterior-superior\nsizes: 4 3 2\n\
         space directions: ({a},{a},0) ({m},{a},0) (0,0,3)\nendian: little\nencoding: raw\n\
         space origin: (1,2,3)\n",
        a = 2.0 * s,
        m = -2.0 * s
    );
    let dir = tempfile::tempdir().unwrap();
    let v = read_nrrd(&write(dir.path(), "o.nrrd", &header, &lps_bytes())).unwrap();
    let d = v.direction();
    let close = |a: DVec3, b: DVec3| (a - b).length() < 1e-12;
    assert!(close(d.x_axis, DVec3::new(s, -s, 0.0)), "{d}");
    assert!(close(d.y_axis, DVec3::new(-s, -s, 0.0)), "{d}");
    assert!(close(d.z_axis, DVec3::Z), "{d}");
    assert!((v.spacing() - DVec3::new(2.0, 2.0, 3.0)).length() < 1e-12);
    assert_eq!(v.origin(), DVec3::new(1.0, -2.0, 3.0));
}

/// Each bad file ends in an error naming what is wrong.
#[test]
fn bad_files_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = lps_bytes();
    let cases: Vec<(String, Vec<u8>, &str)> = vec![
        (LPS.into(), bytes[..bytes.len() - 2].to_vec(), "truncated"),
        (
            LPS.replace("encoding: raw", "encoding: bzip2"),
            bytes.clone(),
            "encoding 'bzip2'",
        ),
        (
            LPS.replace("dimension: 3", "dimension: 4"),
            bytes.clone(),
            "dimension 4",
        ),
        (
            LPS.replace("left-posterior-superior", "scanner-xyz"),
            bytes.clone(),
            "space 'scanner-xyz'",
        ),
        (LPS.replace("sizes: 4 3 2\n", ""), bytes.clone(), "'sizes'"),
        (
            LPS.replace("type: short", "type: block"),
            bytes.clone(),
            "type 'block'",
        ),
        (
            LPS.replace("(0,0,2.5)", "none"),
            bytes.clone(),
            "without a direction",
        ),
        (
            LPS.replace("(0.7,0,0)", "(0,0,0)"),
            bytes.clone(),
            "zero or non-finite step",
        ),
        (
            LPS.replace("encoding: raw", "encoding: gzip"),
            bytes.clone(),
            "do not decompress",
        ),
        (
            LPS.replace("encoding: raw", "encoding: gzip")
                .replace("sizes: 4 3 2", "sizes: 400 300 200"),
            gzip(&bytes),
            "cannot hold",
        ),
        (
            LPS.replace("encoding: raw", "encoding: raw\ndata file: /dev/zero"),
            Vec::new(),
            "not a regular file",
        ),
        (
            LPS.replace("sizes: 4 3 2", "sizes: 4000000 3000000 2000000"),
            bytes.clone(),
            "too large",
        ),
        ("P6\n4 3\n".into(), bytes.clone(), "not an NRRD file"),
    ];
    for (k, (header, data, want)) in cases.into_iter().enumerate() {
        let p = write(dir.path(), &format!("bad{k}.nrrd"), &header, &data);
        let e = read_nrrd(&p).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains(want), "case {k}: {msg}");
        assert!(
            msg.contains(&format!("bad{k}.nrrd")),
            "case {k} names the file: {msg}"
        );
    }
    // A NaN sample is refused by the volume, naming the file.
    let header = LPS.replace("type: short", "type: float");
    let mut data: Vec<u8> = samples()
        .iter()
        .flat_map(|&v| f32::from(v).to_le_bytes())
        .collect();
    data[..4].copy_from_slice(&f32::NAN.to_le_bytes());
    let e = read_nrrd(&write(dir.path(), "nan.nrrd", &header, &data)).unwrap_err();
    assert!(matches!(e, DatasetError::Volume { .. }), "{e}");
}
