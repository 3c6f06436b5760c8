//! Landmarks of the mediastinum that the airways, the heart and the great vessels are
//! placed by: where the oesophagus and the trachea run, and the carina's height (mm).

use super::patient::Params;

/// Outer radius of the trachea and oesophagus.
pub(crate) fn trachea_radius(p: &Params) -> f64 {
    9.5 * p.sv
}
pub(crate) fn esophagus_radius(p: &Params) -> f64 {
    7.0 * p.s
}

/// Centre y of the oesophagus (just in front of the spine) at height z.
pub(crate) fn esophagus_y(p: &Params, z: f64) -> f64 {
    p.spine_y(z) - p.vertebra(z).1 - esophagus_radius(p) - 2.0
}

/// Centre y of the trachea (in front of the oesophagus) at height z.
pub(crate) fn trachea_y(p: &Params, z: f64) -> f64 {
    esophagus_y(p, z) - esophagus_radius(p) - 3.0 - trachea_radius(p)
}

/// Height of the carina.
pub(crate) fn z_carina(p: &Params) -> f64 {
    p.z_thoracic(4.6)
}
