//! Scatter inside the acquisition chain: `none` changes nothing, a Monte Carlo adds exactly
//! its own expected images to the primary, and the `[scatter]` table parses.

use glam::{DMat3, DVec3};
use tomograf_sim::acquisition::Acquisition;
use tomograf_sim::scatter::ScatterModel;
use tomograf_sim::*;

fn water_cube() -> Volume {
    Volume::new(
        [16, 16, 16],
        DVec3::splat(10.0),
        DVec3::splat(-75.0),
        DMat3::IDENTITY,
        vec![0.0; 16 * 16 * 16],
    )
    .unwrap()
}

fn view() -> View {
    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(8, 8, 40.0),
        isocentre: DVec3::ZERO,
    };
    g.view(Pose::new(0.0, 0.0)).unwrap()
}

#[test]
fn scatter_adds_its_expected_images_and_none_adds_nothing() {
    let hu = water_cube();
    let v = view();
    let base = Acquisition::preset("kv-flat-panel-120kvp").unwrap();
    assert_eq!(base.scatter, ScatterModel::None);
    let plain = base.prepare(&hu, 3).unwrap();
    assert!(plain.scatter(&v, 0).unwrap().is_none());
    let (p0, _) = plain.expected(Projector::Siddon, &v).unwrap();

    let mut with = base.clone();
    with.scatter = ScatterModel::MonteCarlo {
        photons: 1500,
        grid: 4,
        max_order: 20,
    };
    let prepared = with.prepare(&hu, 3).unwrap();
    let (p1, _) = prepared.expected(Projector::Siddon, &v).unwrap();
    let s = prepared.scatter(&v, 0).unwrap().unwrap().total();
    for i in 0..p0.mean.len() {
        assert!(s.mean[i] > 0.0 && s.second_moment[i] > 0.0);
        assert_eq!(p1.mean[i], p0.mean[i] + s.mean[i]);
        assert_eq!(
            p1.second_moment[i],
            p0.second_moment[i] + s.second_moment[i]
        );
    }
    // 15 cm of water at 120 kVp, 24 cm field at the detector: scatter is a large fraction
    // of the primary under the phantom (literature SPR for 15–20 cm water without a grid
    // is 1–5), and certainly between 0.2 and 10 here.
    let c = 3 * 8 + 3;
    let spr = s.mean[c] / p0.mean[c];
    assert!((0.2..10.0).contains(&spr), "SPR {spr}");
}

#[test]
fn the_scatter_table_parses_inside_an_acquisition() {
    let mut a = Acquisition::preset("cbct-100kvp").unwrap();
    a.scatter = ScatterModel::Estimate {
        photons: 100,
        grid: 4,
        smoothing: 1.0,
    };
    let text = toml::to_string(&a).unwrap();
    assert!(text.contains("model = \"estimate\""), "{text}");
    let back: Acquisition = toml::from_str(&text).unwrap();
    assert_eq!(back, a);
}
