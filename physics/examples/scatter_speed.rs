//! Where the Monte Carlo's time goes and the time to a 256² scatter image at ≤ 2 % noise
//! per pixel (docs/scatter.md, "Speed"). Not a test; all in one process, CPU time from
//! getrusage (user + system of the whole process, all threads).
//!
//! `cargo run --release -p tomograf-physics --example scatter_speed`
#[path = "common/scatter_chest.rs"]
mod case;
#[path = "common/cpu_time.rs"]
mod cpu_time;

use cpu_time::cpu_seconds;
use tomograf_physics::acquisition::Acquisition;
use tomograf_physics::scatter::ScatterModel;

fn main() {
    // A 430 mm panel read as 256 × 256 pixels of 1.68 mm.
    let hu = case::thorax();
    let view = case::ap_view(256);
    // The variance of one scoring point's estimate does not depend on how many other points
    // there are, so the photons needed for 2 % per point come from the run with the most
    // batches (16 × 16, 20 000 photons = 79 batches); the cost per history from each run.
    println!(
        "| scoring grid | photons | CPU s | histories per CPU s | median rel. SE per point | CPU s for 2 % (photons from the 16×16 run) |"
    );
    println!("|---|---|---|---|---|---|");
    let mut n2 = 0.0;
    let mut rows = Vec::new();
    for (grid, photons) in [
        (16, 20_000),
        (1, 20_000),
        (4, 20_000),
        (64, 2_048),
        (256, 512),
    ] {
        let mut a = Acquisition::preset("kv-flat-panel-120kvp").unwrap();
        a.scatter = ScatterModel::MonteCarlo {
            photons,
            grid,
            multiple_grid: 0,
            max_order: 50,
            detection_cell_mm: 0.0,
            angular_window_deg: 0.0,
            split: 1,
            sparse_multiple: false,
            sampler: Default::default(),
            cell_check: 0,
        };
        let p = a.prepare(&hu, 7).unwrap();
        let t0 = cpu_seconds();
        let s = p.scatter(&view, 0).unwrap().unwrap();
        let cpu = cpu_seconds() - t0;
        let mut rel: Vec<f64> = s
            .grid_mean
            .iter()
            .zip(&s.grid_standard_error)
            .filter(|(m, _)| **m > 0.0)
            .map(|(m, e)| e / m)
            .collect();
        rel.sort_by(f64::total_cmp);
        let med = rel[rel.len() / 2];
        if grid == 16 {
            n2 = photons as f64 * (med / 0.02).powi(2);
        }
        rows.push((grid, photons, cpu, med));
    }
    rows.sort_by_key(|r| r.0);
    for (grid, photons, cpu, med) in rows {
        println!(
            "| {grid}×{grid} | {photons} | {cpu:.1} | {:.0} | {:.1} % | {:.0} |",
            photons as f64 / cpu,
            100.0 * med,
            cpu * n2 / photons as f64
        );
    }
    println!("photons for a median 2 % per scoring point: {n2:.0}");
}
