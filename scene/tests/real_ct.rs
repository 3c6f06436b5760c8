//! Real CTs into items (issue 47): every orientation a file can store gives the same item,
//! and what is not the body — a couch, the scanner's padding circle, stray voxels — is set
//! to air before the crop, while an arm held apart from the chest is kept.
//!
//! The synthetic patient is written here, by hand, in the patient frame (i → left,
//! j → posterior, k → superior); each of the 48 axis permutations and flips is built by
//! reindexing that array directly (not with the code under test), placed in the world by
//! its direction matrix, and written as NIfTI and as a DICOM series.

use glam::{DMat3, DVec3};
use std::path::{Path, PathBuf};
use tomograf_datasets::item::{ItemRecord, finished_record};
use tomograf_datasets::{dicom, image, nifti};
use tomograf_scene::dataset::{ItemSettings, ItemSource, make_item};
use tomograf_sim::Volume;

const DIMS: [usize; 3] = [32, 26, 14];
const SPACING: [f64; 3] = [12.0, 10.0, 20.0];

/// HU of the synthetic patient at canonical voxel `(i, j, k)`; `dirty` adds a couch under
/// the back, −2048 padding outside the reconstruction circle and stray voxels in the air.
fn patient(i: usize, j: usize, k: usize, dirty: bool) -> f32 {
    let (x, y) = (i as f64 - 13.0, j as f64 - 11.0);
    // Trunk: an ellipse, left–right 11 voxels, antero-posterior 8 (j = 3 … 19).
    let trunk = (x / 11.0).powi(2) + (y / 8.0).powi(2) <= 1.0 && (1..=12).contains(&k);
    // An arm held apart on the patient's left (high i, 26 … 30; the trunk ends at 24), from
    // k = 3 to 11.
    let arm =
        (i as f64 - 28.0).powi(2) + (y + 1.0).powi(2) <= 2.6f64.powi(2) && (3..=11).contains(&k);
    // Asymmetric contents: a lung on the right, a spine at the back, a dense lump high and
    // to the left, so that any flip or swap of axes shows.
    let lung = (x + 5.0).powi(2) / 16.0 + (y + 1.0).powi(2) / 20.0 <= 1.0 && (3..=10).contains(&k);
    let spine = x.abs() <= 1.0 && (14..=17).contains(&j) && (1..=12).contains(&k);
    let lump = (x - 5.0).abs() <= 1.0 && (y + 4.0).abs() <= 1.0 && (9..=11).contains(&k);
    if trunk {
        return if spine || lump {
            700.0
        } else if lung {
            -820.0
        } else {
            40.0 + (i + 2 * j + 3 * k) as f32 % 7.0
        };
    }
    if arm {
        return 60.0;
    }
    if dirty {
        // A couch top: flat, under the back (posterior: high j), the whole length.
        if (22..=23).contains(&j) {
            return 300.0;
        }
        // The reconstruction circle: −2048 outside.
        if x.powi(2) + y.powi(2) > 19.0f64.powi(2) {
            return -2048.0;
        }
        // Stray voxels: a sheet's edge, a cable.
        if (i == 3 && j == 3) || (i == 25 && j == 20 && k == 7) {
            return -300.0;
        }
    }
    -1000.0
}

fn canonical(dirty: bool) -> Volume {
    let mut data = Vec::with_capacity(DIMS.iter().product());
    for k in 0..DIMS[2] {
        for j in 0..DIMS[1] {
            for i in 0..DIMS[0] {
                data.push(patient(i, j, k, dirty));
            }
        }
    }
    Volume::new(
        DIMS,
        DVec3::from(SPACING),
        DVec3::new(-150.0, -120.0, 40.0),
        DMat3::IDENTITY,
        data,
    )
    .unwrap()
}

/// The same patient stored with index axis `a` along world axis `perm[a]`, in the sense
/// `sign[a]`: the signed permutation's direction, dims, spacing and origin, and the
/// voxels reindexed by hand.
fn stored(v: &Volume, perm: [usize; 3], sign: [f64; 3]) -> Volume {
    let n = v.dims();
    let dims: [usize; 3] = std::array::from_fn(|a| n[perm[a]]);
    let spacing = DVec3::from_array(std::array::from_fn(|a| v.spacing()[perm[a]]));
    let canonical_index = |idx: [usize; 3]| -> [usize; 3] {
        let mut c = [0; 3];
        for a in 0..3 {
            c[perm[a]] = if sign[a] > 0.0 {
                idx[a]
            } else {
                n[perm[a]] - 1 - idx[a]
            };
        }
        c
    };
    let mut data = Vec::with_capacity(v.len());
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let c = canonical_index([i, j, k]);
                data.push(v.get(c[0], c[1], c[2]));
            }
        }
    }
    let axis = |a: usize| {
        let mut e = DVec3::ZERO;
        e[perm[a]] = sign[a];
        e
    };
    let direction = DMat3::from_cols(axis(0), axis(1), axis(2));
    let c0 = canonical_index([0, 0, 0]);
    let origin = v.index_to_world(DVec3::new(c0[0] as f64, c0[1] as f64, c0[2] as f64));
    Volume::new(dims, spacing, origin, direction, data).unwrap()
}

