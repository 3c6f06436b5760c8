//! How much faster are detector columns traced as ray sheets
//! (`Renderer::with_column_sheets`) than the renderer's default at a gantry angle θ, and
//! what does the k-fastest copy of the volume they need cost? Renders one 256² view of a CT
//! (SAD 1000 / SID 1500, 2.6 mm pitch, as `scripts/compare_plastimatch.py`) with and without
//! column sheets, interleaved, `N` times each (default 11), checks that the two images agree
//! to 1e-6 relative, and prints the medians and the copy's time (median of `N` renderers
//! made). Where the rows are sheets (AP, PA) the renderer keeps them, and both take the
//! same path.
//!
//! Not part of the test suite; figures in docs/projector.md ("Column sheets").
//!
//! `cargo run --release -p tomograf-bench --example column_sheets -- CT.nii.gz [θ°]`

#[path = "common/chest.rs"]
mod chest;
#[path = "../../datasets/examples/common/timing.rs"]
mod timing;

use std::time::Instant;
use tomograf_sim::*;

fn main() {
    let (path, theta): (String, f64) = timing::args("column_sheets CT.nii.gz [θ°]", 30.0);
    let n = chest::repeats(11);
    let mu = chest::mu(&path);
    let g = chest::geometry(&mu);
    let view = g.view(Pose::new(theta, 0.0)).unwrap();
    let plain = Renderer::new(&mu, Projector::Siddon).unwrap();
    let columns = plain.clone().with_column_sheets(true);
    let (a, b) = (columns.render(&view).unwrap(), plain.render(&view).unwrap());
    let worst = a
        .data
        .iter()
        .zip(&b.data)
        .map(|(x, y)| (x - y).abs() as f64 / (y.abs() as f64).max(1e-6))
        .fold(0.0, f64::max);
    assert!(
        worst <= 1e-6,
        "column sheets and renderer differ by {worst:e}"
    );
    let mut times = [Vec::new(), Vec::new(), Vec::new()];
    for _ in 0..n {
        let start = Instant::now();
        std::hint::black_box(plain.clone().with_column_sheets(true));
        times[0].push(start.elapsed().as_secs_f64() * 1e3);
        for (t, r) in times[1..].iter_mut().zip([&columns, &plain]) {
            let start = Instant::now();
            std::hint::black_box(r.render(&view).unwrap());
            t.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    let [copy, c, p] = times.map(timing::median);
    let pays = if p > c {
        format!("pays for itself after {:.1} views", copy / (p - c))
    } else {
        "does not pay here".to_string()
    };
    println!(
        "{path}: {:?} voxels; θ = {theta}°, 256² rays, {} threads; median of {n} (ms): \
         column sheets {c:.1} | default {p:.1} ({:.2}×); k-fastest copy {copy:.1} ({pays}); \
         largest difference {worst:.1e} relative",
        mu.dims(),
        rayon::current_num_threads(),
        p / c,
    );
}
