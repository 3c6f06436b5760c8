//! The tracer chosen by name (`Renderer::with_tracer`, `[projector] tracer`): every tracer's
//! images against the scalar tracer's, and `auto` against a renderer that was never told.
//! Tolerance 1e-6 relative on the f32 pixels (floor 1e-6): the tracers sum the same exact
//! path lengths in different orders (each matches the brute-force reference to 1e-9 in
//! `siddon.rs`, `packet.rs` and `sheet.rs`), so they differ by f64 rounding before the cast.

mod common;

use common::*;
use glam::DVec3;
use tomograf_sim::{Beam, Detector, Geometry, Pose, Projector, Renderer, Tracer, Volume};

/// A cone-beam orbit about the grid's k axis (16 views, so `auto` makes column sheets),
/// its isocentre a little off the volume's centre (see `sheet.rs`'s `geometry`), and a
/// tilted view.
fn views(vol: &Volume) -> Vec<tomograf_sim::View> {
    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: 300.0,
            sid_mm: 450.0,
        },
        detector: Detector::new(23, 31, 3.0),
        isocentre: vol.centre() + DVec3::new(0.0123, 0.0456, 0.0078),
    };
    let mut poses: Vec<Pose> = (0..16).map(|n| Pose::new(n as f64 * 22.5, 0.0)).collect();
    poses.push(Pose::new(33.0, 12.0));
    g.views(&poses).unwrap()
}

#[test]
fn every_tracer_renders_the_scalar_tracers_images() {
    let mut r = rng(91);
    let vol = random_volume(&mut r, [36, 29, 19], false);
    let views = views(&vol);
    let render = |tracer: Option<Tracer>| -> Vec<Vec<f32>> {
        let mut renderer = Renderer::new(&vol, Projector::Siddon).unwrap();
        if let Some(t) = tracer {
            renderer = renderer.with_tracer(t);
        }
        let renderer = renderer.for_views(&views);
        views
            .iter()
            .map(|v| renderer.render(v).unwrap().data)
            .collect()
    };
    let scalar = render(Some(Tracer::Scalar));
    assert!(scalar.iter().flatten().any(|&v| v > 0.0));
    for t in [
        Tracer::Auto,
        Tracer::Packets,
        Tracer::Sheets,
        Tracer::Columns,
    ] {
        for (n, (a, b)) in scalar.iter().zip(render(Some(t))).enumerate() {
            for (p, (x, y)) in a.iter().zip(&b).enumerate() {
                assert!(
                    (x - y).abs() <= 1e-6 * x.abs().max(1e-6),
                    "{t:?}, view {n}, pixel {p}: scalar {x}, {y}"
                );
            }
        }
    }
    // `auto` is what a renderer that was never told does, to the bit.
    assert_eq!(render(None), render(Some(Tracer::Auto)));
}

#[test]
fn a_tracer_chosen_by_name_keeps_its_choice_over_the_views() {
    let mut r = rng(92);
    let vol = random_volume(&mut r, [24, 20, 12], false);
    let views = views(&vol);
    let copy = |t: Tracer| {
        Renderer::new(&vol, Projector::Siddon)
            .unwrap()
            .with_tracer(t)
            .for_views(&views)
            .column_copy()
            .is_some()
    };
    // Sixteen views of an orbit about k: `auto` makes the column sheets' copy, `columns`
    // makes it whatever the views, the others never do.
    assert!(copy(Tracer::Auto));
    assert!(copy(Tracer::Columns));
    for t in [Tracer::Scalar, Tracer::Packets, Tracer::Sheets] {
        assert!(!copy(t), "{t:?}");
    }
    let one = Renderer::new(&vol, Projector::Siddon)
        .unwrap()
        .with_tracer(Tracer::Columns)
        .for_views(&views[..1]);
    assert!(one.column_copy().is_some());
    assert_eq!(one.tracer(), Tracer::Columns);
}
