//! Local majorants for Woodcock tracking: the composition grid cut into bricks of `size³`
//! voxels, each holding, per material, the largest density found within one voxel of it.
//!
//! At energy E a brick's majorant is σ̄_b(E) = max_m (μ/ρ)_m(E) · ρ̄_{b,m} (mm⁻¹), which
//! bounds the attenuation of every voxel a point inside the brick can be looked up in
//! (the brick grown by one voxel covers the `floor` of points on its faces, whatever the
//! rounding). Tracking with the brick's own majorant instead of the volume's makes fewer
//! null collisions where the medium is thinner than its densest voxel (lung next to bone)
//! and none at all in empty bricks (air), and it stays unbiased: the free path is sampled
//! piecewise, and the optical depth left when a brick is exited carries over to the next
//! ([`super::transport::Medium::fly`]).
//!
//! Tracking looks the majorant up in a table per brick and 1 keV energy interval
//! ([`MajorantGrid::tabulate`]), one load per brick crossed. Memory: `k` + `n` f32 per
//! brick (`k` materials, `n` 1 keV intervals); the default 16³ bricks of a 512×512×133
//! grid take 5.8 MB for six materials at 150 kVp.

use rayon::prelude::*;
use tomograf_sim::accel::bricks::brick_rows;
use tomograf_sim::composition::unpack;
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::volume::Volume;

/// Default brick edge, voxels: of 4, 8 and 16 the fastest in two of the three cases of
/// `physics/examples/scatter_tracking.rs` and within run-to-run spread in the third
/// (docs/scatter.md, "Tracking").
pub const DEFAULT_BRICK: usize = 16;

/// Per-brick, per-material maximum densities of a packed composition grid.
#[derive(Debug, Clone, PartialEq)]
pub struct MajorantGrid {
    size: usize,
    bricks: [usize; 3],
    materials: usize,
    /// ρ̄ (g/cm³), `materials` values per brick, bricks `x`-fastest.
    rho_max: Vec<f32>,
    /// Majorants (mm⁻¹) per energy interval of a 1 keV table ([`MajorantGrid::tabulate`]):
    /// interval-major, a row of one value per brick each.
    sigma: Vec<f32>,
    bricks_total: usize,
}

impl MajorantGrid {
    /// Scans `packed` (a [`tomograf_sim::composition`] grid of `materials` materials) in bricks of
    /// `size³` voxels (≥ 1).
    pub fn build(packed: &Volume, materials: usize, size: usize) -> Result<Self> {
        if size == 0 {
            return Err(SimError::OutOfRange(
                "majorant brick size is 0 voxels; it must be ≥ 1".into(),
            ));
        }
        let dims = packed.dims();
        let bricks = dims.map(|d| d.div_ceil(size));
        let data = packed.data();
        let rho_max: Vec<f32> = (0..bricks[0] * bricks[1] * bricks[2])
            .into_par_iter()
            .flat_map_iter(|b| {
                // The brick grown by one voxel on every side, clamped to the grid.
                let mut rho = vec![0.0f32; materials];
                for row in brick_rows(b, bricks, size, 1, dims) {
                    for &v in &data[row] {
                        let (r, m) = unpack(v);
                        if m < materials && r > rho[m] {
                            rho[m] = r;
                        }
                    }
                }
                rho
            })
            .collect();
        Ok(Self {
            size,
            bricks,
            materials,
            rho_max,
            sigma: Vec::new(),
            bricks_total: bricks[0] * bricks[1] * bricks[2],
        })
    }

    /// Tabulates every brick's majorant for `cells` energy cells, given for each material
    /// `m` and cell `k` a bound `mu_per_density(m, k)` (mm⁻¹ per g/cm³) on its μ/ρ anywhere
    /// in the cell; rounded up to f32.
    pub fn tabulate(&mut self, cells: usize, mu_per_density: impl Fn(usize, usize) -> f64 + Sync) {
        let n = self.bricks_total;
        let mut sigma = Vec::with_capacity(cells * n);
        for k in 0..cells {
            let mu: Vec<f64> = (0..self.materials).map(|m| mu_per_density(m, k)).collect();
            sigma.extend((0..n).map(|b| (self.sigma_of(b, &mu) * (1.0 + 1e-6)) as f32));
        }
        self.sigma = sigma;
    }

    /// The tabulated majorant (mm⁻¹) of brick `b` for energy interval `interval` (after
    /// [`MajorantGrid::tabulate`]).
    #[inline]
    pub fn sigma_in(&self, b: [usize; 3], interval: usize) -> f64 {
        let i = b[0] + self.bricks[0] * (b[1] + self.bricks[1] * b[2]);
        f64::from(self.sigma[interval * self.bricks_total + i])
    }

    #[inline]
    fn sigma_of(&self, i: usize, mu_per_density: &[f64]) -> f64 {
        self.rho_max[i * self.materials..(i + 1) * self.materials]
            .iter()
            .zip(mu_per_density)
            .fold(0.0, |s, (&r, &mu)| s.max(f64::from(r) * mu))
    }

    /// Brick edge, voxels.
    pub fn size(&self) -> usize {
        self.size
    }

    /// Bricks per axis.
    pub fn brick_dims(&self) -> [usize; 3] {
        self.bricks
    }

    /// The majorant (mm⁻¹) of brick `b` given each material's μ/ρ at the photon's energy
    /// in mm⁻¹ per g/cm³ (`mu_per_density[m]`).
    #[inline]
    pub fn sigma(&self, b: [usize; 3], mu_per_density: &[f64]) -> f64 {
        self.sigma_of(
            b[0] + self.bricks[0] * (b[1] + self.bricks[1] * b[2]),
            mu_per_density,
        )
    }

    /// The densest voxel of each material over the whole grid (g/cm³).
    pub fn global_max(&self) -> Vec<f64> {
        let mut out = vec![0.0f64; self.materials];
        for brick in self.rho_max.chunks(self.materials.max(1)) {
            for (o, &r) in out.iter_mut().zip(brick) {
                *o = o.max(f64::from(r));
            }
        }
        out
    }
}
