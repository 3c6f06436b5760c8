//! The scatter examples' case: the analytic thorax voxelised at 4.5 × 4.5 × 8.3 mm, seen
//! AP by a cone beam (SAD 1000 / SID 1500 mm) on a 430 mm square panel.
use glam::DVec3;
use tomograf_sim::phantom::Phantom;
use tomograf_sim::*;

/// Panel width, mm (256 pixels of 1.68 mm).
pub const PANEL_MM: f64 = 256.0 * 1.68;

/// The thorax, HU.
pub fn thorax() -> Volume {
    Phantom::thorax()
        .voxelize([80, 56, 40], DVec3::new(4.5, 4.5, 8.3), DVec3::ZERO)
        .unwrap()
}

/// The AP view with the panel read as `pixels` × `pixels`.
pub fn ap_view(pixels: usize) -> View {
    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: 1000.0,
            sid_mm: 1500.0,
        },
        detector: Detector::new(pixels, pixels, PANEL_MM / pixels as f64),
        isocentre: DVec3::ZERO,
    };
    g.view(Pose::new(0.0, 0.0)).unwrap()
}
