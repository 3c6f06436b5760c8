//! The scan range: which stretch of the patient's length a CT covers. A chest CT is not
//! always taken from the lung apices to below the diaphragm: pyradiomics' `lung1` covers the
//! upper thorax only (apex to the heart), an abdominal scan takes the lung bases alone. Once
//! cropped to the body and put on the training grid, such a CT's sections are stretched
//! along the patient to fill the grid, and a prior that has seen only whole chests draws a
//! whole chest into it (docs/model.md, "On real CTs"). Training phantoms cut to a drawn
//! range show it what part-thorax scans look like.
//!
//! One [`ScanRange`] is drawn per item from a seed and applied to a volume in the patient
//! frame ([`crate::frame`], k → superior) before it is cropped: of the body's length — the
//! sections holding a voxel above the crop threshold, from the lowest (fraction 0) to the
//! highest (fraction 1) — the sections from `from` to `to` are kept and the others dropped.
//! The crop that follows takes the kept body's box.

use crate::error::{DatasetError, Result};
use glam::{DMat3, DVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use tomograf_sim::Volume;

/// The shortest range [`ScanRange::draw`] gives, as a fraction of the body's length: half
/// (an upper thorax from the apex to the heart, as lung1 holds).
pub const SHORTEST: f64 = 0.5;

/// A stretch of the body's length, as fractions of it from its inferior end (0) to its
/// superior end (1), as recorded in `item.json`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ScanRange {
    /// Fraction of the body's length where the kept stretch begins (inferior end).
    pub from: f64,
    /// Fraction where it ends (superior end); `from < to`.
    pub to: f64,
}

impl ScanRange {
    /// The whole body.
    pub const WHOLE: Self = Self { from: 0.0, to: 1.0 };

    /// A draw from `seed`: a length uniform in [[`SHORTEST`], 1], placed uniformly within
    /// the body (so a quarter of the items keep at least 7/8 of it, and the apex and the
    /// diaphragm are each cut from about half).
    pub fn draw(seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let length: f64 = rng.random_range(SHORTEST..=1.0);
        let from = rng.random_range(0.0..=1.0 - length);
        Self {
            from,
            to: (from + length).min(1.0),
        }
    }

