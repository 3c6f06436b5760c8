//! Mass thickness per material through a ray sheet: over a composition's packed values
//! ([`crate::composition`]: a density and a material index per voxel), each ray's Σρ·ℓ of
//! every material, as [`crate::trace::accumulate::MaterialPaths`] sums it for one ray.
//!
//! A segment's piece of a ray is split between the two voxels it meets as for the line
//! integral (`Kernel::piece`), and goes to one material or, where the two voxels differ in
//! material, to both; each piece is added to its material's sum at once. The SIMD kernels
//! add it to every material's vector where the lane's material is that one (k masked adds
//! per piece). Keeping a running sum per ray while its material stays the same, as the
//! packet kernels do, measured slower here: on the chest CT split into the Schneider
//! tissues the material changes on 12 % of a ray's steps, so some lane of eight changes
//! on most steps and the flushes branch unpredictably (docs/projector.md, "Session 27").
//! Adding a piece of 0 (a ray outside its range, or a voxel of density 0) changes no bits,
//! so the kernels' skips of such pieces (`super::Sheet::skip_zeros`) keep the same bits.

use super::{Kernel, Rays, Segment};
use crate::composition::unpack;

/// Per material and ray, the sums Σρ·db (g/cm³ per unit of b), material-major: material `m`
/// of ray `r` at `m·n + r` (`n` rays), so that a kernel's lanes read one vector per material.
#[derive(Debug, Clone)]
pub(super) struct MaterialSums {
    k: usize,
    pub(super) sums: Vec<f64>,
}

impl MaterialSums {
    /// Zero sums of `rays` rays over `k` materials.
    pub(super) fn new(rays: usize, k: usize) -> Self {
        Self {
            k,
            sums: vec![0.0; rays * k],
        }
    }

    /// Materials held.
    pub(super) fn materials(&self) -> usize {
        self.k
    }

    /// Rays held.
    pub(super) fn rays(&self) -> usize {
        self.sums.len() / self.k.max(1)
    }

    /// Adds `w` of material `label` to ray `r`.
    #[inline]
    fn add(&mut self, r: usize, label: usize, w: f64) {
        let n = self.rays();
        self.sums[label * n + r] += w;
    }

    /// Material `m`'s sum of ray `r`.
    pub(super) fn sum(&self, r: usize, m: usize) -> f64 {
        self.sums[m * self.rays() + r]
    }
}

impl Kernel<'_> {
    /// Σ over segments of ∫ρ db per material for every ray into `state` (portable; the
    /// SIMD kernels compute the same operations, so give the same bits).
    pub(super) fn integrate_materials(
        &self,
        segments: &[Segment],
        rays: &Rays,
        state: &mut MaterialSums,
    ) {
        for s in segments {
            for r in 0..rays.len() {
                let (v0, v1, w, db) = self.voxels(s, rays, r);
                let ((rho0, m0), (rho1, m1)) = (unpack(v0), unpack(v1));
                let (rho0, rho1) = (f64::from(rho0), f64::from(rho1));
                if m0 == m1 {
                    state.add(r, m1, w.mul_add(rho0 - rho1, db * rho1));
                } else {
                    state.add(r, m0, w * rho0);
                    state.add(r, m1, (db - w) * rho1);
                }
            }
        }
    }
}
