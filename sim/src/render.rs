//! Rendering a view: one ray per pixel, traced in parallel (rayon), then turned into the
//! requested quantity.
//!
//! Each pixel is computed independently from the same inputs, so images are bit-identical
//! whatever the number of threads.

use crate::accel::intervals::Interval;
use crate::accel::{EmptySpace, SkipOptions, siddon_over, trilinear_in};
use crate::composition::Composition;
use crate::error::{Result, SimError};
use crate::geometry::View;
use crate::mesh::object::subtract;
use crate::mesh::{MeshInterval, MeshScene};
use crate::ray::{GridBox, GridRay, Ray};
use crate::trace::{LineIntegral, MaterialPaths, packet, siddon, trilinear};
use crate::volume::Volume;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// How a ray is integrated through the volume.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Projector {
    /// Exact: each voxel (nearest-neighbour field) weighted by its exact path length.
    Siddon,
    /// Midpoint-rule ray marching through the trilinearly interpolated field.
    Trilinear {
        /// Distance between samples, in voxels (grid units along the ray); > 0.
        step_voxels: f64,
    },
}

/// What a pixel records.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Quantity {
    /// The line integral L = ∫mu ds (dimensionless).
    LineIntegral,
    /// exp(−L), in [0, 1]; underflows to 0 (never NaN) beyond L ≈ 745.
    Transmission,
    /// I0 · exp(−L).
    Intensity {
        /// Unattenuated intensity (any unit; e.g. photons per pixel).
        i0: f64,
    },
}

impl Quantity {
    /// Converts one line integral.
    #[inline]
    pub fn from_line_integral(&self, l: f64) -> f64 {
        match *self {
            Self::LineIntegral => l,
            Self::Transmission => (-l).exp(),
            Self::Intensity { i0 } => i0 * (-l).exp(),
        }
    }

    /// Checks parameters (I0 finite and > 0).
    pub fn validate(&self) -> Result<()> {
        if let Self::Intensity { i0 } = *self
            && !(i0.is_finite() && i0 > 0.0)
        {
            return Err(SimError::OutOfRange(format!(
                "I0 = {i0}; it must be finite and > 0"
            )));
        }
        Ok(())
    }
}

/// A rendered image: `rows × cols` values, row-major (pixel `(r, c)` at `r·cols + c`),
/// pixel (0, 0) as documented on [`crate::geometry::Detector`].
#[derive(Debug, Clone, PartialEq)]
pub struct Projection {
    /// Image height.
    pub rows: usize,
    /// Image width.
    pub cols: usize,
    /// Pixel values (f32, as written to files).
    pub data: Vec<f32>,
}

impl Projection {
    /// Value at `(row, col)`.
    pub fn at(&self, row: usize, col: usize) -> f32 {
        self.data[row * self.cols + col]
    }

    /// Applies `quantity` to line-integral values.
    pub fn to_quantity(&self, quantity: Quantity) -> Projection {
        Projection {
            rows: self.rows,
            cols: self.cols,
            data: self
                .data
                .iter()
                .map(|&l| quantity.from_line_integral(f64::from(l)) as f32)
                .collect(),
        }
    }
}

/// Per-pixel mass thickness of each material of a [`Composition`]: ∫ρ_m ds in g/cm²,
/// the input of polychromatic integration (`crate::polychromatic`).
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

/// Renders line integrals of an attenuation volume (mm⁻¹), or per-material mass
/// thicknesses of a [`Composition`].
#[derive(Debug, Clone)]
pub struct Renderer<'a> {
    /// mu (mm⁻¹), or a packed composition when `materials > 0`.
    mu: &'a Volume,
    /// Number of materials of a composition; 0 for an attenuation volume.
    materials: usize,
    projector: Projector,
    packet_threshold: f64,
    /// Where rays are clipped: for Siddon the box of non-zero mu (air adds exactly
    /// nothing), for the trilinear field the whole grid (it is non-zero half a voxel
    /// beyond). `None`: nothing to integrate.
    bounds: Option<GridBox>,
    /// Empty-space skipping (see [`crate::accel`]); `None`: off.
    skip: Option<Arc<EmptySpace>>,
    /// Mesh objects in the same rays (see [`crate::mesh`]); `None`: voxels only.
    meshes: Option<Arc<MeshScene>>,
}

