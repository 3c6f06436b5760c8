//! The coarse copy of the composition that forced detection traces through.
//!
//! Every scored collision traces a ray to every scoring point, and at a CT's full
//! resolution (0.7 × 0.7 × 2.5 mm voxels: about 700 voxels a ray) those traces are nearly
//! all of the Monte Carlo's time (docs/scatter.md, "Speed"). The scattered photons reach
//! the panel from a spread of sites and angles, so the scatter image varies over
//! centimetres and does not need the transmission of each path at the CT's resolution.
//! A [`DetectionGrid`] merges `f₀ × f₁ × f₂` voxels into one cell holding, per material,
//! the mean partial density (g/cm³: the material's mass in the cell over the cell's
//! volume), so a path's per-material mass thickness Σρℓ is traced exactly through the
//! cells (Siddon) and the transmission exp(−Σ μ/ρ · ρℓ) follows at any energy as before.
//!
//! What it changes: within a cell, mass is spread evenly, so a path crossing a cell at an
//! edge of bone or lung sees the cell's mean instead of what lies on its own line. The mass
//! of every material is kept (the mean over many paths is unchanged to first order); the
//! transmission of single paths is not, and exp is convex (the mean of exp(−τ) over the
//! paths through a cell exceeds exp of their mean τ), so the scatter comes out slightly low
//! where cells mix very different densities: 0.14 % on a real chest CT, 0.5 % on a
//! validation phantom at 8 mm (docs/scatter.md). `cell_check` ([`super::estimator::CellCheck`])
//! measures that level error per run on a sample of paths and removes it.
//!
//! Cells at the far faces that reach past the grid hold the mean of the voxels they have,
//! and paths are clipped to the full-resolution grid's box first, so they cross only the
//! part of such a cell that lies inside it. Transport (where photons collide) always uses the full-resolution composition.

use glam::{DMat3, DVec3};
use rayon::prelude::*;
use tomograf_sim::composition::{Composition, MAX_MATERIALS, unpack};
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::ray::{GridRay, Ray};
use tomograf_sim::trace::{PathAccumulator, siddon};

/// Most voxels merged along one axis.
pub const MAX_FACTOR: usize = 64;

/// A composition averaged over blocks of voxels, for forced detection's transmissions.
#[derive(Debug, Clone)]
pub struct DetectionGrid {
    /// The full-resolution grid's geometry: world → grid coordinates is
    /// `to_grid · (p − origin) + ½` (see [`tomograf_sim::volume::Volume::world_to_grid`]).
    origin: DVec3,
    to_grid: DMat3,
    /// Voxels merged per cell along i, j, k.
    factor: [usize; 3],
    /// Cells along i, j, k.
    dims: [usize; 3],
    /// Voxels of the full-resolution grid along i, j, k.
    fine_dims: [usize; 3],
    /// The material indices present, in the order of `densities`' per-cell entries.
    materials: Vec<usize>,
    /// Entries per cell: `materials.len()` rounded up to 4, 8 or 16 (the padding is 0), so
    /// the walk's inner loop has a fixed length the compiler unrolls.
    lanes: usize,
    /// Mean partial density of each present material (g/cm³), `lanes` per cell, cells i
    /// fastest.
    densities: Vec<f32>,
}

impl DetectionGrid {
    /// Merges blocks of about `cell_mm` along each axis (at least one voxel, at most
    /// [`MAX_FACTOR`]): `f_a = round(cell_mm / spacing_a)`.
    pub fn new(composition: &Composition, cell_mm: f64) -> Result<Self> {
        if !(cell_mm.is_finite() && cell_mm > 0.0) {
            return Err(SimError::OutOfRange(format!(
                "[scatter] detection_cell_mm = {cell_mm}; give a cell size in mm > 0 (0: full resolution)"
            )));
        }
        let packed = composition.packed();
        let spacing = packed.spacing().to_array();
        let factor = spacing.map(|s| ((cell_mm / s).round() as usize).clamp(1, MAX_FACTOR));
        Self::with_factor(composition, factor)
    }