    /// The volume cut to this range of its body's length: the sections (k-planes) whose
    /// position along the body — (k − k_lo)/(k_hi − k_lo), with k_lo and k_hi the lowest and
    /// highest sections holding a voxel above `threshold` (HU) — lies within [`from`, `to`]
    /// rounded to whole sections; the kept sections stay where they were in the world.
    /// Errors if the range is not within [0, 1] with `from < to`, `threshold` is not
    /// finite, no voxel exceeds it, or the volume is not in the patient frame.
    ///
    /// [`from`]: ScanRange::from
    /// [`to`]: ScanRange::to
    pub fn apply(&self, volume: &Volume, threshold: f32) -> Result<Volume> {
        let ordered = self.from.is_finite()
            && self.to.is_finite()
            && 0.0 <= self.from
            && self.from < self.to
            && self.to <= 1.0;
        if !ordered {
            return Err(DatasetError::Invalid(format!(
                "scan range {self:?}: needs 0 ≤ from < to ≤ 1"
            )));
        }
        if !threshold.is_finite() {
            return Err(DatasetError::Invalid(format!(
                "scan range: threshold {threshold} HU is not finite"
            )));
        }
        if volume.direction() != DMat3::IDENTITY {
            return Err(DatasetError::Invalid(
                "scan range: the volume must be in the patient frame (identity direction)".into(),
            ));
        }
        let [nx, ny, _] = volume.dims();
        let plane = nx * ny;
        let body: Vec<usize> = volume
            .data()
            .chunks(plane)
            .enumerate()
            .filter(|(_, p)| p.iter().any(|&v| v > threshold))
            .map(|(k, _)| k)
            .collect();
        let (Some(&lo), Some(&hi)) = (body.first(), body.last()) else {
            return Err(DatasetError::Invalid(format!(
                "scan range: no voxel exceeds the threshold {threshold} HU: no body to cut"
            )));
        };
        let span = (hi - lo) as f64;
        let k0 = lo + (self.from * span).round() as usize;
        let k1 = (lo + (self.to * span).round() as usize).clamp(k0, hi);
        let data = volume.data()[k0 * plane..(k1 + 1) * plane].to_vec();
        let origin = volume.index_to_world(DVec3::new(0.0, 0.0, k0 as f64));
        Volume::new(
            [nx, ny, k1 - k0 + 1],
            volume.spacing(),
            origin,
            DMat3::IDENTITY,
            data,
        )
        .map_err(|e| DatasetError::Invalid(format!("scan range: {e}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::AIR_HU;

    /// 3 × 2 sections; sections 2..=12 of 15 hold body (value k·10 at one voxel).
    fn column() -> Volume {
        let mut data = vec![AIR_HU; 3 * 2 * 15];
        for k in 2..=12 {
            data[1 + 3 * (1 + 2 * k)] = k as f32 * 10.0;
        }
        Volume::centred([3, 2, 15], DVec3::new(1.0, 1.0, 2.0), DVec3::ZERO, data).unwrap()
    }

    #[test]
    fn the_whole_range_keeps_every_body_section_and_the_air_around_goes() {
        let v = column();
        let whole = ScanRange::WHOLE.apply(&v, -900.0).unwrap();
        assert_eq!(whole.dims(), [3, 2, 11]);
        assert_eq!(whole.get(1, 1, 0), 20.0);
        assert_eq!(whole.get(1, 1, 10), 120.0);
        // The kept sections stay where they were.
        let at = |w: &Volume, k: usize| w.index_to_world(DVec3::new(0.0, 0.0, k as f64));
        assert_eq!(at(&whole, 0), at(&v, 2));
    }

    #[test]
    fn a_range_keeps_its_fraction_of_the_body_by_whole_sections() {
        let v = column();
        // The body spans 10 section steps: 0.3–0.8 → sections 5..=10.
        let part = ScanRange { from: 0.3, to: 0.8 }.apply(&v, -900.0).unwrap();
        assert_eq!(part.dims(), [3, 2, 6]);
        assert_eq!(part.get(1, 1, 0), 50.0);
        assert_eq!(part.get(1, 1, 5), 100.0);
        let at = |w: &Volume, k: usize| w.index_to_world(DVec3::new(0.0, 0.0, k as f64));
        assert_eq!(at(&part, 0), at(&v, 5));
        // The superior end: the top section is the body's highest.
        let top = ScanRange { from: 0.5, to: 1.0 }.apply(&v, -900.0).unwrap();
        assert_eq!(top.get(1, 1, top.dims()[2] - 1), 120.0);
    }

    #[test]
    fn bad_ranges_and_bodiless_volumes_are_errors() {
        let v = column();
        for (from, to) in [
            (0.5, 0.5),
            (0.6, 0.4),
            (-0.1, 0.5),
            (0.2, 1.1),
            (f64::NAN, 1.0),
        ] {
            let e = ScanRange { from, to }.apply(&v, -900.0).unwrap_err();
            assert!(e.to_string().contains("0 ≤ from < to ≤ 1"), "{e}");
        }
        let air = Volume::centred([2, 2, 2], DVec3::ONE, DVec3::ZERO, vec![AIR_HU; 8]).unwrap();
        let e = ScanRange::WHOLE.apply(&air, -900.0).unwrap_err();
        assert!(e.to_string().contains("no body"), "{e}");
        assert!(ScanRange::WHOLE.apply(&v, f32::NAN).is_err());
    }

    #[test]
    fn draws_stay_in_range_and_differ_by_seed() {
        for seed in 0..200 {
            let r = ScanRange::draw(seed);
            assert!(0.0 <= r.from && r.to <= 1.0, "{r:?}");
            assert!(r.apply(&column(), -900.0).is_ok());
            assert!(r.to - r.from >= SHORTEST - 1e-12, "{r:?}");
        }
        assert_eq!(ScanRange::draw(7), ScanRange::draw(7));
        assert_ne!(ScanRange::draw(1), ScanRange::draw(2));
    }
}
