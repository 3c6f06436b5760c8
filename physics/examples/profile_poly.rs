//! Repeats the polychromatic chain of `tomograf bench --physics` (analytic thorax on 256³
//! voxels of 1.4 mm, one 256² cone-beam view at θ = 30°, 120 kVp, Schneider tissues) part
//! by part, for profiling and tuning; not part of the test suite.
//!
//! `cargo run --release -p tomograf-physics --example profile_poly -- [mono|trace|integrate|all] [bins]`
use glam::DVec3;
use std::time::Instant;
use tomograf_physics::acquisition::Acquisition;
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::phantom::Phantom;
use tomograf_sim::tissue::TissueModel;
use tomograf_sim::*;

fn main() {
    let part = std::env::args().nth(1).unwrap_or_else(|| "all".into());
    let bins: Option<usize> = std::env::args().nth(2).and_then(|b| b.parse().ok());
    let hu = Phantom::thorax()
        .voxelize([256; 3], DVec3::splat(1.4), DVec3::ZERO)
        .unwrap();
    let mu = Attenuation::hounsfield_at_kev(70.0)
        .unwrap()
        .to_mu(hu.clone())
        .unwrap();
    let view = Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(256, 256, 360.0 * 1.5 * 1.1 / 256.0),
        isocentre: DVec3::ZERO,
    }
    .view(Pose::new(30.0, 0.0))
    .unwrap();
    let mut acq = Acquisition::preset("kv-flat-panel-120kvp").unwrap();
    acq.materials = TissueModel::schneider();
    acq.spectrum.bins = bins;
    let p = acq.prepare(&hu, 1).unwrap();
    let renderer = Renderer::new(&mu, Projector::Siddon).unwrap();
    let t = p.mass_thickness(Projector::Siddon, &view).unwrap();
    let mas = acq.spectrum.mas;
    let n: usize = std::env::var("N")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(40);
    let time = |name: &str, f: &dyn Fn()| {
        f();
        let mut times: Vec<f64> = (0..n)
            .map(|_| {
                let start = Instant::now();
                f();
                start.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        times.sort_by(f64::total_cmp);
        println!(
            "{name}: median {:.2} ms, fastest {:.2} ms",
            times[n / 2],
            times[0]
        );
    };
    if part == "mono" || part == "all" {
        time("mono render", &|| {
            std::hint::black_box(renderer.render(&view).unwrap());
        });
    }
    if part == "trace" || part == "all" {
        time("per-material trace", &|| {
            std::hint::black_box(p.mass_thickness(Projector::Siddon, &view).unwrap());
        });
    }
    if part == "integrate" || part == "all" {
        time(
            &format!("integration, {} bins", p.integrator().energies_kev().len()),
            &|| {
                std::hint::black_box(p.integrator().expected(&t, &view, mas).unwrap());
            },
        );
    }
}