    /// Merges `factor[a]` voxels along axis a (each 1 to [`MAX_FACTOR`]).
    pub fn with_factor(composition: &Composition, factor: [usize; 3]) -> Result<Self> {
        if factor.iter().any(|f| !(1..=MAX_FACTOR).contains(f)) {
            return Err(SimError::OutOfRange(format!(
                "detection grid: merge factors {factor:?}; give 1 to {MAX_FACTOR} voxels per axis"
            )));
        }
        let packed = composition.packed();
        let fine_dims = packed.dims();
        let dims = [0, 1, 2].map(|a| fine_dims[a].div_ceil(factor[a]));
        let materials: Vec<usize> = composition
            .present()
            .iter()
            .enumerate()
            .filter_map(|(m, &p)| p.then_some(m))
            .collect();
        let lanes = lanes_for(materials.len());
        let mut slot = [usize::MAX; MAX_MATERIALS];
        for (k, &m) in materials.iter().enumerate() {
            slot[m] = k;
        }
        let data = packed.data();
        // Voxels in the cells of each axis (the last may have fewer).
        let count = |a: usize, c: usize| ((c + 1) * factor[a]).min(fine_dims[a]) - c * factor[a];
        let mut densities = vec![0.0f32; dims[0] * dims[1] * dims[2] * lanes];
        // One k-slab of cells per task: each sums its own block of fine voxels.
        densities
            .par_chunks_mut(dims[0] * dims[1] * lanes)
            .enumerate()
            .for_each(|(ck, slab)| {
                let mut acc = vec![0.0f64; dims[0] * dims[1] * lanes];
                let k_end = ((ck + 1) * factor[2]).min(fine_dims[2]);
                for k in ck * factor[2]..k_end {
                    for j in 0..fine_dims[1] {
                        let row = &data[fine_dims[0] * (j + fine_dims[1] * k)..][..fine_dims[0]];
                        let cj = j / factor[1];
                        for (i, &v) in row.iter().enumerate() {
                            let (rho, m) = unpack(v);
                            if rho > 0.0 {
                                let cell = i / factor[0] + dims[0] * cj;
                                acc[cell * lanes + slot[m]] += f64::from(rho);
                            }
                        }
                    }
                }
                for (cell, (d, a)) in slab.chunks_mut(lanes).zip(acc.chunks(lanes)).enumerate() {
                    let (ci, cj) = (cell % dims[0], cell / dims[0]);
                    let n = (count(0, ci) * count(1, cj) * count(2, ck)) as f64;
                    for (x, y) in d.iter_mut().zip(a) {
                        *x = (y / n) as f32;
                    }
                }
            });
        Ok(Self {
            origin: packed.origin(),
            to_grid: DMat3::from_diagonal(packed.spacing().recip())
                * packed.direction().transpose(),
            factor,
            dims,
            fine_dims,
            materials,
            lanes,
            densities,
        })
    }

    /// Voxels merged per cell along i, j, k.
    pub fn factor(&self) -> [usize; 3] {
        self.factor
    }

    /// Cells along i, j, k.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Per-material Σρ̄ℓ (g/cm³·mm, indexed by the composition's material index) along the
    /// segment `from` → `to` (world mm), traced through the cells.
    pub fn paths(&self, from: DVec3, to: DVec3) -> [f64; MAX_MATERIALS] {
        let ray = Ray::segment(from, to);
        let f = self.factor.map(|f| f as f64);
        let g0 = (self.to_grid * (ray.origin - self.origin) + 0.5).to_array();
        let gd = (self.to_grid * ray.direction).to_array();
        let missed = [0.0; MAX_MATERIALS];
        // Clipped to the full-resolution grid's box, then walked through the cells.
        let Some(fine) = GridRay::clip_grid(self.fine_dims, g0, gd, ray.t_min, ray.t_max) else {
            return missed;
        };
        let Some(g) = GridRay::clip_grid(
            self.dims,
            [0, 1, 2].map(|a| g0[a] / f[a]),
            [0, 1, 2].map(|a| gd[a] / f[a]),
            fine.t_enter,
            fine.t_exit,
        ) else {
            return missed;
        };
        match self.lanes {
            4 => self.walk::<4>(&g),
            8 => self.walk::<8>(&g),
            _ => self.walk::<MAX_MATERIALS>(&g),
        }
    }

