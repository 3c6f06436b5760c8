//! Renders the chest-sized case (512×512×133 voxels of 0.7×0.7×2.5 mm, 256² detector,
//! SAD 1000 / SID 1500) repeatedly at gantry angle θ (first argument, degrees), for
//! profiling and tuning; not part of the test suite.
//!
//! * `TG_PACKET_THRESHOLD=x` — crossings per layer from which the SIMD tracer is used
//!   (`inf`: scalar only), as used to choose `packet::default_threshold`.
//! * `COUNT=1` — also print what the scalar tracer reports per ray (segments, runs).
//! * `N=k` — time k back-to-back renders after the first (default 20) and print their
//!   mean, fastest and median: on a shared machine compare builds by their fastest, in
//!   interleaved runs.
//!
//! `cargo run --release -p tomograf-sim --example profile_ap -- 30`
use glam::DVec3;
use std::time::Instant;
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::phantom::Phantom;
use tomograf_sim::trace::{PathAccumulator, siddon};
use tomograf_sim::*;

fn main() {
    let hu = Phantom::thorax()
        .voxelize([512, 512, 133], DVec3::new(0.7, 0.7, 2.5), DVec3::ZERO)
        .unwrap();
    let mu = Attenuation::hounsfield_at_kev(60.0)
        .unwrap()
        .to_mu(hu)
        .unwrap();
    let theta: f64 = std::env::args()
        .nth(1)
        .map(|s| s.parse().unwrap())
        .unwrap_or(0.0);
    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(256, 256, 2.6),
        isocentre: DVec3::ZERO,
    };
    let v = g.view(Pose::new(theta, 0.0)).unwrap();
    let mut r = Renderer::new(&mu, Projector::Siddon).unwrap();
    if let Some(t) = std::env::var("TG_PACKET_THRESHOLD")
        .ok()
        .and_then(|v| v.parse().ok())
    {
        r = r.with_packet_threshold(t);
    }
    let t = Instant::now();
    let _ = r.render(&v).unwrap();
    println!("first render: {:.2} ms", t.elapsed().as_secs_f64() * 1e3);
    let n: usize = std::env::var("N")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20)
        .max(1);
    let mut times: Vec<f64> = (0..n)
        .map(|_| {
            let t = Instant::now();
            std::hint::black_box(r.render(&v).unwrap());
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    println!(
        "θ={theta}: mean {:.2} ms, min {:.2}, median {:.2}",
        times.iter().sum::<f64>() / n as f64,
        times[0],
        times[n / 2]
    );
    if std::env::var_os("COUNT").is_some() {
        count(&mu, &v);
    }
}

/// Counts what the scalar tracer reports per ray.
#[derive(Default)]
struct Counts {
    segments: u64,
    triples: u64,
    runs: u64,
    run_voxels: u64,
}

impl PathAccumulator for Counts {
    fn segment(&mut self, _: usize, _: f64) {
        self.segments += 1;
    }
    fn segments3(&mut self, _: [usize; 3], _: [f64; 3]) {
        self.triples += 1;
    }
    fn run(&mut self, _: usize, _: usize, count: usize, _: f64) {
        self.runs += 1;
        self.run_voxels += count as u64;
    }
}

fn count(mu: &Volume, v: &View) {
    let mut c = Counts::default();
    let mut rays = 0;
    for r in 0..v.rows {
        for col in 0..v.cols {
            if let Some(g) = GridRay::clip(mu, &v.ray(r as f64, col as f64)) {
                siddon::trace(mu.dims(), &g, &mut c);
                rays += 1;
            }
        }
    }
    let f = |x: u64| x as f64 / rays as f64;
    println!(
        "per ray ({rays} rays): single segments {:.1}, slab triples {:.1}, runs {:.1}, voxels in runs {:.1}",
        f(c.segments),
        f(c.triples),
        f(c.runs),
        f(c.run_voxels)
    );
}
