use glam::DVec3;
use std::time::Instant;
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::phantom::Phantom;
use tomograf_sim::*;
fn main() {
    let small = std::env::args().any(|a| a == "small");
    let hu = if small { Phantom::thorax().voxelize([128, 128, 133], DVec3::new(2.8, 2.8, 2.5), DVec3::ZERO).unwrap() } else { Phantom::thorax().voxelize([512, 512, 133], DVec3::new(0.7, 0.7, 2.5), DVec3::ZERO).unwrap() };
    let mu = Attenuation::hounsfield_at_kev(60.0).unwrap().to_mu(&hu).unwrap();
    let args: Vec<String> = std::env::args().collect();
    let par = args.get(1).map(|s| s == "par").unwrap_or(false);
    let g = Geometry { beam: if par { Beam::Parallel } else { Beam::Cone { sad_mm: 1000.0, sid_mm: 1500.0 } }, detector: Detector::new(256, 256, if par {1.4} else {2.6}), isocentre: DVec3::ZERO };
    for pose in [Pose::AP, Pose::LATERAL, Pose::new(30.0, 0.0), Pose::new(0.0, 30.0)] {
        let v = g.view(pose).unwrap();
        let r = Renderer::new(&mu, Projector::Siddon).unwrap();
        let _ = r.render(&v).unwrap();
        let t = Instant::now();
        let n = 10;
        for _ in 0..n { std::hint::black_box(r.render(&v).unwrap()); }
        println!("{pose:?}: {:.2} ms", t.elapsed().as_secs_f64() * 1e3 / n as f64);
    }
}
