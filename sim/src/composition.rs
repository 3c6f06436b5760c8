//! What each voxel is made of: a material index and a density, for polychromatic tracing.
//!
//! A polychromatic projection needs, per ray, the mass thickness of each material
//! (∫ρ_m ds, g/cm²), not one line integral. [`Composition`] stores, per voxel, the index
//! of its material (into a list of at most [`MAX_MATERIALS`]) and its density (g/cm³),
//! *packed into one f32*: the density with the low [`LABEL_BITS`] bits of its mantissa
//! replaced by the material index. One load then gives both, so the exact tracer visits
//! the grid once whatever the number of materials (`sim/src/trace/packet/` gathers one
//! value per segment exactly as for a line integral).
//!
//! The price is precision: the stored density is the given one truncated to 19 mantissa
//! bits, a relative change below 2⁻¹⁹ ≈ 1.9·10⁻⁶ — far below any tabulated attenuation
//! coefficient's uncertainty (~1 %). A density of exactly 0 (vacuum) is stored as 0.0 and
//! adds nothing whatever its label, so empty space stays exactly zero and the tracer's
//! clipping to the occupied box still applies.

use crate::error::{Result, SimError};
use crate::grid_box::GridBox;
use crate::occupancy::RowExtents;
use crate::volume::Volume;
use rayon::prelude::*;
use std::sync::Arc;

/// Bits of an f32 mantissa that carry the material index.
pub const LABEL_BITS: u32 = 4;
/// Most materials one [`Composition`] can hold.
pub const MAX_MATERIALS: usize = 1 << LABEL_BITS;
const LABEL_MASK: u32 = (MAX_MATERIALS as u32) - 1;

/// Packs a density (g/cm³, finite, ≥ 0) and a material index (< [`MAX_MATERIALS`]).
#[inline]
pub fn pack(density_g_cm3: f32, material: usize) -> f32 {
    debug_assert!(material < MAX_MATERIALS);
    if density_g_cm3 <= 0.0 {
        return 0.0;
    }
    f32::from_bits((density_g_cm3.to_bits() & !LABEL_MASK) | material as u32)
}

/// The (density g/cm³, material index) stored in a packed value.
#[inline(always)]
pub fn unpack(value: f32) -> (f32, usize) {
    let bits = value.to_bits();
    (
        f32::from_bits(bits & !LABEL_MASK),
        (bits & LABEL_MASK) as usize,
    )
}

/// Per-voxel material and density on a volume's grid.
///
/// The grid (dims, spacing, origin, direction) is that of the CT it was made from; the
/// values are packed as the module describes. Materials are referred to by name, in the
/// order of their indices; which physical data a name stands for is
/// [`crate::material`]'s business.
#[derive(Debug, Clone)]
pub struct Composition {
    /// Shared: a clone (the scatter medium keeps one) costs no copy of the voxels.
    packed: Arc<Volume>,
    materials: Vec<String>,
    /// Where each row of voxels has non-zero densities, and so the box of voxels with
    /// non-zero density (exact Siddon clips rays to it, the ray sheets skip the zeros),
    /// found once here rather than at every render.
    rows: Arc<RowExtents>,
    occupied: Option<GridBox>,
}

impl Composition {
    /// Builds a composition from a volume's grid and a per-voxel classifier returning
    /// `(density g/cm³, material index)` for a voxel value, evaluated in parallel. Errors
    /// on more than [`MAX_MATERIALS`] materials, an index out of range, or a negative or
    /// non-finite density (naming the voxel).
    pub fn classify(
        grid: &Volume,
        materials: Vec<String>,
        classify: impl Fn(f32) -> (f32, usize) + Sync,
    ) -> Result<Self> {
        let data = grid.data();
        Self::build(grid, materials, |i| classify(data[i]))
    }