impl<'a> Renderer<'a> {
    /// A renderer over `mu` (linear attenuation, mm⁻¹, see [`crate::attenuation`]).
    pub fn new(mu: &'a Volume, projector: Projector) -> Result<Self> {
        let renderer = Self::build(mu, projector)?;
        // Empty-space skipping is on by default where it was measured faster (trilinear:
        // docs/benchmarks.md, "Empty-space skipping"); exact Siddon's row packets gain
        // nothing from it, so it stays opt-in there.
        match projector {
            Projector::Trilinear { .. } => renderer.with_skipping(Some(SkipOptions::default())),
            Projector::Siddon => Ok(renderer),
        }
    }

    /// A renderer over `field` with no skipping and no meshes.
    fn build(mu: &'a Volume, projector: Projector) -> Result<Self> {
        if let Projector::Trilinear { step_voxels } = projector
            && !(step_voxels.is_finite() && step_voxels > 0.0)
        {
            return Err(SimError::OutOfRange(format!(
                "trilinear step is {step_voxels} voxels; it must be finite and > 0"
            )));
        }
        let bounds = match projector {
            Projector::Siddon => mu.occupied(),
            Projector::Trilinear { .. } => Some(GridBox::whole(mu.dims())),
        };
        Ok(Self {
            mu,
            materials: 0,
            projector,
            packet_threshold: packet::default_threshold(),
            bounds,
            skip: None,
            meshes: None,
        })
    }

    /// Adds mesh objects: inside a mesh its `mu_per_mm` replaces the voxels' values (an
    /// implant displaces tissue); every mesh needs an explicit `mu_per_mm`.
    pub fn with_meshes(mut self, meshes: Arc<MeshScene>) -> Result<Self> {
        if self.materials > 0 {
            return Err(SimError::OutOfRange(
                "meshes in a material composition (polychromatic scenes) are not supported yet"
                    .into(),
            ));
        }
        meshes
            .require_mu()
            .map_err(|e| SimError::OutOfRange(e.to_string()))?;
        self.meshes = (!meshes.is_empty()).then_some(meshes);
        Ok(self)
    }

    /// Turns empty-space skipping on (`Some`, building the brick map now) or off
    /// (`None`). Results are unchanged: see [`crate::accel`] for how exact that is.
    pub fn with_skipping(mut self, options: Option<SkipOptions>) -> Result<Self> {
        if self.materials > 0 && options.is_some() {
            return Err(SimError::OutOfRange(
                "empty-space skipping of a material composition is not supported yet".into(),
            ));
        }
        self.skip = match options {
            None => None,
            Some(o) => Some(Arc::new(match self.projector {
                Projector::Siddon => EmptySpace::for_siddon(self.mu, o)?,
                Projector::Trilinear { .. } => EmptySpace::for_trilinear(self.mu, o)?,
            })),
        };
        Ok(self)
    }

    /// A renderer of per-material mass thickness over `composition`
    /// ([`Renderer::mass_thickness`]). Both projectors apply: exact Siddon over the
    /// nearest-neighbour material grid, and trilinear marching of each material's partial
    /// density field.
    pub fn for_composition(composition: &'a Composition, projector: Projector) -> Result<Self> {
        let mut r = Self::build(composition.packed(), projector)?;
        r.materials = composition.materials().len();
        Ok(r)
    }

    /// Sets the crossings per voxel layer from which exact Siddon traces a packet of rays
    /// with the SIMD tracer (default [`packet::default_threshold`]; `f64::INFINITY`
    /// never does). Results agree either way to ~1e-12 relative; this is for tuning.
    pub fn with_packet_threshold(mut self, crossings_per_layer: f64) -> Self {
        self.packet_threshold = crossings_per_layer;
        self
    }

    /// The projector in use.
    pub fn projector(&self) -> Projector {
        self.projector
    }

    /// ∫mu ds along one ray (f64; 0 when the ray misses the volume).
    pub fn line_integral(&self, ray: &Ray) -> f64 {
        let g = self.clip(ray);
        match self.meshes.as_deref() {
            Some(m) => {
                let mut iv = Vec::new();
                m.line_integral(ray, &mut iv) + self.voxels_outside(g.as_ref(), &iv)
            }
            None => self.clipped_integral(g.as_ref()),
        }
    }

