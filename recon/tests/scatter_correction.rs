//! Scatter correction through the acquisition's own scatter model: from the object itself
//! the correction removes the scatter a Monte Carlo added, to f32 rounding with the same
//! stream and to its statistical error with another.

use glam::{DMat3, DVec3};
use tomograf_physics::acquisition::Acquisition;
use tomograf_physics::scatter::ScatterModel;
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
fn scatter_correction_from_the_object_removes_the_scatter() {
    use tomograf_recon::scatter_correction::{correct_log, scatter_to_primary};
    let hu = water_cube();
    let v = view();
    let mut a = Acquisition::preset("kv-flat-panel-120kvp").unwrap();
    a.scatter = ScatterModel::MonteCarlo {
        photons: 4000,
        grid: 4,
        multiple_grid: 0,
        max_order: 20,
        detection_cell_mm: 0.0,
        angular_window_deg: 0.0,
        split: 1,
        sparse_multiple: false,
        sampler: Default::default(),
        cell_check: 0,
    };
    let prepared = a.prepare(&hu, 3).unwrap();
    // Noiseless −log with and without scatter: the expected images over the open field.
    let (with, open) = prepared.expected(Projector::Siddon, &v).unwrap();
    let primary = prepared.primary(Projector::Siddon, &v).unwrap();
    let log = |signal: &[f64]| -> Vec<f32> {
        signal
            .iter()
            .zip(&open.mean)
            .map(|(s, o)| (-(s / o).ln()) as f32)
            .collect()
    };
    let truth = log(&primary.mean);
    let measured = log(&with.mean);
    let error = |p: &[f32]| -> f64 {
        p.iter()
            .zip(&truth)
            .map(|(a, b)| f64::from(a - b).abs())
            .fold(0.0, f64::max)
    };
    let before = error(&measured);
    assert!(before > 0.1, "scatter lowers the −log by {before}");
    // The same Monte Carlo stream as the measurement (view 0): exact up to f32 rounding.
    let mut same = measured.clone();
    correct_log(&mut same, &scatter_to_primary(&prepared, &v, 0).unwrap()).unwrap();
    assert!(error(&same) < 1e-5, "{}", error(&same));
    // Another stream (view 7): exact up to the estimate's statistical error; 4000
    // histories leave a few per cent of the scatter, so the error falls by ≥ 80 %.
    let mut other = measured.clone();
    correct_log(&mut other, &scatter_to_primary(&prepared, &v, 7).unwrap()).unwrap();
    assert!(
        error(&other) < 0.2 * before,
        "{} of {before}",
        error(&other)
    );
    // Without scatter in the acquisition there is nothing to estimate.
    let plain = Acquisition::preset("kv-flat-panel-120kvp")
        .unwrap()
        .prepare(&hu, 3)
        .unwrap();
    let e = scatter_to_primary(&plain, &v, 0).unwrap_err();
    assert!(e.to_string().contains("models scatter"), "{e}");
}