fn settings() -> ItemSettings {
    ItemSettings {
        size: 12,
        views: 2,
        ..ItemSettings::default()
    }
}

/// (CT voxels, projections, record) of the item made from `path`.
fn item(path: &Path, dir: &Path, settings: &ItemSettings) -> (Vec<f32>, Vec<f32>, ItemRecord) {
    make_item(
        settings,
        0,
        &ItemSource::File {
            path: path.to_path_buf(),
        },
        dir,
    )
    .unwrap();
    let ct = nifti::read_nifti(&dir.join("ct.nii.gz")).unwrap();
    assert_eq!(ct.direction(), DMat3::IDENTITY, "{}", path.display());
    let (projections, _) = image::read_npy(&dir.join("projections.npy")).unwrap();
    (ct.into_data(), projections, finished_record(dir).unwrap())
}

fn write(volume: &Volume, dir: &Path, name: &str, dicom_too: bool) -> Vec<PathBuf> {
    let nii = dir.join(format!("{name}.nii.gz"));
    nifti::write_nifti(&nii, volume).unwrap();
    let mut out = vec![nii];
    if dicom_too {
        let series = dir.join(format!("{name}_dicom"));
        dicom::write_dicom_series(&series, volume, "1.2.826.0.1.3680043.2.1125.47").unwrap();
        out.push(series);
    }
    out
}

#[test]
fn every_axis_permutation_and_flip_gives_the_same_item() {
    let tmp = tempfile::tempdir().unwrap();
    let v = canonical(true);
    let reference = item(
        &write(&v, tmp.path(), "canonical", false)[0],
        &tmp.path().join("item_ref"),
        &settings(),
    );
    let perms = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut checked = 0;
    for (p, perm) in perms.iter().enumerate() {
        for flips in 0..8 {
            let sign: [f64; 3] =
                std::array::from_fn(|a| if flips >> a & 1 == 0 { 1.0 } else { -1.0 });
            let s = stored(&v, *perm, sign);
            let name = format!("p{p}f{flips}");
            for path in write(&s, tmp.path(), &name, true) {
                let got = item(
                    &path,
                    &tmp.path().join(format!("item_{checked}")),
                    &settings(),
                );
                // Reordering is exact: the CT on the item grid is the same bytes.
                assert_eq!(got.0, reference.0, "{}: CT differs", path.display());
                // The views see the same patient; the files store positions in f32, so the
                // geometry (and the line integrals) agree to rounding.
                let peak = reference.1.iter().fold(0f32, |m, &x| m.max(x));
                for (a, b) in got.1.iter().zip(&reference.1) {
                    assert!(
                        (a - b).abs() <= 1e-4 * peak,
                        "{}: projection {a} vs {b}",
                        path.display()
                    );
                }
                assert_eq!(got.2.body_fraction, reference.2.body_fraction);
                assert!(!got.2.frame.is_empty());
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 96, "48 orientations, NIfTI and DICOM");
    // The reference is not trivially symmetric: flipping j alone changes the CT.
    let flipped = stored(&v, [0, 1, 2], [1.0, -1.0, 1.0]);
    let mirrored = Volume::new(
        v.dims(),
        v.spacing(),
        v.origin(),
        DMat3::IDENTITY,
        flipped.into_data(),
    )
    .unwrap();
    let wrong = item(
        &write(&mirrored, tmp.path(), "mirrored", false)[0],
        &tmp.path().join("item_mirrored"),
        &settings(),
    );
    assert_ne!(
        wrong.0, reference.0,
        "a mirrored patient must give another item"
    );
}

#[test]
fn the_couch_padding_and_stray_voxels_go_the_arm_stays() {
    let tmp = tempfile::tempdir().unwrap();
    let dirty = write(&canonical(true), tmp.path(), "dirty", false).remove(0);
    let clean = write(&canonical(false), tmp.path(), "clean", false).remove(0);
    let a = item(&dirty, &tmp.path().join("a"), &settings());
    let b = item(&clean, &tmp.path().join("b"), &settings());
    // The body alone: the dirty CT's item is the clean CT's, byte for byte.
    assert_eq!(a.0, b.0);
    assert_eq!(a.1, b.1);
    let fraction = a.2.body_fraction.unwrap();
    // The trunk and arm fill most of their box (an ellipse fills π/4 of its own).
    assert!(fraction > 0.5, "body fraction {fraction}");
    assert!(a.2.outside_body.contains("air"), "{}", a.2.outside_body);
    // The arm is kept: the item's box reaches it (i up to 30, the trunk ends at 24).
    let ct = nifti::read_nifti(&tmp.path().join("a/ct.nii.gz")).unwrap();
    let extent = ct.dims()[0] as f64 * ct.spacing().x;
    assert!(
        extent > 27.0 * SPACING[0],
        "left–right extent {extent} mm: the arm was dropped"
    );
    // Kept (opt-out), the couch and padding stay: the box is larger, the body a smaller part.
    let keep = ItemSettings {
        keep_table: true,
        ..settings()
    };
    let c = item(&dirty, &tmp.path().join("c"), &keep);
    assert_ne!(c.0, a.0);
    let kept = c.2.body_fraction.unwrap();
    assert!(
        kept < fraction - 0.10,
        "with the couch {kept}, without {fraction}"
    );
    assert_eq!(c.2.outside_body, "kept");
}
