//! Read speed of a DICOM CT series, one thread against all, interleaved: the series is
//! written from a NIfTI CT (one int16 file per slice, `write_dicom_series`) into a
//! temporary folder, then read with `read_dicom_series` in a 1-thread and an N-thread rayon
//! pool in turn (headers and pixel data are parsed per file in parallel); the volumes must
//! be identical. Not part of the test suite; figures in docs/datasets.md ("Loading speed").
//!
//! `cargo run --release -p tomograf-datasets --example dicom_speed -- CT.nii.gz [repeats]`

#[path = "common/timing.rs"]
mod timing;

use std::time::Instant;
use tomograf_datasets::dicom::{read_dicom_series, write_dicom_series};

fn main() {
    let (path, repeats): (String, usize) = timing::args("dicom_speed CT.nii.gz [repeats]", 7);
    let ct = tomograf_datasets::nifti::read_nifti(std::path::Path::new(&path)).expect("reads");
    let dir = tempfile::tempdir().expect("a temporary folder");
    write_dicom_series(dir.path(), &ct, "1.2.826.0.1.3680043.8.498.1").expect("writes");
    let threads = rayon::current_num_threads();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let read = || read_dicom_series(dir.path(), false).expect("reads the series");
    let reference = one.install(read);
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for _ in 0..repeats.max(1) {
        let t = Instant::now();
        let v = one.install(read);
        a.push(t.elapsed().as_secs_f64());
        assert!(v == reference);
        let t = Instant::now();
        let v = read();
        b.push(t.elapsed().as_secs_f64());
        assert!(v == reference, "the same volume whatever the thread count");
    }
    let (a, b) = (timing::median(a), timing::median(b));
    println!(
        "{path} as {} DICOM slices of {}×{}: read_dicom_series, median of {repeats}: \
         1 thread {:.0} ms | {threads} threads {:.0} ms | speed-up {:.2}×",
        ct.dims()[2],
        ct.dims()[0],
        ct.dims()[1],
        a * 1e3,
        b * 1e3,
        a / b
    );
}
