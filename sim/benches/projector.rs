//! Criterion benchmark: exact Siddon against the trilinear marcher on the same scene, so
//! their ratio is measured in one process. `cargo bench -p tomograf-sim`.
//! (The full speed tables come from `tomograf bench`.)

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;
use std::hint::black_box;
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::phantom::Phantom;
use tomograf_sim::{Beam, Detector, Geometry, Pose, Projector, Renderer};

fn projectors(c: &mut Criterion) {
    let hu = Phantom::thorax()
        .voxelize([128, 128, 64], DVec3::new(2.8, 2.8, 5.2), DVec3::ZERO)
        .unwrap();
    let mu = Attenuation::hounsfield_at_kev(60.0)
        .unwrap()
        .to_mu(hu)
        .unwrap();
    let view = Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(128, 128, 4.4),
        isocentre: DVec3::ZERO,
    }
    .view(Pose::new(30.0, 10.0))
    .unwrap();
    let mut g = c.benchmark_group("cone 128² view of a 128×128×64 thorax");
    for (name, p) in [
        ("siddon", Projector::Siddon),
        (
            "trilinear step 1",
            Projector::Trilinear { step_voxels: 1.0 },
        ),
        (
            "trilinear step 0.5",
            Projector::Trilinear { step_voxels: 0.5 },
        ),
    ] {
        let r = Renderer::new(&mu, p).unwrap();
        g.bench_function(name, |b| b.iter(|| black_box(r.render(&view).unwrap())));
    }
    g.finish();
}

criterion_group!(benches, projectors);
criterion_main!(benches);
