//! The projection sidecar (`tomograf_datasets::sidecar`): written and read back to the same
//! record, keys in alphabetical order, detector-signal sidecars recognised, bad files named.

use std::path::PathBuf;
use tomograf_datasets::sidecar::{
    PixelQuantity, Sidecar, ViewRecord, VolumeRecord, acquisition_record,
};
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::{Beam, Detector, Geometry, Pose, Projector, Quantity};

fn record() -> Sidecar {
    let geometry = Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(8, 10, 2.0),
        isocentre: glam::DVec3::ZERO,
    };
    let poses = [Pose::AP, Pose::LATERAL];
    let views = geometry.views(&poses).unwrap();
    Sidecar::new(
        VolumeRecord {
            path: Some(PathBuf::from("ct.nii.gz")),
            phantom: None,
            units: "hu".into(),
            attenuation: Attenuation::LinearPerMm,
            dims: [4, 5, 6],
            spacing_mm: [1.0, 1.5, 2.0],
            origin_mm: [-1.0, 0.0, 3.0],
            direction: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        },
        Projector::Trilinear { step_voxels: 0.25 },
        None,
        Quantity::Intensity { i0: 1e4 },
        Some(geometry),
        views
            .iter()
            .enumerate()
            .map(|(index, v)| ViewRecord {
                index,
                pose: Some(poses[index]),
                view: *v,
            })
            .collect(),
    )
}

#[test]
fn written_and_read_back_to_the_same_record() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("drr.json");
    let sc = record();
    sc.write(&path).unwrap();
    let back = Sidecar::read(&path).unwrap();
    assert_eq!(back.quantity, sc.quantity);
    assert_eq!(back.projector, sc.projector);
    assert_eq!(back.views.len(), 2);
    assert_eq!(back.views[1].pose, Some(Pose::LATERAL));
    assert_eq!(back.views[0].view, sc.views[0].view);
    let grid = back.grid().unwrap();
    assert_eq!(grid.dims(), [4, 5, 6]);
    assert_eq!(grid.origin().to_array(), [-1.0, 0.0, 3.0]);
    // Writing what was read gives the same bytes; top-level keys are alphabetical and the
    // fields a run did not set are absent.
    let again = dir.path().join("again.json");
    back.write(&again).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(text, std::fs::read_to_string(&again).unwrap());
    let keys: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with("  \"") && !l.starts_with("   "))
        .map(|l| l.trim().split('"').nth(1).unwrap())
        .collect();
    let mut sorted = keys.clone();
    sorted.sort();
    assert_eq!(keys, sorted);
    assert!(
        !keys.contains(&"acquisition") && !keys.contains(&"channel"),
        "{keys:?}"
    );
}

#[test]
fn a_detector_signal_sidecar_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("drr.json");
    let mut sc = record();
    sc.quantity = PixelQuantity::Described("detector signal (see acquisition)".into());
    sc.acquisition = Some(acquisition_record(&serde_json::json!({"preset": "x"}), 7).unwrap());
    sc.channel = Some(1);
    sc.write(&path).unwrap();
    let back = Sidecar::read(&path).unwrap();
    assert_eq!(back.quantity, sc.quantity);
    assert_eq!(back.channel, Some(1));
    assert_eq!(back.acquisition.unwrap()["seed"], 7);
}

#[test]
fn bad_sidecars_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("drr.json");
    std::fs::write(&path, "{\"views\": 3}").unwrap();
    let e = Sidecar::read(&path).unwrap_err().to_string();
    assert!(e.contains("drr.json"), "{e}");
    let e = Sidecar::read(&dir.path().join("missing.json"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing.json"), "{e}");
    // A grid that cannot exist is refused when it is built, not when it is read.
    let mut sc = record();
    sc.volume.dims = [0, 5, 6];
    assert!(sc.grid().is_err());
}
