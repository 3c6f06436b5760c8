//! A small synthetic item (ellipsoid body with a dense sphere) and its exact projections.

use glam::DVec3;
use tomograf_datasets::preprocess::HuWindow;
use tomograf_model::data::Item;
use tomograf_model::render::DensityScale;
use tomograf_sim::attenuation::mu_water_per_mm;
use tomograf_sim::{Beam, Detector, Geometry, Pose, Projector, Renderer, Volume};

/// Normalised density of a body (0.33 ≈ water in the chest window) with a bone-like
/// sphere (0.6), in a `n³` grid of 3 mm voxels centred at `centre`.
pub fn body(n: usize, centre: DVec3, shift: f64) -> Volume {
    let mut data = Vec::with_capacity(n * n * n);
    let h = (n as f64 - 1.0) / 2.0;
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let p = DVec3::new(i as f64 - h, j as f64 - h, k as f64 - h) / h;
                let e = (p.x / 0.8).powi(2) + (p.y / 0.6).powi(2) + (p.z / 0.9).powi(2);
                let s = (p - DVec3::new(0.3 + shift, 0.1, 0.0)).length();
                data.push(if s < 0.3 {
                    0.6
                } else if e < 1.0 {
                    0.33
                } else {
                    0.0
                });
            }
        }
    }
    Volume::centred([n, n, n], DVec3::splat(3.0), centre, data).unwrap()
}

/// An item of `body(n)` with `views` projections (every 360/views°) on a `det²` panel.
pub fn item(n: usize, views: usize, det: usize, shift: f64) -> Item {
    let centre = DVec3::new(5.0, -3.0, 10.0);
    let ct = body(n, centre, shift);
    let window = HuWindow::CHEST;
    let scale = DensityScale::from_window(-1024.0, 2048.0, mu_water_per_mm(60.0).unwrap()).unwrap();
    let mu = ct.map(|d| scale.mu_scalar(f64::from(d)) as f32).unwrap();
    let geometry = Geometry {
        beam: Beam::Cone {
            sad_mm: 600.0,
            sid_mm: 900.0,
        },
        detector: Detector::new(det, det, 1.5 * 3.0 * n as f64 / det as f64),
        isocentre: centre,
    };
    let poses: Vec<Pose> = (0..views)
        .map(|v| Pose::new(v as f64 * 360.0 / views as f64, 0.0))
        .collect();
    let views_v = geometry.views(&poses).unwrap();
    let r = Renderer::new(&mu, Projector::Siddon).unwrap();
    let mut projections = Vec::new();
    for v in &views_v {
        projections.extend(r.render(v).unwrap().data);
    }
    Item {
        id: format!("synthetic-{shift}"),
        dir: std::path::PathBuf::new(),
        ct: Some(ct),
        projections,
        rows: det,
        cols: det,
        geometry,
        poses,
        views: views_v,
        window,
        scale,
        acquisition: None,
    }
}