    /// [`DetectionGrid::paths`] along the clipped ray `g` (cell coordinates) with `N` =
    /// `self.lanes` entries a cell, each lane's sum put at its material's index.
    fn walk<const N: usize>(&self, g: &GridRay) -> [f64; MAX_MATERIALS] {
        let (cells, rest) = self.densities.as_chunks::<N>();
        debug_assert!(rest.is_empty());
        let mut acc = CellPaths::<N> {
            cells,
            sums: [0.0; N],
        };
        siddon::trace(self.dims, g, &mut acc);
        let mut out = [0.0; MAX_MATERIALS];
        for (&m, &sum) in self.materials.iter().zip(&acc.sums) {
            out[m] = sum;
        }
        out
    }
}

/// Entries per cell for `materials` present materials: 4, 8 or [`MAX_MATERIALS`].
fn lanes_for(materials: usize) -> usize {
    match materials {
        0..=4 => 4,
        5..=8 => 8,
        _ => MAX_MATERIALS,
    }
}

/// Sums each lane's ρ̄·ℓ over the cells a ray crosses (`N` lanes a cell, a fixed length so
/// the loop unrolls). Every lane adds its segments in the walk's order, as one material
/// at a time would.
struct CellPaths<'a, const N: usize> {
    cells: &'a [[f32; N]],
    sums: [f64; N],
}

