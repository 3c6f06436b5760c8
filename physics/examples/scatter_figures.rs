//! The figures of docs/scatter.md: scatter-to-primary ratio of a chest phantom AP view at
//! 120 kVp without a grid, Monte Carlo time and noise vs photons, and the fast estimate's
//! error against the full Monte Carlo on held-out phantoms and its time. Not a test.
//!
//! `cargo run --release -p tomograf-physics --example scatter_figures`
//! (`SCALE=k`: k times the photons everywhere, for sharper figures at k times the time.)
use glam::DVec3;
use std::time::Instant;
use tomograf_physics::acquisition::{Acquisition, Prepared};
use tomograf_physics::scatter::{ScatterImages, ScatterModel};
use tomograf_sim::phantom::Phantom;
use tomograf_sim::*;

/// The chest phantom on a coarse grid (scatter is low-frequency): 80×56×40 voxels of
/// 4.5×4.5×8.3 mm.
fn chest(p: &Phantom) -> Volume {
    p.voxelize([80, 56, 40], DVec3::new(4.5, 4.5, 8.3), DVec3::ZERO)
        .unwrap()
}

fn view() -> View {
    // SAD 1000 / SID 1500 mm, a 430 mm panel read as 64×64 pixels of 6.72 mm.
    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(64, 64, 6.72),
        isocentre: DVec3::ZERO,
    };
    g.view(Pose::new(0.0, 0.0)).unwrap()
}

fn prepare(hu: &Volume, model: ScatterModel) -> Prepared {
    let mut a = Acquisition::preset("kv-flat-panel-120kvp").unwrap();
    a.scatter = model;
    a.prepare(hu, 7).unwrap()
}

fn mc(photons: u64, grid: usize) -> ScatterModel {
    ScatterModel::MonteCarlo {
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
    }
}

fn run(p: &Prepared, v: &View) -> (ScatterImages, f64) {
    let t = Instant::now();
    let s = p.scatter(v, 0).unwrap().unwrap();
    (s, t.elapsed().as_secs_f64())
}

/// Median over grid points of standard error / mean.
fn median_rel_se(s: &ScatterImages) -> f64 {
    let mut r: Vec<f64> = s
        .grid_mean
        .iter()
        .zip(&s.grid_standard_error)
        .filter(|(m, _)| **m > 0.0)
        .map(|(m, e)| e / m)
        .collect();
    r.sort_by(f64::total_cmp);
    r[r.len() / 2]
}

/// RMS of (a − b) over the image, relative to b's mean.
fn rel_rms(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let rms = (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / n).sqrt();
    rms / (b.iter().sum::<f64>() / n)
}

fn main() {
    let scale: u64 = std::env::var("SCALE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    let v = view();
    println!("threads: {}", rayon::current_num_threads());

    // 1. SPR of the chest AP view.
    let hu = chest(&Phantom::thorax());
    let reference_photons = 50_000 * scale;
    let p = prepare(&hu, mc(reference_photons, 16));
    let t = Instant::now();
    let thick = p.mass_thickness(Projector::Siddon, &v).unwrap();
    let primary = p.integrator().expected(&thick, &v, 1.0).unwrap();
    let t_primary = t.elapsed().as_secs_f64();
    let (s, t_mc) = run(&p, &v);
    let total = s.total();
    let (r, c) = (v.rows / 2, v.cols / 2);
    let at = |im: &[f64], rr: usize, cc: usize| im[rr * v.cols + cc];
    let spr = |rr, cc| at(&total.mean, rr, cc) / at(&primary.mean, rr, cc);
    println!(
        "chest AP 120 kVp, no grid, {reference_photons} photons, grid 16: primary {t_primary:.3} s, scatter {t_mc:.2} s ({:.0} histories/s), median rel. SE {:.3}",
        reference_photons as f64 / t_mc,
        median_rel_se(&s)
    );
    // Lung: 1/4 of the way across at mid-height; mediastinum: the centre.
    println!(
        "SPR centre (mediastinum) {:.2}, right lung {:.2}, left lung {:.2}",
        spr(r, c),
        spr(r, v.cols / 4),
        spr(r, 3 * v.cols / 4)
    );
    let sum = |im: &[f64]| im.iter().sum::<f64>();
    println!(
        "panel totals: single Compton {:.1} %, single Rayleigh {:.1} %, multiple {:.1} % of scatter; scatter/primary over the panel {:.2}",
        100.0 * sum(&s.single_compton.mean) / sum(&total.mean),
        100.0 * sum(&s.single_rayleigh.mean) / sum(&total.mean),
        100.0 * sum(&s.multiple.mean) / sum(&total.mean),
        sum(&total.mean) / sum(&primary.mean)
    );

    // 2. MC time and noise vs photons.
    println!("photons | grid | time s | histories/s | median rel. SE per grid point");
    for n in [625u64, 2_500, 10_000].map(|n| n * scale) {
        let q = prepare(&hu, mc(n, 16));
        let (s, t) = run(&q, &v);
        println!(
            "{n} | 16 | {t:.2} | {:.0} | {:.3}",
            n as f64 / t,
            median_rel_se(&s)
        );
    }

    // 3. The fast estimate vs the full MC on held-out phantoms (thorax variants not used
    // to choose the estimate's settings).
    println!("phantom | estimate time s | MC time s | estimate rel. RMS error | MC rel. SE");
    for seed in [101u64, 102, 103] {
        let hu = chest(&Phantom::thorax_variant(seed));
        let est = prepare(
            &hu,
            ScatterModel::Estimate {
                photons: 5_000,
                grid: 8,
                multiple_grid: 0,
                smoothing: 1.0,
                detection_cell_mm: 0.0,
            },
        );
        let (e, te) = run(&est, &v);
        let full = prepare(&hu, mc(reference_photons, 16));
        let (f, tf) = run(&full, &v);
        println!(
            "thorax_variant({seed}) | {te:.2} | {tf:.2} | {:.3} | {:.3}",
            rel_rms(&e.total().mean, &f.total().mean),
            median_rel_se(&f)
        );
    }

    // 4. Contact geometry like the AAPM TG-195 radiography case (but water, not ICRU soft
    // tissue, and this preset's beam, not RQR-9): a 390×390×200 mm slab whose back face is
    // 10 mm in front of the detector, SID 1800 mm, a 390 mm panel of 40×40 pixels.
    let slab = Volume::new(
        [78, 40, 78],
        DVec3::splat(5.0),
        DVec3::new(-192.5, -97.5, -192.5),
        glam::DMat3::IDENTITY,
        vec![0.0; 78 * 40 * 78],
    )
    .unwrap();
    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: 1690.0,
            sid_mm: 1800.0,
        },
        detector: Detector::new(40, 40, 9.75),
        isocentre: DVec3::ZERO,
    };
    let sv = g.view(Pose::new(0.0, 0.0)).unwrap();
    let n = 20_000 * scale;
    let q = prepare(&slab, mc(n, 16));
    let thick = q.mass_thickness(Projector::Siddon, &sv).unwrap();
    let primary = q.integrator().expected(&thick, &sv, 1.0).unwrap();
    let (s, t) = run(&q, &sv);
    let total = s.total();
    let c = 20 * 40 + 20;
    println!(
        "water slab 200 mm, contact, SID 1800, {n} photons: {t:.1} s, SPR centre {:.2}, edge-centre {:.2}, median rel. SE {:.3}",
        total.mean[c] / primary.mean[c],
        total.mean[20 * 40 + 1] / primary.mean[20 * 40 + 1],
        median_rel_se(&s)
    );
}
