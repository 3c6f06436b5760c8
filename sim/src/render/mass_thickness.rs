//! Per-material mass thickness images, the input of polychromatic integration.

use super::{MassThicknesses, Projector, Renderer};
use crate::composition::Composition;
use crate::error::{Result, SimError};
use crate::geometry::View;

/// Per-pixel mass thickness of each material of a [`Composition`]: ∫ρ_m ds in g/cm²,
/// the input of polychromatic integration (`tomograf_physics::polychromatic`).
#[derive(Debug, Clone, PartialEq)]
pub struct MassThickness {
    /// Image height.
    pub rows: usize,
    /// Image width.
    pub cols: usize,
    /// Material names, by index (as in the composition).
    pub materials: Vec<String>,
    /// `materials.len()` values per pixel, pixel-major: material `m` of pixel `(r, c)` at
    /// `(r·cols + c)·materials.len() + m`; g/cm².
    pub data: Vec<f64>,
}

impl MassThickness {
    /// The mass thicknesses (g/cm²) of every material at pixel `(row, col)`.
    pub fn at(&self, row: usize, col: usize) -> &[f64] {
        let k = self.materials.len();
        let p = row * self.cols + col;
        &self.data[p * k..(p + 1) * k]
    }
}

impl<'a> Renderer<'a, MassThicknesses> {
    /// A renderer of per-material mass thickness over `composition`
    /// ([`Renderer::mass_thickness`]). Both projectors apply: exact Siddon over the
    /// nearest-neighbour material grid, and trilinear marching of each material's partial
    /// density field.
    pub fn for_composition(composition: &'a Composition, projector: Projector) -> Result<Self> {
        let mut r = Self::build_with(composition.packed(), projector, || composition.occupied())?;
        r.materials = composition.materials().len();
        // Where the densities are non-zero, row by row, for the sheets to skip zeros.
        if projector == Projector::Siddon {
            r.rows = Some(composition.rows().clone());
        }
        Ok(r)
    }

    /// Per-material mass thickness image of one view (a renderer made with
    /// [`Renderer::for_composition`]).
    pub fn mass_thickness(&self, view: &View, materials: &[String]) -> Result<MassThickness> {
        let k = self.materials + self.mesh_materials;
        if materials.len() != k {
            return Err(SimError::OutOfRange(format!(
                "mass thickness needs a renderer over a composition of {} materials (voxel \
                 materials, then mesh materials); this one has {} + {}",
                materials.len(),
                self.materials,
                self.mesh_materials
            )));
        }
        let mut data = self.trace(view)?;
        // g/cm³ · mm → g/cm².
        data.iter_mut().for_each(|v| *v *= 0.1);
        Ok(MassThickness {
            rows: view.rows,
            cols: view.cols,
            materials: materials.to_vec(),
            data,
        })
    }
}
