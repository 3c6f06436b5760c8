//! Scatter correction of an item's views: with the object itself as the estimate the
//! corrected −log is the primary's, up to the estimate's Monte Carlo error; items that
//! cannot be corrected are named.

mod common;

use tomograf_model::scatter_correction::correct_item;
use tomograf_physics::acquisition::Acquisition;
use tomograf_physics::scatter::ScatterModel;
use tomograf_sim::{Projector, Volume};

#[test]
fn the_objects_own_scatter_is_removed_from_its_views() {
    let mut item = common::item(24, 4, 12, 0.0);
    let mut acq = Acquisition::preset("kv-flat-panel-120kvp").unwrap();
    acq.scatter = ScatterModel::Estimate {
        photons: 20_000,
        grid: 6,
        multiple_grid: 0,
        smoothing: 1.0,
        detection_cell_mm: 0.0,
    };
    // The views as a scatter-contaminated acquisition records them (expected signal, no
    // noise), and as the primary alone would be.
    let ct: &Volume = item.ct.as_ref().unwrap();
    let hu = item.window.denormalize(ct).unwrap();
    let measured_with = acq.prepare(&hu, 11).unwrap();
    let (mut measured, mut primary) = (Vec::new(), Vec::new());
    for v in &item.views {
        let (with, open) = measured_with.expected(Projector::Siddon, v).unwrap();
        let p = measured_with.primary(Projector::Siddon, v).unwrap();
        for k in 0..open.mean.len() {
            measured.push((-(with.mean[k] / open.mean[k]).ln()) as f32);
            primary.push((-(p.mean[k] / open.mean[k]).ln()) as f32);
        }
    }
    item.projections = measured.clone();
    item.acquisition = Some(acq);
    let worst = |p: &[f32]| -> f64 {
        p.iter()
            .zip(&primary)
            .map(|(a, b)| f64::from(a - b).abs())
            .fold(0.0, f64::max)
    };
    let before = worst(&measured);
    // A 72 mm body: little scatter, but well above the estimate's error.
    assert!(before > 0.02, "scatter lowers the −log by up to {before}");
    // Views 1 and 3 only, from the ground truth with another Monte Carlo seed.
    let fixed = correct_item(&item, ct, &[1, 3], 99).unwrap();
    let n = item.rows * item.cols;
    for v in 0..4 {
        let (a, b) = (v * n, (v + 1) * n);
        if v % 2 == 0 {
            assert_eq!(
                fixed.projections[a..b],
                measured[a..b],
                "view {v} untouched"
            );
        } else {
            // Exact but for the two estimates' statistical error (20 000 histories each,
            // smoothed: ≈ 1.4 % of the scatter here, so 5 % leaves a margin of 3).
            let left = worst_in(&fixed.projections[a..b], &primary[a..b]);
            assert!(left < 0.05 * before, "view {v}: {left} left of {before}");
        }
    }
}

fn worst_in(a: &[f32], b: &[f32]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| f64::from(x - y).abs())
        .fold(0.0, f64::max)
}

#[test]
fn items_without_scatter_or_acquisition_are_named() {
    let mut item = common::item(8, 2, 6, 0.0);
    let ct = item.ct.clone().unwrap();
    let e = correct_item(&item, &ct, &[0], 1).unwrap_err().to_string();
    assert!(e.contains("has none"), "{e}");
    item.acquisition = Some(Acquisition::preset("kv-flat-panel-120kvp").unwrap());
    let e = correct_item(&item, &ct, &[0], 1).unwrap_err().to_string();
    assert!(e.contains("models no scatter"), "{e}");
    let mut with = Acquisition::preset("kv-flat-panel-120kvp").unwrap();
    with.scatter = ScatterModel::Estimate {
        photons: 10,
        grid: 2,
        multiple_grid: 0,
        smoothing: 1.0,
        detection_cell_mm: 0.0,
    };
    item.acquisition = Some(with);
    let e = correct_item(&item, &ct, &[5], 1).unwrap_err().to_string();
    assert!(e.contains("view 5 does not exist"), "{e}");
}
