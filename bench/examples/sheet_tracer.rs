//! How much faster is the ray-sheet tracer (`tomograf_sim::trace::sheet`) than the
//! per-ray exact tracers on a real CT? Renders one 256² view (SAD 1000 / SID 1500, 2.6 mm
//! pitch, as `scripts/compare_plastimatch.py`) with sheets on and off, interleaved, `N`
//! times each (default 21), checks that the two images agree to 1e-6 relative, and prints
//! both medians. At θ = 0 (AP) and 90 (lateral) every detector row is a sheet; at other
//! angles none is, and both renders take the same path.
//!
//! Not part of the test suite; measured figures in docs/projector.md ("Ray sheets").
//!
//! `cargo run --release -p tomograf-bench --example sheet_tracer -- CT.nii.gz [θ°]`

#[path = "common/chest.rs"]
mod chest;
#[path = "../../datasets/examples/common/timing.rs"]
mod timing;

use std::time::Instant;
use tomograf_sim::*;

fn main() {
    let (path, theta): (String, f64) = timing::args("sheet_tracer CT.nii.gz [θ°]", 0.0);
    let n = chest::repeats(21);
    let mu = chest::mu(&path);
    let g = chest::geometry(&mu);
    let view = g.view(Pose::new(theta, 0.0)).unwrap();
    let renderer = |sheets: bool| {
        Renderer::new(&mu, Projector::Siddon)
            .unwrap()
            .with_sheets(sheets)
    };
    let (on, off) = (renderer(true), renderer(false));
    let (a, b) = (on.render(&view).unwrap(), off.render(&view).unwrap());
    let worst = a
        .data
        .iter()
        .zip(&b.data)
        .map(|(x, y)| (x - y).abs() as f64 / (y.abs() as f64).max(1e-6))
        .fold(0.0, f64::max);
    assert!(
        worst <= 1e-6,
        "sheets and per-ray tracers differ by {worst:e}"
    );
    let mut times = [Vec::new(), Vec::new()];
    for _ in 0..n {
        for (t, r) in times.iter_mut().zip([&on, &off]) {
            let start = Instant::now();
            std::hint::black_box(r.render(&view).unwrap());
            t.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    let [s, p] = times.map(timing::median);
    println!(
        "{path}: {:?} voxels; θ = {theta}°, 256² rays, {} threads; median of {n} (ms): \
         sheets {s:.1} | per-ray tracers {p:.1} ({:.2}×); largest difference {worst:.1e} \
         relative",
        mu.dims(),
        rayon::current_num_threads(),
        p / s
    );
}
