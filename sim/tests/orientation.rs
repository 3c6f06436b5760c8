//! Which detector pixel sees which point: a point object, no silent flips or transposes.
//!
//! Pixel (0, 0) is the top-left pixel in the beam's-eye view; in the AP view the patient's
//! right is on the image's left and the head at the top.

#![allow(clippy::needless_range_loop)] // loops over the three grid axes read best with an index

use glam::{DMat3, DVec3};
use tomograf_sim::{Beam, Detector, Geometry, Pose, Projection, Projector, Renderer, Volume};

/// A 64³ volume of 2 mm voxels, zero except one voxel whose centre is at world `p`.
fn point_object(p: DVec3, direction: DMat3) -> Volume {
    let n = 64;
    let spacing = DVec3::splat(2.0);
    // Put voxel (40, 20, 50) at p, whatever the storage orientation.
    let idx = DVec3::new(40.0, 20.0, 50.0);
    let origin = p - direction * (idx * spacing);
    let mut data = vec![0.0f32; n * n * n];
    data[40 + n * (20 + n * 50)] = 1.0;
    Volume::new([n, n, n], spacing, origin, direction, data).unwrap()
}

fn argmax(img: &Projection) -> (usize, usize) {
    let i = img
        .data
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.partial_cmp(b.1).unwrap())
        .unwrap()
        .0;
    (i / img.cols, i % img.cols)
}

/// Intensity-weighted centre `(row, col)` of an image.
fn centroid(img: &Projection) -> (f64, f64) {
    let (mut w, mut r, mut c) = (0.0, 0.0, 0.0);
    for (i, &v) in img.data.iter().enumerate() {
        let v = f64::from(v);
        w += v;
        r += v * (i / img.cols) as f64;
        c += v * (i % img.cols) as f64;
    }
    (r / w, c / w)
}

/// The point's shadow is centred where the geometry says. Pixel-centre sampling of a
/// 2 mm voxel's shadow places its centroid within half a 0.25 mm pixel, so a half-voxel
/// (1 mm) shift, a flip or a transpose fails.
fn assert_at(img: &Projection, proj: (f64, f64)) {
    let (r, c) = centroid(img);
    assert!(
        (r - proj.0).abs() <= 0.5 && (c - proj.1).abs() <= 0.5,
        "centroid ({r:.2}, {c:.2}) vs projected ({:.2}, {:.2})",
        proj.0,
        proj.1
    );
}

fn render(vol: &Volume, beam: Beam, pose: Pose) -> (Projection, (f64, f64)) {
    let g = Geometry {
        beam,
        detector: Detector::new(513, 513, 0.25),
        isocentre: DVec3::new(5.0, -3.0, 2.0),
    };
    let view = g.view(pose).unwrap();
    let img = Renderer::new(vol, Projector::Siddon)
        .unwrap()
        .render(&view)
        .unwrap();
    let p = view.project_point(DVec3::new(30.0, -20.0, 40.0)).unwrap();
    (img, p)
}

const CONE: Beam = Beam::Cone {
    sad_mm: 1000.0,
    sid_mm: 1500.0,
};

#[test]
fn ap_view_puts_patient_left_on_the_right_and_head_at_the_top() {
    // Left (+x), anterior (−y), superior (+z) of the isocentre.
    let p = DVec3::new(30.0, -20.0, 40.0);
    let vol = point_object(p, DMat3::IDENTITY);
    let (img, proj) = render(&vol, CONE, Pose::AP);
    assert_at(&img, proj);
    let (r, c) = argmax(&img);
    // By hand: the source is at y = −1003, the point 983 mm from it: magnification 1.526.
    // 25 mm left of the isocentre → 38 mm right of the panel centre; 38 mm above → 58 mm up.
    let (du, dv) = ((c as f64 - 256.0) * 0.25, (r as f64 - 256.0) * 0.25);
    assert!((du - 38.2).abs() < 1.5, "column offset {du} mm");
    assert!((dv + 58.0).abs() < 1.5, "row offset {dv} mm");
}

#[test]
fn lateral_view_puts_anterior_on_the_left() {
    let p = DVec3::new(30.0, -20.0, 40.0);
    let vol = point_object(p, DMat3::IDENTITY);
    let (img, proj) = render(&vol, CONE, Pose::LATERAL);
    assert_at(&img, proj);
    let (r, c) = argmax(&img);
    // Source at x = 1005; the point is 17 mm anterior of the isocentre, 975 mm from the
    // source: magnification 1.538 → 26 mm left of centre; 38 mm above → 58.5 mm up.
    let (du, dv) = ((c as f64 - 256.0) * 0.25, (r as f64 - 256.0) * 0.25);
    assert!(
        (du + 26.2).abs() < 1.5,
        "anterior (−y) on the image's left: column offset {du} mm"
    );
    assert!(
        (dv + 58.5).abs() < 1.5,
        "head at the top: row offset {dv} mm"
    );
}

#[test]
fn parallel_view_agrees_with_projection() {
    let p = DVec3::new(30.0, -20.0, 40.0);
    let vol = point_object(p, DMat3::IDENTITY);
    for pose in [Pose::AP, Pose::LATERAL, Pose::new(37.0, 12.0)] {
        let (img, proj) = render(&vol, Beam::Parallel, pose);
        assert_at(&img, proj);
    }
}

#[test]
fn storage_orientation_does_not_change_the_image() {
    // The same physical object stored LPS-style, RAS-style (x and y flipped) and rotated:
    // the images must agree pixel by pixel.
    let p = DVec3::new(30.0, -20.0, 40.0);
    let reference = render(
        &point_object(p, DMat3::IDENTITY),
        CONE,
        Pose::new(20.0, 10.0),
    )
    .0;
    for dir in [
        DMat3::from_diagonal(DVec3::new(-1.0, -1.0, 1.0)),
        DMat3::from_cols(DVec3::Y, DVec3::X, -DVec3::Z),
        DMat3::from_cols(DVec3::Z, DVec3::X, DVec3::Y),
    ] {
        let img = render(&point_object(p, dir), CONE, Pose::new(20.0, 10.0)).0;
        assert_eq!(argmax(&img), argmax(&reference));
        for (a, b) in img.data.iter().zip(&reference.data) {
            assert!((a - b).abs() <= 1e-5 * b.abs().max(1e-3), "{a} vs {b}");
        }
    }
}
