//! The bias of a coarse scoring grid: scatter scored at G × G points and interpolated to
//! every pixel, against scatter scored at every pixel (docs/scatter.md, "Scoring-grid
//! bias"). Not a test; one process.
//!
//! `cargo run --release -p tomograf-physics --example scatter_grid_bias`
//!
//! The chest and AP view of `scatter_speed`, its 430 mm panel read as 61 × 61 pixels of
//! 7.05 mm, so that scoring every pixel (3721 points) is affordable: the scatter field is
//! smooth on a scale of centimetres, and a 16 × 16 grid lies on every 4th pixel here, 28 mm
//! apart, as it is on the 256² panel (28.6 mm). Every grid scores the same photon histories
//! (the scoring draws no random numbers), so the difference "interpolated − per pixel" is
//! the interpolation's error with most of the Monte Carlo noise cancelled. What noise is
//! left is measured with two seeds: with d₁, d₂ the two seeds' differences,
//! mean(((d₁+d₂)/2)²) − mean(((d₁−d₂)/2)²) estimates the squared bias alone.
#[path = "common/scatter_chest.rs"]
mod case;

use tomograf_physics::acquisition::Acquisition;
use tomograf_physics::scatter::ScatterModel;
use tomograf_sim::{View, Volume};

const PIXELS: usize = 61;
const PHOTONS: u64 = 6_000;
const SEEDS: [u64; 2] = [7, 8];

/// Total scatter (channel 0) at every pixel, scored on a `grid` × `grid` grid.
fn scatter(hu: &Volume, view: &View, grid: usize, seed: u64) -> Vec<f64> {
    let mut a = Acquisition::preset("kv-flat-panel-120kvp").unwrap();
    a.scatter = ScatterModel::MonteCarlo {
        photons: PHOTONS,
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
    let p = a.prepare(hu, seed).unwrap();
    let s = p.scatter(view, 0).unwrap().unwrap();
    let t = s.total();
    t.mean[..t.rows * t.cols].to_vec()
}

fn main() {
    let hu = case::thorax();
    let view = case::ap_view(PIXELS);
    let reference: Vec<Vec<f64>> = SEEDS
        .iter()
        .map(|&s| scatter(&hu, &view, PIXELS, s))
        .collect();
    let n = (PIXELS * PIXELS) as f64;
    let level = reference.iter().flatten().sum::<f64>() / (2.0 * n);
    println!(
        "{PIXELS}×{PIXELS} pixels, {PHOTONS} photons × {} seeds; errors relative to the mean \
         per-pixel scatter",
        SEEDS.len()
    );
    println!();
    println!(
        "| scoring grid | point spacing mm | RMS bias | mean bias | largest |bias| (two-seed mean) | RMS noise left in the difference |"
    );
    println!("|---|---|---|---|---|---|");
    for grid in [4, 8, 16, 31] {
        let d: Vec<Vec<f64>> = SEEDS
            .iter()
            .zip(&reference)
            .map(|(&s, r)| {
                scatter(&hu, &view, grid, s)
                    .iter()
                    .zip(r)
                    .map(|(a, b)| (a - b) / level)
                    .collect()
            })
            .collect();
        let (mut sum2, mut noise2, mut mean, mut worst) = (0.0, 0.0, 0.0, 0.0f64);
        for (a, b) in d[0].iter().zip(&d[1]) {
            let (m, h) = ((a + b) / 2.0, (a - b) / 2.0);
            sum2 += m * m;
            noise2 += h * h;
            mean += m;
            worst = worst.max(m.abs());
        }
        let rms_bias = ((sum2 - noise2) / n).max(0.0).sqrt();
        let spacing = (PIXELS - 1) as f64 * case::PANEL_MM / PIXELS as f64 / (grid - 1) as f64;
        println!(
            "| {grid}×{grid} | {spacing:.1} | {:.2} % | {:+.2} % | {:.1} % | {:.2} % |",
            100.0 * rms_bias,
            100.0 * mean / n,
            100.0 * worst,
            100.0 * (noise2 / n).sqrt()
        );
    }
}