    /// Exact-Siddon ∫mu ds of the voxels along `g` inside the mesh intervals `iv`.
    fn voxels_inside(&self, g: Option<&GridRay>, iv: &[MeshInterval]) -> f64 {
        let Some(g) = g else {
            return 0.0;
        };
        let inside: Vec<Interval> = iv
            .iter()
            .map(|i| Interval {
                t0: i.t0.max(g.t_enter),
                t1: i.t1.min(g.t_exit),
            })
            .filter(|i| i.t1 > i.t0)
            .collect();
        let mut acc = LineIntegral::new(self.mu.data());
        siddon_over(self.mu.dims(), g, &inside, &mut acc);
        acc.value()
    }

    /// ∫mu ds of the voxels along `g` outside the mesh intervals `iv`.
    fn voxels_outside(&self, g: Option<&GridRay>, iv: &[MeshInterval]) -> f64 {
        let Some(g) = g else {
            return 0.0;
        };
        if iv.is_empty() {
            return self.clipped_integral(Some(g));
        }
        let mut base = vec![Interval {
            t0: g.t_enter,
            t1: g.t_exit,
        }];
        let mut keep = Vec::new();
        match self.projector {
            Projector::Siddon => {
                if let Some(s) = self.skip.as_deref() {
                    s.intervals(g, &mut base);
                }
                subtract(&base, iv, &mut keep);
                let mut acc = LineIntegral::new(self.mu.data());
                siddon_over(self.mu.dims(), g, &keep, &mut acc);
                acc.value()
            }
            Projector::Trilinear { step_voxels } => {
                subtract(&base, iv, &mut keep);
                trilinear_in(self.mu.data(), self.mu.dims(), g, step_voxels, &keep)
            }
        }
    }

    /// `ray` clipped to the part of the grid this projector integrates.
    fn clip(&self, ray: &Ray) -> Option<GridRay> {
        GridRay::clip_to(self.mu, ray, self.bounds.as_ref()?)
    }

    /// ∫mu ds along a ray already clipped to the grid (`None`: it misses).
    fn clipped_integral(&self, g: Option<&GridRay>) -> f64 {
        let Some(g) = g else {
            return 0.0;
        };
        match (self.projector, self.skip.as_deref()) {
            (Projector::Siddon, skip) => {
                let mut acc = LineIntegral::new(self.mu.data());
                match skip {
                    Some(s) => s.siddon(self.mu.dims(), g, &mut acc),
                    None => siddon::trace(self.mu.dims(), g, &mut acc),
                }
                acc.value()
            }
            (Projector::Trilinear { step_voxels }, Some(s)) => {
                s.trilinear(self.mu.data(), self.mu.dims(), g, step_voxels)
            }
            (Projector::Trilinear { step_voxels }, None) => {
                trilinear::march(self.mu.data(), self.mu.dims(), g, step_voxels)
            }
        }
    }

    /// Line-integral image of one view.
    pub fn render(&self, view: &View) -> Result<Projection> {
        if self.materials > 0 {
            return Err(SimError::OutOfRange(
                "this renderer traces a material composition: ask it for mass_thickness, \
                 not line integrals"
                    .into(),
            ));
        }
        let sums = self.trace(view, 1)?;
        Ok(Projection {
            rows: view.rows,
            cols: view.cols,
            data: sums.into_iter().map(|v| v as f32).collect(),
        })
    }

    /// Per-material mass thickness image of one view (a renderer made with
    /// [`Renderer::for_composition`]).
    pub fn mass_thickness(&self, view: &View, materials: &[String]) -> Result<MassThickness> {
        if self.materials == 0 || materials.len() != self.materials {
            return Err(SimError::OutOfRange(format!(
                "mass thickness needs a renderer over a composition of {} materials; this one \
                 has {}",
                materials.len(),
                self.materials
            )));
        }
        let mut data = self.trace(view, self.materials)?;
        // g/cm³ · mm → g/cm².
        data.iter_mut().for_each(|v| *v *= 0.1);
        Ok(MassThickness {
            rows: view.rows,
            cols: view.cols,
            materials: materials.to_vec(),
            data,
        })
    }

