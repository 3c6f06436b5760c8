//! A smooth random deformation of a phantom: anatomy its generator cannot draw.
//!
//! The generator's organs keep their shapes from patient to patient (a rib cage of regular
//! ribs, a straight spine, a heart of one form, lungs of one outline); a prior trained on
//! them learns those shapes, and a real chest breaks them everywhere by a centimetre or two.
//! [`AnatomySpec::deform_mm`](super::AnatomySpec::deform_mm) warps the rendered phantom by
//! a displacement field whose three components are independent value noise
//! ([`super::heterogeneity::value_noise_on`]: standard normal deviates on a lattice of
//! [`CELL_MM`], counter-based, blended trilinearly), each of standard deviation `deform_mm`:
//! output voxel centre `q` (world mm) takes the rendered volume's value at `q + d(q)`,
//! trilinearly (labels: the nearest voxel's), the grid's edge value beyond it. With
//! displacements of ~1 cm on a 64 mm lattice the warp stays smooth and invertible (its
//! gradient is ~0.2) and keeps each tissue's share of the volume to a few per cent. Every
//! voxel is one fixed sequence of operations: the same bytes on any thread count.

use super::heterogeneity::value_noise_on;
use super::raster::Grid;
use super::tissue::mix64;
use glam::DVec3;
use rayon::prelude::*;

/// Lattice spacing of the displacement field, mm: organ-sized (a heart is ~120 mm across).
pub const CELL_MM: f64 = 64.0;

/// The largest displacement standard deviation accepted, mm.
pub const MAX_DEFORM_MM: f64 = 30.0;

/// The displacement (mm) at world position `p` of the field of `seed` with standard
/// deviation `sd_mm` per component.
pub fn displacement(seed: u64, p: DVec3, sd_mm: f64) -> DVec3 {
    let c = |axis: u64| {
        f64::from(value_noise_on(
            mix64(seed ^ (0x4445_464F_524D + axis)),
            p,
            CELL_MM,
        ))
    };
    DVec3::new(c(0), c(1), c(2)) * sd_mm
}

/// Where each output voxel of `grid` reads from under the field of `seed` and `sd_mm`, in
/// voxel index coordinates: computed once, shared by the values' and the labels' warps.
pub(crate) fn sources(grid: &Grid, seed: u64, sd_mm: f64) -> Vec<DVec3> {
    let [nx, ny, nz] = grid.dims;
    (0..nx * ny * nz)
        .into_par_iter()
        .map(|idx| {
            let (i, j, k) = (idx % nx, (idx / nx) % ny, idx / (nx * ny));
            let q = DVec3::new(grid.coord(0, i), grid.coord(1, j), grid.coord(2, k));
            let p = q + displacement(seed, q, sd_mm);
            (p - grid.origin) / grid.spacing
        })
        .collect()
}

/// `data` (on `grid`, x fastest) read at `sources` ([`sources`]): trilinear, clamped to the
/// grid's edge.
pub(crate) fn warp_values(grid: &Grid, data: &[f32], sources: &[DVec3]) -> Vec<f32> {
    let [nx, ny, nz] = grid.dims;
    let at = |i: usize, j: usize, k: usize| data[i + nx * (j + ny * k)];
    sources
        .par_iter()
        .map(|s| {
            let axis = |v: f64, n: usize| {
                let v = v.clamp(0.0, (n - 1) as f64);
                let lo = (v.floor() as usize).min(n.saturating_sub(2));
                let hi = (lo + 1).min(n - 1);
                (lo, hi, v - lo as f64)
            };
            let ((i0, i1, wx), (j0, j1, wy), (k0, k1, wz)) =
                (axis(s.x, nx), axis(s.y, ny), axis(s.z, nz));
            let lerp = |a: f32, b: f32, w: f64| f64::from(a) + (f64::from(b) - f64::from(a)) * w;
            let plane = |k: usize| {
                let a = lerp(at(i0, j0, k), at(i1, j0, k), wx);
                let b = lerp(at(i0, j1, k), at(i1, j1, k), wx);
                a + (b - a) * wy
            };
            let (a, b) = (plane(k0), plane(k1));
            (a + (b - a) * wz) as f32
        })
        .collect()
}

/// Labels (on `grid`) read at `sources`: the nearest voxel's, clamped to the grid's edge.
pub(crate) fn warp_labels(grid: &Grid, labels: &[u8], sources: &[DVec3]) -> Vec<u8> {
    let [nx, ny, nz] = grid.dims;
    sources
        .par_iter()
        .map(|s| {
            let near = |v: f64, n: usize| (v.round().clamp(0.0, (n - 1) as f64)) as usize;
            labels[near(s.x, nx) + nx * (near(s.y, ny) + ny * near(s.z, nz))]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A zero field is the identity, and the field's spread is the asked one.
    #[test]
    fn the_field_has_the_asked_spread_and_zero_is_the_identity() {
        let grid = Grid::centred([6, 5, 4], DVec3::new(2.0, 3.0, 4.0));
        let data: Vec<f32> = (0..120).map(|v| v as f32 * 1.5 - 40.0).collect();
        let zero = sources(&grid, 3, 0.0);
        assert_eq!(warp_values(&grid, &data, &zero), data);
        let labels: Vec<u8> = (0..120).map(|v| (v % 7) as u8).collect();
        assert_eq!(warp_labels(&grid, &labels, &zero), labels);
        let (mut s2, n) = (0.0f64, 20_000);
        for i in 0..n {
            let f = i as f64;
            let p = DVec3::new(f * 3.71 % 997.0, f * 1.37 % 613.0, f * 0.113);
            s2 += displacement(9, p, 10.0).length_squared();
        }
        let sd = (s2 / (3 * n) as f64).sqrt();
        assert!((sd - 10.0).abs() < 1.0, "{sd}");
    }
}
