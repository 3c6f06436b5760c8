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
