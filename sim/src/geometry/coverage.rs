//! How a view's beam meets a volume: for geometry that is legal but almost certainly not
//! what was meant — a source inside the patient, a detector through the patient (SID at
//! or just above SAD), or a beam that misses the volume altogether (an isocentre or a
//! detector offset far from the CT) and would write an image of zeros.
//!
//! A sample of the view's pixels (a grid of at most 17 × 17, edges and corners included)
//! is traced against the volume's box; the checks are geometric only (no voxel is read).

use super::{View, ViewBeam};
use crate::ray::GridRay;
use crate::volume::Volume;

/// How a view meets a volume's box.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Coverage {
    /// The point source lies inside the volume's box (cone beam only).
    pub source_inside: bool,
    /// Some sampled pixel centre lies inside the volume's box (the detector cuts through
    /// the volume: the rays stop there, and the line integrals are truncated).
    pub detector_inside: bool,
    /// Sampled pixels whose ray crosses the volume's box.
    pub rays_hitting: usize,
    /// Pixels sampled.
    pub rays_sampled: usize,
}

/// The sampled pixel indices along an axis of `n` pixels: at most 17, both ends included.
fn samples(n: usize) -> Vec<f64> {
    let k = n.min(17);
    if k == 1 {
        return vec![0.0];
    }
    (0..k)
        .map(|i| (i as f64 * (n - 1) as f64 / (k - 1) as f64).round())
        .collect()
}

/// How `view` meets `volume` (see [`Coverage`]).
pub fn coverage(view: &View, volume: &Volume) -> Coverage {
    let mut c = Coverage {
        source_inside: false,
        detector_inside: false,
        rays_hitting: 0,
        rays_sampled: 0,
    };
    for &row in &samples(view.rows) {
        for &col in &samples(view.cols) {
            let ray = view.ray(row, col);
            c.rays_sampled += 1;
            let Some(g) = GridRay::clip(volume, &ray) else {
                continue;
            };
            c.rays_hitting += 1;
            if let ViewBeam::Cone { .. } = view.beam {
                // The ray starts at the source (t = 0) and ends at the pixel (t_max).
                let eps = 1e-9 * ray.t_max.max(1.0);
                c.source_inside |= g.t_enter <= ray.t_min + eps;
                c.detector_inside |= g.t_exit >= ray.t_max - eps;
            }
        }
    }
    c
}