    /// From a label volume (material index per voxel, as f32 integers) and a density
    /// volume (g/cm³) on the same grid.
    pub fn from_labels(labels: &Volume, density: &Volume, materials: Vec<String>) -> Result<Self> {
        if labels.dims() != density.dims() {
            return Err(SimError::InvalidVolume(format!(
                "label volume is {:?} voxels but density volume is {:?}",
                labels.dims(),
                density.dims()
            )));
        }
        let (l, d) = (labels.data(), density.data());
        // A non-integer or negative label maps past the end and is reported as out of range.
        Self::build(labels, materials, |i| {
            let ok = l[i].fract() == 0.0 && l[i] >= 0.0;
            (d[i], if ok { l[i] as usize } else { usize::MAX })
        })
    }

    /// Packs `at(voxel)` = (density, material) for every voxel of `grid`.
    fn build(
        grid: &Volume,
        materials: Vec<String>,
        at: impl Fn(usize) -> (f32, usize) + Sync,
    ) -> Result<Self> {
        if materials.is_empty() || materials.len() > MAX_MATERIALS {
            return Err(SimError::OutOfRange(format!(
                "{} materials; a composition holds 1 to {MAX_MATERIALS}",
                materials.len()
            )));
        }
        let n = materials.len();
        let valid = |(rho, m): (f32, usize)| m < n && rho.is_finite() && rho >= 0.0;
        let values: Vec<f32> = (0..grid.len())
            .into_par_iter()
            .map(|i| match at(i) {
                p if valid(p) => pack(p.0, p.1),
                _ => f32::NAN,
            })
            .collect();
        if let Some(bad) = values.iter().position(|v| v.is_nan()) {
            let (rho, m) = at(bad);
            return Err(SimError::OutOfRange(format!(
                "voxel {bad} was given material {} with density {rho} g/cm³; materials are \
                 0..{n} ({}) and densities finite and ≥ 0",
                if m == usize::MAX {
                    "(not a whole number ≥ 0)".to_string()
                } else {
                    m.to_string()
                },
                materials.join(", ")
            )));
        }
        let packed = Volume::new(
            grid.dims(),
            grid.spacing(),
            grid.origin(),
            grid.direction(),
            values,
        )?;
        let rows = RowExtents::of(&packed);
        let occupied = rows.bounding_box();
        Ok(Self {
            packed: Arc::new(packed),
            materials,
            rows: Arc::new(rows),
            occupied,
        })
    }

    /// The smallest box of voxels holding every voxel of non-zero density (`None`: none).
    pub fn occupied(&self) -> Option<GridBox> {
        self.occupied
    }

    /// Where each row of voxels (along i) has non-zero densities.
    pub fn rows(&self) -> &Arc<RowExtents> {
        &self.rows
    }

    /// The packed grid (see the module documentation), for the tracers.
    pub fn packed(&self) -> &Volume {
        &self.packed
    }

    /// Material names, by index.
    pub fn materials(&self) -> &[String] {
        &self.materials
    }

    /// Which material indices occur with a non-zero density (a material absent from the
    /// scene costs nothing downstream).
    pub fn present(&self) -> Vec<bool> {
        let n = self.materials.len();
        self.packed
            .data()
            .par_chunks(1 << 16)
            .map(|c| {
                let mut seen = vec![false; n];
                for &v in c {
                    if v != 0.0 {
                        seen[unpack(v).1] = true;
                    }
                }
                seen
            })
            .reduce(
                || vec![false; n],
                |a, b| a.iter().zip(&b).map(|(x, y)| *x || *y).collect(),
            )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pack_round_trips_label_and_keeps_density_to_2e_6() {
        for &rho in &[1e-3f32, 0.0012, 0.26, 1.0, 1.06, 1.92, 7.9, 19.3] {
            for m in 0..MAX_MATERIALS {
                let (r, l) = unpack(pack(rho, m));
                assert_eq!(l, m);
                assert!(((r - rho) / rho).abs() < 2e-6, "{rho} -> {r}");
            }
        }
        assert_eq!(pack(0.0, 5), 0.0);
        assert_eq!(unpack(0.0), (0.0, 0));
    }
}