impl<const N: usize> PathAccumulator for CellPaths<'_, N> {
    #[inline(always)]
    fn segment(&mut self, cell: usize, length_mm: f64) {
        let d = &self.cells[cell];
        // Indexed over the constant N: the form measured (docs/scatter-speed-unrolled.md).
        #[allow(clippy::needless_range_loop)]
        for l in 0..N {
            self.sums[l] += f64::from(d[l]) * length_mm;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tomograf_sim::composition::pack;
    use tomograf_sim::volume::Volume;

    /// A 12 × 10 × 8 grid of 1.5 × 2 × 3 mm voxels, rotated, with two materials in a
    /// pattern that varies voxel to voxel.
    fn composition() -> Composition {
        composition_of(2)
    }

    /// The same grid with `materials` materials in turn.
    fn composition_of(materials: usize) -> Composition {
        let dims = [12, 10, 8];
        let mut labels = Vec::new();
        let mut density = Vec::new();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    labels.push(if materials == 2 {
                        ((i + 2 * j + k) % 3 == 0) as u8 as f32
                    } else {
                        ((i + 2 * j + 5 * k) % materials) as f32
                    });
                    density.push(if (i * 7 + j * 3 + k) % 5 == 0 {
                        0.0
                    } else {
                        0.5 + ((i + j * k) % 4) as f32 * 0.4
                    });
                }
            }
        }
        let rot = DMat3::from_rotation_z(0.3) * DMat3::from_rotation_x(-0.2);
        let grid = |data| {
            Volume::new(
                dims,
                DVec3::new(1.5, 2.0, 3.0),
                DVec3::new(-5.0, 3.0, 1.0),
                rot,
                data,
            )
            .unwrap()
        };
        let names = if materials == 2 {
            vec!["water".into(), "bone".into()]
        } else {
            (0..materials).map(|m| format!("material {m}")).collect()
        };
        Composition::from_labels(&grid(labels), &grid(density), names).unwrap()
    }

    #[test]
    fn every_lane_count_traces_each_materials_own_path() {
        // 2, 6 and 11 materials: 4, 8 and 16 entries a cell; one voxel a cell, so each
        // material's Σρℓ is the full-resolution walk's, added in the same order.
        for (materials, lanes) in [(2, 4), (6, 8), (11, MAX_MATERIALS)] {
            let c = composition_of(materials);
            let g = DetectionGrid::with_factor(&c, [1, 1, 1]).unwrap();
            assert_eq!((g.materials.len(), g.lanes), (materials, lanes));
            let centre = c.packed().centre();
            for d in [
                DVec3::new(40.0, -2.0, 3.5),
                DVec3::new(6.5, 45.0, -10.0),
                DVec3::new(-4.5, 45.0, 32.5),
            ] {
                let (a, b) = (centre - d, centre + d);
                let (x, y) = (g.paths(a, b), full_paths(&c, a, b));
                assert!(y.iter().filter(|&&v| v > 0.0).count() >= 2.min(materials));
                for m in 0..MAX_MATERIALS {
                    assert!(
                        (x[m] - y[m]).abs() <= 1e-12 * (1.0 + y[m]),
                        "{materials} {m}: {x:?} {y:?}"
                    );
                }
            }
        }
    }

    fn full_paths(c: &Composition, from: DVec3, to: DVec3) -> [f64; MAX_MATERIALS] {
        let packed = c.packed();
        let mut acc = tomograf_sim::trace::MaterialPaths::new(packed.data());
        if let Some(g) = GridRay::clip(packed, &Ray::segment(from, to)) {
            siddon::trace(packed.dims(), &g, &mut acc);
        }
        *acc.sums()
    }

    #[test]
    fn merging_one_voxel_per_cell_traces_the_composition_itself() {
        let c = composition();
        let g = DetectionGrid::with_factor(&c, [1, 1, 1]).unwrap();
        let centre = c.packed().centre();
        for (a, b) in [
            (DVec3::new(-40.0, 1.0, 2.0), DVec3::new(40.0, -3.0, 9.0)),
            (centre, DVec3::new(13.0, 90.0, -20.0)),
            (centre + DVec3::X, centre + DVec3::new(2.0, 1.0, 0.5)),
        ] {
            let (x, y) = (g.paths(a, b), full_paths(&c, a, b));
            for m in 0..MAX_MATERIALS {
                assert!(
                    (x[m] - y[m]).abs() <= 1e-5 * (1.0 + y[m]),
                    "{m}: {x:?} {y:?}"
                );
            }
        }
    }

    #[test]
    fn cells_keep_every_materials_mass() {
        let c = composition();
        for factor in [[2, 2, 2], [3, 1, 4], [5, 4, 3]] {
            let g = DetectionGrid::with_factor(&c, factor).unwrap();
            let fine_dims = c.packed().dims();
            let voxels = |cell: usize| -> f64 {
                let idx = [
                    cell % g.dims[0],
                    (cell / g.dims[0]) % g.dims[1],
                    cell / (g.dims[0] * g.dims[1]),
                ];
                (0..3)
                    .map(|a| {
                        (((idx[a] + 1) * factor[a]).min(fine_dims[a]) - idx[a] * factor[a]) as f64
                    })
                    .product()
            };
            for (k, &m) in g.materials.iter().enumerate() {
                let coarse: f64 = g
                    .densities
                    .chunks(g.lanes)
                    .enumerate()
                    .map(|(cell, d)| f64::from(d[k]) * voxels(cell))
                    .sum();
                let fine: f64 = c
                    .packed()
                    .data()
                    .iter()
                    .map(|&v| unpack(v))
                    .filter(|&(rho, mm)| mm == m && rho > 0.0)
                    .map(|(rho, _)| f64::from(rho))
                    .sum();
                assert!(
                    (coarse - fine).abs() < 1e-4 * fine,
                    "{factor:?} {m}: {coarse} {fine}"
                );
            }
        }
    }

    #[test]
    fn a_path_through_uniform_cells_matches_the_full_resolution() {
        // A uniform block: averaging changes nothing, whatever the factor.
        let dims = [9, 8, 6];
        let vol = |v: f32| {
            Volume::centred(
                dims,
                DVec3::new(2.0, 1.0, 3.0),
                DVec3::ZERO,
                vec![v; 9 * 8 * 6],
            )
            .unwrap()
        };
        let c = Composition::from_labels(&vol(0.0), &vol(1.2), vec!["water".into()]).unwrap();
        let g = DetectionGrid::with_factor(&c, [3, 4, 2]).unwrap();
        let (a, b) = (DVec3::new(-3.0, -30.0, 2.0), DVec3::new(5.0, 30.0, -4.0));
        let (x, y) = (g.paths(a, b)[0], full_paths(&c, a, b)[0]);
        assert!((x - y).abs() < 1e-9 * y && y > 1.0, "{x} {y}");
        let _ = pack(1.0, 0);
    }

    #[test]
    fn bad_cell_sizes_are_refused_by_name() {
        let c = composition();
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = DetectionGrid::new(&c, bad).unwrap_err().to_string();
            assert!(e.contains("detection_cell_mm"), "{e}");
        }
        assert!(DetectionGrid::with_factor(&c, [0, 1, 1]).is_err());
        assert_eq!(DetectionGrid::new(&c, 3.0).unwrap().factor(), [2, 2, 1]);
    }
}
