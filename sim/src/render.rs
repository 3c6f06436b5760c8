//! Rendering a view: one ray per pixel, traced in parallel (rayon), then turned into the
//! requested quantity.
//!
//! Each pixel is computed independently from the same inputs, so images are bit-identical
//! whatever the number of threads.

use crate::accel::intervals::Interval;
use crate::accel::{EmptySpace, SkipOptions, siddon_over, trilinear_in};
use crate::error::{Result, SimError};
use crate::geometry::View;
use crate::mesh::object::subtract;
use crate::mesh::{MeshInterval, MeshScene};
use crate::ray::{GridBox, GridRay, Ray};
use crate::trace::{LineIntegral, packet, siddon, trilinear};
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

/// Renders line integrals of an attenuation volume (mm⁻¹).
#[derive(Debug, Clone)]
pub struct Renderer<'a> {
    mu: &'a Volume,
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
        let renderer = Self {
            mu,
            projector,
            packet_threshold: packet::default_threshold(),
            bounds,
            skip: None,
            meshes: None,
        };
        // Empty-space skipping is on by default where it was measured faster (trilinear:
        // docs/benchmarks.md, "Empty-space skipping"); exact Siddon's row packets gain
        // nothing from it, so it stays opt-in there.
        match projector {
            Projector::Trilinear { .. } => renderer.with_skipping(Some(SkipOptions::default())),
            Projector::Siddon => Ok(renderer),
        }
    }

    /// Adds mesh objects: inside a mesh its `mu_per_mm` replaces the voxels' values (an
    /// implant displaces tissue); every mesh needs an explicit `mu_per_mm`.
    pub fn with_meshes(mut self, meshes: Arc<MeshScene>) -> Result<Self> {
        meshes
            .require_mu()
            .map_err(|e| SimError::OutOfRange(e.to_string()))?;
        self.meshes = (!meshes.is_empty()).then_some(meshes);
        Ok(self)
    }

    /// Turns empty-space skipping on (`Some`, building the brick map now) or off
    /// (`None`). Results are unchanged: see [`crate::accel`] for how exact that is.
    pub fn with_skipping(mut self, options: Option<SkipOptions>) -> Result<Self> {
        self.skip = match options {
            None => None,
            Some(o) => Some(Arc::new(match self.projector {
                Projector::Siddon => EmptySpace::for_siddon(self.mu, o)?,
                Projector::Trilinear { .. } => EmptySpace::for_trilinear(self.mu, o)?,
            })),
        };
        Ok(self)
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
        view.validate()?;
        let mut data = vec![0.0f32; view.rows * view.cols];
        let packets = self.projector == Projector::Siddon && packet::available();
        data.par_chunks_mut(view.cols)
            .enumerate()
            .for_each(|(r, row)| {
                let r = r as f64;
                let world: Vec<Ray> = (0..row.len()).map(|c| view.ray(r, c as f64)).collect();
                let rays: Vec<Option<GridRay>> = world.iter().map(|w| self.clip(w)).collect();
                // Rays through meshes: the mesh part, and the voxels outside it (scalar).
                let meshed: Vec<Option<(f64, Vec<MeshInterval>)>> = match self.meshes.as_deref() {
                    Some(m) => world
                        .iter()
                        .map(|w| {
                            let mut iv = Vec::new();
                            let l = m.line_integral(w, &mut iv);
                            (!iv.is_empty()).then_some((l, iv))
                        })
                        .collect(),
                    None => vec![None; row.len()],
                };
                // Rays whose mesh intervals overlap their voxel part: traced whole by the
                // packets, then the voxels inside the meshes are subtracted (Siddon over
                // those intervals only); the scalar path traces the complement instead.
                let overlap: Vec<bool> = rays
                    .iter()
                    .zip(&meshed)
                    .map(|(g, m)| match (g, m) {
                        (Some(g), Some((_, iv))) => {
                            iv.iter().any(|i| i.t1 > g.t_enter && i.t0 < g.t_exit)
                        }
                        _ => false,
                    })
                    .collect();
                let mut values = vec![0.0f64; row.len()];
                let mut handled = vec![false; row.len()];
                if packets {
                    // The whole row through the SIMD tracer where its rays allow (it walks
                    // whole layers: empty-space skipping applies to the scalar rays only).
                    packet::trace_row(
                        self.mu.data(),
                        self.mu.dims(),
                        &rays,
                        self.packet_threshold,
                        &mut values,
                        &mut handled,
                    );
                }
                for (c, px) in row.iter_mut().enumerate() {
                    let mesh_part = meshed[c].as_ref().map_or(0.0, |m| m.0);
                    let v = if let (true, Some((l, iv))) = (overlap[c], &meshed[c]) {
                        if handled[c] {
                            l + values[c] - self.voxels_inside(rays[c].as_ref(), iv)
                        } else {
                            l + self.voxels_outside(rays[c].as_ref(), iv)
                        }
                    } else if handled[c] {
                        mesh_part + values[c]
                    } else {
                        mesh_part + self.clipped_integral(rays[c].as_ref())
                    };
                    *px = v as f32;
                }
            });
        Ok(Projection {
            rows: view.rows,
            cols: view.cols,
            data,
        })
    }
}
