//! Soft-tissue heterogeneity: a spatially correlated texture added to muscle, organs, blood
//! and myocardium, so that a phantom's soft tissue varies as a real CT's does at CT
//! resolution (vessels, fat stranding, contrast and the scanner's noise, which the labels
//! do not draw).
//!
//! Real chest CTs at 64³ (docs/real-ct/tissue-stats-5cts.md) show soft tissue with a
//! standard deviation of 48–58 HU and a 3×3×3 texture of 12–15 HU; the default phantoms'
//! per-voxel white noise (a few HU at 2 mm) averages to 23–30 and 4–6 there. The texture here
//! is value noise: standard normal deviates on a lattice of [`CELL_MM`] spacing, counter-based
//! (`super::tissue::gauss`) so that it does not depend on the thread count, interpolated
//! trilinearly and rescaled to unit variance on average over positions.

use super::Tissue;
use super::tissue::{gauss, mix64};
use glam::DVec3;

/// Lattice spacing of the texture, mm. Chosen with the real CTs' statistics: at 64³, 8 mm
/// gave a 3×3×3 texture twice the real CTs' at the same spread (21 HU at sd 42); 16 mm with
/// 60 HU gives sd 54 and texture 15 against the real 53 and 14 (docs/datasets.md,
/// "Soft-tissue heterogeneity").
pub const CELL_MM: f64 = 16.0;

/// The values a heterogeneous soft-tissue voxel is kept within, HU: the soft-tissue class of
/// the statistics above widened by the texture's tails (a voxel of muscle may read as fat,
/// as partial volume makes it do in a real CT).
pub const RANGE_HU: (f32, f32) = (-100.0, 250.0);

/// The tissues that receive the texture.
pub fn applies_to(t: Tissue) -> bool {
    matches!(
        t,
        Tissue::Muscle | Tissue::SoftTissue | Tissue::Blood | Tissue::Heart
    )
}

/// Mean over positions of the variance of a trilinear blend of independent unit deviates:
/// `(E[w² + (1 − w)²])³ = (2/3)³` for `w` uniform on [0, 1).
const BLEND_VARIANCE: f64 = 8.0 / 27.0;

/// The texture at world position `p` (mm), about standard normal: deviates of `seed` on the
/// lattice, blended trilinearly.
pub fn value_noise(seed: u64, p: DVec3) -> f32 {
    value_noise_on(seed, p, CELL_MM)
}

/// [`value_noise`] on a lattice of `cell_mm` spacing.
pub fn value_noise_on(seed: u64, p: DVec3, cell_mm: f64) -> f32 {
    let q = p / cell_mm;
    let base = q.floor();
    let w = q - base;
    let (bx, by, bz) = (base.x as i64, base.y as i64, base.z as i64);
    let mut sum = 0.0f64;
    for corner in 0..8u32 {
        let (dx, dy, dz) = (
            (corner & 1) as i64,
            ((corner >> 1) & 1) as i64,
            (corner >> 2) as i64,
        );
        let key = mix64(
            ((bx + dx) as u64)
                ^ mix64(((by + dy) as u64) ^ mix64((bz + dz) as u64)).rotate_left(17),
        );
        let weight = [(w.x, dx), (w.y, dy), (w.z, dz)]
            .iter()
            .map(|&(t, d)| if d == 1 { t } else { 1.0 - t })
            .product::<f64>();
        sum += weight * gauss(seed, key) as f64;
    }
    (sum / BLEND_VARIANCE.sqrt()) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Unit variance over positions, zero mean, correlated within a cell and independent
    /// beyond two.
    #[test]
    fn the_texture_is_unit_variance_and_correlated_over_a_cell() {
        let (mut s, mut s2, mut near, mut far) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let n = 40_000;
        for i in 0..n {
            let f = i as f64;
            let p = DVec3::new(f * 3.71 % 997.0, f * 1.37 % 613.0, f * 0.113);
            let v = value_noise(7, p) as f64;
            s += v;
            s2 += v * v;
            near += v * value_noise(7, p + DVec3::new(0.2 * CELL_MM, 0.0, 0.0)) as f64;
            far += v * value_noise(7, p + DVec3::new(2.5 * CELL_MM, 0.0, 0.0)) as f64;
        }
        let (mean, var) = (s / n as f64, s2 / n as f64 - (s / n as f64).powi(2));
        assert!(mean.abs() < 0.03, "{mean}");
        assert!((var - 1.0).abs() < 0.05, "{var}");
        assert!(near / n as f64 > 0.6, "{}", near / n as f64);
        assert!((far / n as f64).abs() < 0.05, "{}", far / n as f64);
    }
}
