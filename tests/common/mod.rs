//! Helpers shared by the end-to-end tests: run the binary, check its exit, read NPY.
#![allow(dead_code)] // each test crate uses its own subset

use std::path::Path;
use std::process::Command;

/// Runs the `tomograf` binary under test.
pub fn tomograf(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_tomograf"))
        .args(args)
        .output()
        .expect("runs")
}

/// A small phantom grid so each render takes milliseconds.
pub const SMALL: [&str; 8] = [
    "--phantom-dims",
    "64,64,40",
    "--phantom-spacing",
    "5.6,5.6,8.3",
    "--rows",
    "64",
    "--cols",
    "64",
];

pub fn ok(out: &std::process::Output) {
    assert!(
        out.status.success(),
        "failed: {}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

pub fn read_npy(path: &Path) -> (Vec<u64>, Vec<f32>) {
    let bytes = std::fs::read(path).unwrap();
    let npy = npyz::NpyFile::new(&bytes[..]).unwrap();
    let shape = npy.shape().to_vec();
    (shape, npy.into_vec::<f32>().unwrap())
}

/// A minimal NIfTI-1 file written by hand (no sform/qform: voxel size only, axes as the
/// reader's default): float32 voxels `data` (i fastest) on a `dims` grid of `spacing` mm.
pub fn nifti_f32(path: &Path, dims: [u16; 3], spacing: [f32; 3], data: &[f32]) {
    let mut h = vec![0u8; 352];
    h[0..4].copy_from_slice(&348i32.to_le_bytes());
    let dim: [i16; 8] = [
        3,
        dims[0] as i16,
        dims[1] as i16,
        dims[2] as i16,
        1,
        1,
        1,
        1,
    ];
    for (i, d) in dim.iter().enumerate() {
        h[40 + 2 * i..42 + 2 * i].copy_from_slice(&d.to_le_bytes());
    }
    h[70..72].copy_from_slice(&16i16.to_le_bytes()); // DT_FLOAT32
    h[72..74].copy_from_slice(&32i16.to_le_bytes());
    let pixdim: [f32; 8] = [1.0, spacing[0], spacing[1], spacing[2], 1.0, 0.0, 0.0, 0.0];
    for (i, p) in pixdim.iter().enumerate() {
        h[76 + 4 * i..80 + 4 * i].copy_from_slice(&p.to_le_bytes());
    }
    h[108..112].copy_from_slice(&352f32.to_le_bytes()); // vox_offset
    h[112..116].copy_from_slice(&1f32.to_le_bytes()); // scl_slope
    h[344..348].copy_from_slice(b"n+1\0");
    for v in data {
        h.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::write(path, h).unwrap();
}
