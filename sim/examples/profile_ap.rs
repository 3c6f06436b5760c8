//! Renders the chest-sized AP view repeatedly, for profiling. Not part of the test suite.
use glam::DVec3;
use std::time::Instant;
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::phantom::Phantom;
use tomograf_sim::*;
fn main() {
    let hu = Phantom::thorax()
        .voxelize([512, 512, 133], DVec3::new(0.7, 0.7, 2.5), DVec3::ZERO)
        .unwrap();
    let mu = Attenuation::hounsfield_at_kev(60.0)
        .unwrap()
        .to_mu(&hu)
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
    let r = Renderer::new(&mu, Projector::Siddon).unwrap();
    let _ = r.render(&v).unwrap();
    let t = Instant::now();
    let n = 20;
    for _ in 0..n {
        std::hint::black_box(r.render(&v).unwrap());
    }
    println!(
        "θ={theta}: {:.2} ms",
        t.elapsed().as_secs_f64() * 1e3 / n as f64
    );
}
