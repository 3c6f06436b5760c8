//! Shape augmentation of a training CT, so that a prior learned from phantoms has seen what
//! real populations do and phantoms do not: a patient lying a little rotated, and a body
//! whose cross-section changes and drifts along its length (a chest that narrows towards
//! the shoulders, a belly that rises, a back that is not parallel to the table). Phantoms are
//! near-extrusions: each axial section fills ~85 % of their box; a real chest CT's sections
//! fill ~80 % of their own boxes but ~60 % of the union box (docs/model.md, "On real CTs").
//!
//! One [`Augmentation`] is drawn per item from a seed, and applied to a volume in HU in the
//! patient frame ([`crate::frame`]) before it is cropped: output voxel centre `q` (world
//! mm, relative to the volume's centre `c`) takes the input's value at
//!
//! ```text
//! p = c + R⁻¹ · ((q_xy − t(z)) / s(z), q_z),   s(z) = exp(taper · ζ),   t(z) = drift · ζ · (half-width, half-depth)
//! ```
//!
//! with ζ = (z − c_z)/half-height ∈ [−1, 1] and `R` a rotation by `roll` about the
//! patient's long axis (z), then `tilt` about the left–right axis (x); trilinear, air
//! (−1000 HU) outside. Every value is one fixed sequence of f64 operations: the bytes do
//! not depend on the thread count.

use crate::body::AIR_HU;
use crate::error::{DatasetError, Result};
use crate::frame::sample_world;
use glam::{DMat3, DVec2, DVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tomograf_sim::Volume;

/// The largest magnitude of each parameter [`Augmentation::draw`] samples (uniformly in
/// ±these).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AugmentRanges {
    /// Rotation about the long axis, degrees.
    pub roll_deg: f64,
    /// Rotation about the left–right axis, degrees.
    pub tilt_deg: f64,
    /// Log of the section's scale at the top over the middle (and its inverse at the bottom).
    pub taper: f64,
    /// Section centre's shift at the top, as a fraction of the half-width (x) and half-depth
    /// (y); the opposite at the bottom.
    pub drift: [f64; 2],
}

impl Default for AugmentRanges {
    /// ±5° roll, ±3° tilt, ±12 % taper, ±12 % lateral and ±15 % antero-posterior drift.
    fn default() -> Self {
        Self {
            roll_deg: 5.0,
            tilt_deg: 3.0,
            taper: 0.12,
            drift: [0.12, 0.15],
        }
    }
}

/// One draw of the augmentation (module docs), as recorded in `item.json`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Augmentation {
    /// Degrees about z.
    pub roll_deg: f64,
    /// Degrees about x.
    pub tilt_deg: f64,
    /// `s(z) = exp(taper · ζ)`.
    pub taper: f64,
    /// `t(z) = drift · ζ · (half-width, half-depth)`.
    pub drift: [f64; 2],
}