    /// `k` sums per pixel (pixel-major): the line integral (`k` = 1, attenuation) or Σρ·ℓ
    /// per material (g/cm³ · mm, composition).
    fn trace(&self, view: &View, k: usize) -> Result<Vec<f64>> {
        view.validate()?;
        let mut data = vec![0.0f64; view.rows * view.cols * k];
        let packets = self.projector == Projector::Siddon && packet::available();
        let packed = self.materials > 0;
        // The packet tracer takes rows in pairs (see `packet::trace_rows_with`).
        let rows_per_task = if packets { packet::TILE_ROWS } else { 1 };
        data.par_chunks_mut(view.cols * k * rows_per_task)
            .enumerate()
            .for_each(|(task, row)| {
                let first = task * rows_per_task;
                let rows = row.len() / (view.cols * k);
                let world: Vec<Ray> = (first..first + rows)
                    .flat_map(|r| (0..view.cols).map(move |c| view.ray(r as f64, c as f64)))
                    .collect();
                let rays: Vec<Option<GridRay>> = world.iter().map(|w| self.clip(w)).collect();
                // Rays through meshes: the mesh part and its intervals (attenuation only).
                let meshed: Vec<Option<(f64, Vec<MeshInterval>)>> = match self.meshes.as_deref() {
                    Some(m) if !packed => world
                        .iter()
                        .map(|w| {
                            let mut iv = Vec::new();
                            let l = m.line_integral(w, &mut iv);
                            (!iv.is_empty()).then_some((l, iv))
                        })
                        .collect(),
                    _ => vec![None; world.len()],
                };
                let mut handled = vec![false; world.len()];
                if let (true, Some(kernel)) = (packets, packet::kernel()) {
                    // The whole row through the SIMD tracer where its rays allow (it walks
                    // whole layers: empty-space skipping applies to the scalar rays only).
                    let (field, dims, t) = (self.mu.data(), self.mu.dims(), self.packet_threshold);
                    let k = if packed { k } else { 0 };
                    packet::trace_rows_with(
                        kernel,
                        field,
                        dims,
                        &rays,
                        view.cols,
                        t,
                        k,
                        row,
                        &mut handled,
                    );
                }
                for (c, px) in row.chunks_mut(k).enumerate() {
                    if packed {
                        if !handled[c] {
                            self.clipped_materials(rays[c].as_ref(), px);
                        }
                    } else {
                        let packet = handled[c].then_some(px[0]);
                        px[0] = self.pixel(packet, rays[c].as_ref(), meshed[c].as_ref());
                    }
                }
            });
        Ok(data)
    }

    /// ∫mu ds of one pixel: its clipped ray `g` (already traced whole by the packets when
    /// `packet` holds the value) plus the mesh part `mesh` (line integral and intervals).
    /// Inside a mesh the mesh replaces the voxels: the packet value loses the voxels inside
    /// the intervals, or the scalar walk traces only the voxels outside them.
    fn pixel(
        &self,
        packet: Option<f64>,
        g: Option<&GridRay>,
        mesh: Option<&(f64, Vec<MeshInterval>)>,
    ) -> f64 {
        let voxels = || packet.unwrap_or_else(|| self.clipped_integral(g));
        match (mesh, g) {
            (Some((l, iv)), Some(gr))
                if iv.iter().any(|i| i.t1 > gr.t_enter && i.t0 < gr.t_exit) =>
            {
                match packet {
                    Some(v) => l + v - self.voxels_inside(g, iv),
                    None => l + self.voxels_outside(g, iv),
                }
            }
            (Some((l, _)), _) => l + voxels(),
            (None, _) => voxels(),
        }
    }

    /// Σρ·ℓ per material (g/cm³ · mm) along a clipped ray into `out` (zeros when it misses).
    fn clipped_materials(&self, g: Option<&GridRay>, out: &mut [f64]) {
        out.fill(0.0);
        let Some(g) = g else {
            return;
        };
        let (field, dims) = (self.mu.data(), self.mu.dims());
        match self.projector {
            Projector::Siddon => {
                let mut acc = MaterialPaths::new(field);
                siddon::trace(dims, g, &mut acc);
                out.copy_from_slice(&acc.sums()[..out.len()]);
            }
            Projector::Trilinear { step_voxels } => {
                trilinear::march_materials(field, dims, g, step_voxels, out);
            }
        }
    }
}
