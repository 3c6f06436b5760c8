//! Classical reconstruction accuracy and time on the built-in thorax phantom: FDK from a
//! full scan down to 1 view, SART and SART-TV from 1, 2, 5 and 10 views.
//!
//! Projections are exact analytic line integrals of the phantom (no voxel model in the
//! data, so no "inverse crime"); the reference is the phantom voxelised on the
//! reconstruction grid. Prints a markdown table (the one in docs/reconstruction.md).
//!
//! ```sh
//! cargo run --release -p tomograf-recon --example recon_accuracy -- [N] [SART_ITERATIONS] [TV_STEPS,TV_ALPHA]
//! ```
//! `N` (default 64) is the grid size (N³ voxels over 352 mm) and the detector is 2N².

use glam::DVec3;
use std::time::Instant;
use tomograf_recon::{self as recon, FdkOptions, SartOptions, TvOptions};
use tomograf_sim::attenuation::{hu_to_mu, mu_water_per_mm};
use tomograf_sim::phantom::Phantom;
use tomograf_sim::{Beam, Detector, Geometry, Pose, Projection, Renderer, Volume};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let n: usize = args.first().map_or(Ok(64), |s| s.parse())?;
    let iters: usize = args.get(1).map_or(Ok(20), |s| s.parse())?;
    let tv_opts = match args.get(2) {
        Some(s) => {
            let (k, a) = s.split_once(',').ok_or("TV is STEPS,ALPHA")?;
            TvOptions {
                iterations: k.parse()?,
                step: a.parse()?,
            }
        }
        None => TvOptions::default(),
    };
    let energy = 60.0;
    let mu_w = mu_water_per_mm(energy)?;
    let phantom = Phantom::thorax();
    let spacing = 352.0 / n as f64;
    let truth_hu = phantom.voxelize([n; 3], DVec3::splat(spacing), DVec3::ZERO)?;
    let truth = truth_hu.map(|h| hu_to_mu(h, mu_w))?;
    let template = truth.clone();
    let all: Vec<Pose> = (0..360).map(|t| Pose::new(t as f64, 0.0)).collect();
    let mut geometry = Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(2 * n, 2 * n, 1.0),
        isocentre: DVec3::ZERO,
    };
    let pitch = geometry.fit_pitch(&all, &template)?;
    geometry.detector = Detector::new(2 * n, 2 * n, pitch);

    let project = |poses: &[Pose]| -> Result<Vec<Projection>, Box<dyn std::error::Error>> {
        let views = geometry.views(poses)?;
        Ok(views
            .iter()
            .map(|v| Projection {
                rows: v.rows,
                cols: v.cols,
                data: (0..v.rows * v.cols)
                    .map(|i| {
                        let ray = v.ray((i / v.cols) as f64, (i % v.cols) as f64);
                        phantom.line_integral(&ray, mu_w) as f32
                    })
                    .collect(),
            })
            .collect())
    };
    // Body mask: voxels the phantom fills with more than air.
    let body: Vec<bool> = truth_hu.data().iter().map(|&h| h > -990.0).collect();
    let score = |v: &Volume| -> (f64, f64) {
        let hu = recon::mu_to_hu(v, mu_w).expect("finite");
        let (mut se_all, mut se_body, mut nb) = (0.0, 0.0, 0usize);
        for ((a, b), &m) in hu.data().iter().zip(truth_hu.data()).zip(&body) {
            let e = f64::from(a - b).powi(2);
            se_all += e;
            if m {
                se_body += e;
                nb += 1;
            }
        }
        (
            (se_body / nb as f64).sqrt(),
            (se_all / hu.len() as f64).sqrt(),
        )
    };

    // Baseline for times: one Siddon forward projection of all 360 views of the truth.
    let views360 = geometry.views(&all)?;
    let t = Instant::now();
    let r = Renderer::new(&truth, tomograf_sim::Projector::Siddon)?;
    for v in &views360 {
        std::hint::black_box(r.render(v)?);
    }
    let base = t.elapsed().as_secs_f64();

    println!(
        "Grid {n}³ × {spacing:.2} mm, detector {0}×{0} × {pitch:.3} mm, SAD 1000 / SID 1500 mm, {energy} keV (mu_water {mu_w:.5} mm⁻¹), {1} threads.",
        2 * n,
        rayon::current_num_threads()
    );
    println!(
        "SART: {iters} iterations, ordered subsets of one view each (≤ 10 views), λ = 1, non-negative; SART-TV adds {} TV steps of α = {} per iteration.",
        tv_opts.iterations, tv_opts.step
    );
    println!(
        "Baseline: Siddon forward projection of 360 views of the phantom volume: {base:.2} s.\n"
    );
    println!(
        "| method | views | RMSE in body (HU) | RMSE whole grid (HU) | seconds | × baseline |"
    );
    println!("|---|---|---|---|---|---|");
    let sets: Vec<(&str, Vec<Pose>)> = vec![
        ("360 (1° full scan)", all.clone()),
        (
            "72 (5°)",
            (0..72).map(|i| Pose::new(5.0 * i as f64, 0.0)).collect(),
        ),
        (
            "10 (36°)",
            (0..10).map(|i| Pose::new(36.0 * i as f64, 0.0)).collect(),
        ),
        (
            "5 (72°)",
            (0..5).map(|i| Pose::new(72.0 * i as f64, 0.0)).collect(),
        ),
        ("2 (AP + lateral)", vec![Pose::AP, Pose::LATERAL]),
        ("1 (AP)", vec![Pose::AP]),
    ];
    for (name, poses) in &sets {
        let proj = project(poses)?;
        let t = Instant::now();
        let rec = recon::fdk(&proj, &geometry, poses, &FdkOptions::default(), &template)?;
        let s = t.elapsed().as_secs_f64();
        let (b, a) = score(&rec);
        println!(
            "| FDK (Ram-Lak) | {name} | {b:.0} | {a:.0} | {s:.2} | {:.2} |",
            s / base
        );
        if poses.len() <= 10 {
            let views = geometry.views(poses)?;
            for (label, tv) in [("SART", None), ("SART-TV", Some(tv_opts))] {
                let opts = SartOptions {
                    iterations: iters,
                    subsets: poses.len().min(10),
                    tv,
                    ..SartOptions::default()
                };
                let t = Instant::now();
                let rec = recon::sart_tv(&proj, &views, &opts, &template)?;
                let s = t.elapsed().as_secs_f64();
                let (b, a) = score(&rec.volume);
                let res = rec.history.last().map_or(f64::NAN, |r| r.residual);
                println!(
                    "| {label} ({iters} it., residual {res:.3}) | {name} | {b:.0} | {a:.0} | {s:.2} | {:.2} |",
                    s / base
                );
            }
        }
    }
    let zero = template.map(|_| 0.0)?;
    let (b, a) = score(&zero);
    println!("| all-air volume (reference) | — | {b:.0} | {a:.0} | — | — |");
    Ok(())
}
