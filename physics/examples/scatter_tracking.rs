//! Woodcock tracking with one global majorant against majorants per brick (docs/scatter.md,
//! "Tracking"): analog photon histories per CPU second, the forced-detection run's CPU
//! time, and whether the two give the same scatter (z of the grid differences), on the
//! scatter examples' chest (AP, 120 kVp) at its 4.5 mm voxels and at 2.25 mm; then analog
//! histories through a water box holding an iron ball, where local majorants pay. Not a
//! test; CPU time from getrusage (user + system, all threads).
//!
//! `cargo run --release -p tomograf-physics --example scatter_tracking`
#[path = "common/scatter_chest.rs"]
mod case;
#[path = "common/cpu_time.rs"]
mod cpu_time;

use cpu_time::cpu_seconds;
use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use tomograf_physics::acquisition::Acquisition;
use tomograf_physics::scatter::transport::Medium;
use tomograf_physics::scatter::{ScatterImages, ScatterModel};
use tomograf_sim::composition::Composition;
use tomograf_sim::geometry::ViewBeam;
use tomograf_sim::material;
use tomograf_sim::phantom::Phantom;
use tomograf_sim::{View, Volume};

/// Analog histories per CPU second through `medium`: energies from the spectrum
/// (`energies`, `fluence`), aimed uniformly over `view`'s panel from `source`.
fn analog_rate(
    medium: &Medium,
    view: &View,
    source: DVec3,
    energies: &[f64],
    fluence: &[f64],
) -> f64 {
    let total: f64 = fluence.iter().sum();
    let n = 200_000u64;
    let t0 = cpu_seconds();
    (0..n / 1000).into_par_iter().for_each(|b| {
        let mut rng = ChaCha8Rng::seed_from_u64(b);
        for _ in 0..1000 {
            let r = rng.random::<f64>() * view.rows as f64 - 0.5;
            let c = rng.random::<f64>() * view.cols as f64 - 0.5;
            let d = (view.pixel_centre(r, c) - source).normalize();
            let u = rng.random::<f64>() * total;
            let mut acc = 0.0;
            let k = fluence
                .iter()
                .position(|f| {
                    acc += f;
                    acc > u
                })
                .unwrap_or(energies.len() - 1);
            std::hint::black_box(medium.walk(source, d, energies[k], 50, &mut rng));
        }
    });
    n as f64 / (cpu_seconds() - t0)
}

/// rms of (a − b)/√(σa² + σb²) over the grid points with scatter.
fn rms_z(a: &ScatterImages, b: &ScatterImages) -> f64 {
    let z2: Vec<f64> = a
        .grid_mean
        .iter()
        .zip(&a.grid_standard_error)
        .zip(b.grid_mean.iter().zip(&b.grid_standard_error))
        .filter(|((m, _), _)| **m > 0.0)
        .map(|((m, e), (m0, e0))| (m - m0).powi(2) / (e * e + e0 * e0))
        .collect();
    (z2.iter().sum::<f64>() / z2.len() as f64).sqrt()
}

fn main() {
    let view = case::ap_view(256);
    let ViewBeam::Cone { source } = view.beam else {
        unreachable!("the case is a cone beam")
    };
    let mut a = Acquisition::preset("kv-flat-panel-120kvp").unwrap();
    a.scatter = ScatterModel::MonteCarlo {
        photons: 20_000,
        grid: 16,
        multiple_grid: 0,
        max_order: 50,
        detection_cell_mm: 0.0,
        angular_window_deg: 0.0,
        split: 1,
        sparse_multiple: false,
        sampler: Default::default(),
        cell_check: 0,
    };
    let spectrum = a.spectrum.spectrum().unwrap();
    let (energies, fluence) = (spectrum.energies_kev(), spectrum.fluence());
    let fine = Phantom::thorax()
        .voxelize([160, 112, 80], DVec3::new(2.25, 2.25, 4.15), DVec3::ZERO)
        .unwrap();
    for (name, hu) in [("4.5 mm voxels", case::thorax()), ("2.25 mm voxels", fine)] {
        println!("\n### Chest, {name} ({:?})\n", hu.dims());
        println!(
            "| tracking | analog histories per CPU s | × global | forced-detection run (16×16, 20 000 photons) CPU s | × global | rms z vs global |"
        );
        println!("|---|---:|---:|---:|---:|---:|");
        // The reference: global majorant, scatter stream 0. Every other run uses stream 1,
        // so its z against the reference is that of two independent estimates; the
        // "global, other stream" row is the control (≈ 1 when the standard errors are right).
        let mut reference: Option<(f64, f64, ScatterImages)> = None;
        for (size, stream, label) in [
            (None, 0, "global"),
            (None, 1, "global, other stream"),
            (Some(4), 1, "bricks 4³"),
            (Some(8), 1, "bricks 8³"),
            (Some(16), 1, "bricks 16³ (default)"),
        ] {
            let p = a
                .prepare(&hu, 7)
                .unwrap()
                .with_majorant_bricks(size)
                .unwrap();
            let r = analog_rate(
                p.scatter_engine().unwrap().medium(),
                &view,
                source,
                energies,
                fluence,
            );
            let t0 = cpu_seconds();
            let s = p.scatter(&view, stream).unwrap().unwrap();
            let f = cpu_seconds() - t0;
            let Some((r0, f0, s0)) = &reference else {
                println!("| {label} | {r:.0} | 1.00 | {f:.1} | 1.00 | — |");
                reference = Some((r, f, s));
                continue;
            };
            println!(
                "| {label} | {r:.0} | {:.2} | {f:.1} | {:.2} | {:.2} |",
                r / r0,
                f0 / f,
                rms_z(&s, s0)
            );
        }
    }
    // Where local majorants pay: a dense object. A 300 × 200 × 300 mm water box (2 mm
    // voxels) holding a 12 mm steel (iron) ball: the global majorant is the iron's.
    let dims = [150, 100, 150];
    let n: usize = dims.iter().product();
    let (mut labels, mut density) = (vec![0.0f32; n], vec![1.0f32; n]);
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let p = DVec3::new(i as f64, j as f64, k as f64) - DVec3::new(75.0, 50.0, 75.0);
                if p.length() * 2.0 < 6.0 {
                    let v = i + dims[0] * (j + dims[1] * k);
                    labels[v] = 1.0;
                    density[v] = 7.874;
                }
            }
        }
    }
    let grid = |data| Volume::centred(dims, DVec3::splat(2.0), DVec3::ZERO, data).unwrap();
    let comp = Composition::from_labels(
        &grid(labels),
        &grid(density),
        vec!["water".into(), "iron".into()],
    )
    .unwrap();
    let mats = [
        material::by_name("water").unwrap(),
        material::by_name("iron").unwrap(),
    ];
    println!("\n### Water box 300 × 200 × 300 mm with a 12 mm iron ball, 2 mm voxels\n");
    println!("| tracking | analog histories per CPU s | × global |\n|---|---:|---:|");
    let base = Medium::new(&comp, &mats, 150.0).unwrap();
    let g = analog_rate(
        &base.clone().with_majorant_bricks(None).unwrap(),
        &view,
        source,
        energies,
        fluence,
    );
    println!("| global | {g:.0} | 1.00 |");
    for (size, label) in [
        (4, "bricks 4³"),
        (8, "bricks 8³"),
        (16, "bricks 16³ (default)"),
    ] {
        let r = analog_rate(
            &base.clone().with_majorant_bricks(Some(size)).unwrap(),
            &view,
            source,
            energies,
            fluence,
        );
        println!("| {label} | {r:.0} | {:.2} |", r / g);
    }
}