impl Augmentation {
    /// A draw from `seed`: a strength `a` uniform in [0, 1], then each parameter uniform
    /// within ±`a` times its range, so that the set spans unaugmented items to the ranges'
    /// corners (a body filling 85 % of its box down to about 60 %).
    pub fn draw(seed: u64, ranges: &AugmentRanges) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let strength: f64 = rng.random_range(0.0..=1.0);
        let mut u = |m: f64| {
            let m = m * strength;
            if m > 0.0 {
                rng.random_range(-m..=m)
            } else {
                0.0
            }
        };
        Self {
            roll_deg: u(ranges.roll_deg),
            tilt_deg: u(ranges.tilt_deg),
            taper: u(ranges.taper),
            drift: [u(ranges.drift[0]), u(ranges.drift[1])],
        }
    }

    /// The augmented volume (module docs) on the input's grid grown by a fifth of its width
    /// and depth on each side (so that no part of the body leaves it; the crop that follows
    /// takes the body's new box). Errors if a parameter is not finite or the volume is not
    /// in the patient frame (identity direction).
    pub fn apply(&self, volume: &Volume) -> Result<Volume> {
        let finite = [
            self.roll_deg,
            self.tilt_deg,
            self.taper,
            self.drift[0],
            self.drift[1],
        ]
        .iter()
        .all(|v| v.is_finite());
        if !finite {
            return Err(DatasetError::Invalid(format!(
                "augmentation {self:?}: every parameter must be finite"
            )));
        }
        if volume.direction() != DMat3::IDENTITY {
            return Err(DatasetError::Invalid(
                "augmentation: the volume must be in the patient frame (identity direction)".into(),
            ));
        }
        let n = volume.dims();
        // The output grid: the input's, grown by a fifth of its width and depth on each side.
        let grow = [n[0].div_ceil(5), n[1].div_ceil(5)];
        let dims = [n[0] + 2 * grow[0], n[1] + 2 * grow[1], n[2]];
        let spacing = volume.spacing();
        let origin = volume.origin() - DVec3::new(grow[0] as f64, grow[1] as f64, 0.0) * spacing;
        let centre = volume.centre();
        let half = DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64) * spacing * 0.5;
        let inverse = (DMat3::from_rotation_x(self.tilt_deg.to_radians())
            * DMat3::from_rotation_z(self.roll_deg.to_radians()))
        .transpose();
        let mut data = vec![0.0f32; dims[0] * dims[1] * dims[2]];
        data.par_chunks_mut(dims[0] * dims[1])
            .enumerate()
            .for_each(|(k, plane)| {
                let z = origin.z + k as f64 * spacing.z - centre.z;
                let zeta = if half.z > 0.0 { z / half.z } else { 0.0 };
                let scale = (self.taper * zeta).exp();
                let shift = DVec2::new(self.drift[0] * half.x, self.drift[1] * half.y) * zeta;
                for (e, out) in plane.iter_mut().enumerate() {
                    let (i, j) = (e % dims[0], e / dims[0]);
                    let q = DVec2::new(
                        origin.x + i as f64 * spacing.x - centre.x,
                        origin.y + j as f64 * spacing.y - centre.y,
                    );
                    let xy = (q - shift) / scale;
                    *out =
                        sample_world(volume, centre + inverse * DVec3::new(xy.x, xy.y, z), AIR_HU);
                }
            });
        Volume::new(dims, spacing, origin, DMat3::IDENTITY, data)
            .map_err(|e| DatasetError::Invalid(format!("augmentation: {e}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(dims: [usize; 3]) -> Volume {
        let data = (0..dims.iter().product::<usize>())
            .map(|e| (e % 7) as f32 * 10.0)
            .collect();
        Volume::centred(dims, DVec3::new(2.0, 3.0, 4.0), DVec3::ZERO, data).unwrap()
    }

    #[test]
    fn zero_is_the_identity_and_draws_stay_in_range() {
        let v = cube([9, 8, 7]);
        let none = Augmentation {
            roll_deg: 0.0,
            tilt_deg: 0.0,
            taper: 0.0,
            drift: [0.0, 0.0],
        };
        // The input, surrounded by air: 2 voxels more on each side of i, 2 of j.
        let same = none.apply(&v).unwrap();
        assert_eq!(same.dims(), [13, 12, 7]);
        for (i, j, k) in [(0, 0, 0), (8, 7, 6), (3, 4, 5)] {
            assert_eq!(same.get(i + 2, j + 2, k), v.get(i, j, k));
        }
        assert_eq!(same.get(0, 5, 3), AIR_HU);
        assert_eq!(same.index_to_world(DVec3::new(2.0, 2.0, 0.0)), v.origin());
        let r = AugmentRanges::default();
        for seed in 0..50 {
            let a = Augmentation::draw(seed, &r);
            assert!(a.roll_deg.abs() <= r.roll_deg && a.taper.abs() <= r.taper);
            assert!(a.drift[1].abs() <= r.drift[1]);
        }
        assert_ne!(Augmentation::draw(1, &r), Augmentation::draw(2, &r));
    }

    #[test]
    fn a_drift_moves_each_section_by_its_own_amount() {
        // A bright column at the centre: with drift, the top section's column moves by
        // drift·half-width in x, the bottom one the other way, the middle stays.
        let dims = [21, 21, 11];
        let mut data = vec![AIR_HU; 21 * 21 * 11];
        for k in 0..11 {
            data[10 + 21 * (10 + 21 * k)] = 500.0;
        }
        let v = Volume::centred(dims, DVec3::ONE, DVec3::ZERO, data).unwrap();
        let a = Augmentation {
            roll_deg: 0.0,
            tilt_deg: 0.0,
            taper: 0.0,
            drift: [4.0 / 10.5, 0.0],
        };
        let out = a.apply(&v).unwrap();
        // The grid grew by 5 voxels on each side: the input's centre column is at i = 15.
        let peak = |k: usize| {
            (0..31)
                .max_by(|&p, &q| out.get(p, 15, k).total_cmp(&out.get(q, 15, k)))
                .unwrap()
        };
        // ζ = ±5/5.5 at the outer sections: a shift of ±4·5/5.5 ≈ 3.6 mm.
        assert_eq!(peak(5), 15);
        assert_eq!((peak(10), peak(0)), (19, 11));
        // Air outside the input.
        assert_eq!(out.get(0, 0, 0), AIR_HU);
    }
}
