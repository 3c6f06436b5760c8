//! How much faster are a composition's per-material mass thicknesses traced through ray
//! sheets than with the renderer's per-ray tracers? The real CT in HU, split into the
//! Schneider tissues (`TissueModel::schneider`: 7 materials), one 256² view at θ (SAD 1000
//! / SID 1500, 2.6 mm pitch, as `scripts/compare_plastimatch.py`) with sheets on and off,
//! interleaved, `N` times each (default 21); checks that the two agree to 1e-9 relative and
//! prints both medians. At θ = 0 (AP) every detector row is a sheet; with
//! `COLUMNS=1` the renderer also makes the k-fastest copy, so that other angles take
//! column sheets. Not part of the test suite; figures in docs/projector.md ("Session 27").
//!
//! `cargo run --release -p tomograf-bench --example material_sheets -- CT.nii.gz [θ°]`

#[path = "common/chest.rs"]
#[allow(dead_code)] // this example reads the CT in HU, not as mu
mod chest;
#[path = "../../datasets/examples/common/timing.rs"]
mod timing;

use std::time::Instant;
use tomograf_sim::tissue::TissueModel;
use tomograf_sim::*;

fn main() {
    let (path, theta): (String, f64) = timing::args("material_sheets CT.nii.gz [θ°]", 0.0);
    let n = chest::repeats(21);
    let hu = tomograf_datasets::nifti::read_nifti(std::path::Path::new(&path)).expect("reads");
    let (composition, _) = TissueModel::schneider().composition(&hu).unwrap();
    let names = composition.materials().to_vec();
    let g = chest::geometry(composition.packed());
    let view = g.view(Pose::new(theta, 0.0)).unwrap();
    let columns = std::env::var_os("COLUMNS").is_some();
    let renderer = |sheets: bool| {
        Renderer::for_composition(&composition, Projector::Siddon)
            .unwrap()
            .with_sheets(sheets)
            .with_column_sheets(sheets && columns)
    };
    let (on, off) = (renderer(true), renderer(false));
    let (a, b) = (
        on.mass_thickness(&view, &names).unwrap(),
        off.mass_thickness(&view, &names).unwrap(),
    );
    // Relative to each pixel's total: a sliver of a material that a ray grazes within
    // rounding of a voxel's edge may be 1e-14 in one tracer and 0 in the other.
    let k = names.len();
    let worst = a
        .data
        .chunks(k)
        .zip(b.data.chunks(k))
        .map(|(x, y)| {
            let total: f64 = y.iter().sum();
            x.iter()
                .zip(y)
                .map(|(p, q)| (p - q).abs() / total.max(1e-9))
                .fold(0.0, f64::max)
        })
        .fold(0.0, f64::max);
    assert!(
        worst <= 1e-9,
        "sheets and per-ray tracers differ by {worst:e} of a pixel's total"
    );
    let mut times = [Vec::new(), Vec::new()];
    for _ in 0..n {
        for (t, r) in times.iter_mut().zip([&on, &off]) {
            let start = Instant::now();
            std::hint::black_box(r.mass_thickness(&view, &names).unwrap());
            t.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    let [s, p] = times.map(timing::median);
    println!(
        "{path}: {} materials; θ = {theta}°, 256² rays, {} threads; median of {n} (ms): \
         sheets {s:.1} | per-ray tracers {p:.1} ({:.2}×); largest difference {worst:.1e} \
         of a pixel's total",
        names.len(),
        rayon::current_num_threads(),
        p / s
    );
}
