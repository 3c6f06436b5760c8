//! How mesh objects enter a pixel: inside a mesh the mesh's material replaces the voxels
//! (an implant displaces tissue).
//!
//! For a ray with mesh intervals `I` (sorted, disjoint, each held by one mesh, see
//! [`MeshScene::intervals`]):
//!
//! * **attenuation** — `∫mu ds = Σ_I mu_mesh·|I| + ∫ voxels outside I`;
//! * **composition** — per voxel material `m`: `Σρ_m·ℓ` over the voxels outside `I`; per
//!   mesh material column: `Σ density_mesh·|I|` (g/cm³ · mm).
//!
//! The voxels outside `I` come either from the scalar tracer run over the complement of
//! `I`, or — for rays the SIMD row tracer already took whole — from the whole-ray sums
//! minus a scalar trace of the voxels inside `I` (the same voxels and lengths, so the
//! difference is exact to rounding, ~1e-15 of the line integral; per-material sums are
//! clamped at 0 against that rounding).

use super::{Projector, Renderer, Sums};
use crate::accel::intervals::Interval;
use crate::accel::{siddon_over, trilinear_in, trilinear_materials_in};
use crate::mesh::object::{Scratch, subtract};
use crate::mesh::{MeshInterval, MeshScene};
use crate::ray::GridRay;
use crate::trace::{LineIntegral, MaterialPaths};

impl<S: Sums> Renderer<'_, S> {
    /// ∫mu ds of one pixel: its clipped ray `g` (already traced whole by the packets when
    /// `packet` holds the value; `inside`: the voxels inside the mesh intervals, when also
    /// traced by the packets) and its mesh intervals `iv`.
    pub(super) fn pixel(
        &self,
        packet: Option<f64>,
        inside: Option<f64>,
        g: Option<&GridRay>,
        iv: &[MeshInterval],
    ) -> f64 {
        let Some(m) = self.meshes.as_deref().filter(|_| !iv.is_empty()) else {
            return packet.unwrap_or_else(|| self.clipped_integral(g));
        };
        let mesh = m.mu_integral(iv);
        match (overlap(g, iv), packet) {
            (None, Some(v)) => mesh + v,
            (None, None) => mesh + self.clipped_integral(g),
            (Some(g), Some(v)) => {
                let within = inside.unwrap_or_else(|| {
                    let mut acc = LineIntegral::new(self.mu.data());
                    siddon_over(self.mu.dims(), g, &clipped(g, iv), &mut acc);
                    acc.value()
                });
                mesh + v - within
            }
            (Some(g), None) => mesh + self.voxels_outside(g, iv),
        }
    }

    /// ∫mu ds of the voxels along `g` outside the mesh intervals `iv`.
    fn voxels_outside(&self, g: &GridRay, iv: &[MeshInterval]) -> f64 {
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

    /// Σρ·ℓ per material of one pixel into `out` (voxel materials, then mesh material
    /// columns; g/cm³ · mm): its clipped ray `g` (already traced whole by the packets when
    /// `packet` holds the sums) and its mesh intervals `iv`.
    pub(super) fn pixel_materials(
        &self,
        packet: Option<&[f64]>,
        inside: Option<&[f64]>,
        g: Option<&GridRay>,
        iv: &[MeshInterval],
        out: &mut [f64],
    ) {
        let (voxels, meshes) = out.split_at_mut(self.materials);
        let (field, dims) = (self.mu.data(), self.mu.dims());
        match (overlap(g, iv), packet) {
            (None, Some(v)) => voxels.copy_from_slice(v),
            (None, None) => self.clipped_materials(g, voxels),
            (Some(g), Some(v)) => {
                let mut acc = MaterialPaths::new(field);
                let within = match inside {
                    Some(w) => w,
                    None => {
                        siddon_over(dims, g, &clipped(g, iv), &mut acc);
                        &acc.sums()[..v.len()]
                    }
                };
                for ((o, &whole), &ins) in voxels.iter_mut().zip(v).zip(within) {
                    *o = (whole - ins).max(0.0);
                }
            }
            (Some(g), None) => {
                let base = [Interval {
                    t0: g.t_enter,
                    t1: g.t_exit,
                }];
                let mut keep = Vec::new();
                subtract(&base, iv, &mut keep);
                match self.projector {
                    Projector::Siddon => {
                        let mut acc = MaterialPaths::new(field);
                        siddon_over(dims, g, &keep, &mut acc);
                        voxels.copy_from_slice(&acc.sums()[..voxels.len()]);
                    }
                    Projector::Trilinear { step_voxels } => {
                        voxels.fill(0.0);
                        trilinear_materials_in(field, dims, g, step_voxels, &keep, voxels);
                    }
                }
            }
        }
        meshes.fill(0.0);
        for i in iv {
            let (column, density) = self.mesh_columns[i.mesh];
            meshes[column - self.materials] += density * (i.t1 - i.t0);
        }
    }
}

/// `g` when some mesh interval overlaps its part inside the grid.
fn overlap<'g>(g: Option<&'g GridRay>, iv: &[MeshInterval]) -> Option<&'g GridRay> {
    g.filter(|g| iv.iter().any(|i| i.t1 > g.t_enter && i.t0 < g.t_exit))
}

/// `g` narrowed to its one mesh interval inside the grid (`None`: no or several), for
/// the packet tracer.
pub(super) fn single_inside(g: &GridRay, iv: &[MeshInterval]) -> Option<GridRay> {
    match clipped(g, iv).as_slice() {
        [one] => Some(GridRay {
            t_enter: one.t0,
            t_exit: one.t1,
            ..*g
        }),
        _ => None,
    }
}

/// The mesh intervals clipped to the grid part of `g`.
fn clipped(g: &GridRay, iv: &[MeshInterval]) -> Vec<Interval> {
    iv.iter()
        .map(|i| Interval {
            t0: i.t0.max(g.t_enter),
            t1: i.t1.min(g.t_exit),
        })
        .filter(|i| i.t1 > i.t0)
        .collect()
}

impl MeshScene {
    /// Each ray's intervals inside meshes ([`MeshScene::intervals`]), for a tile of rays.
    pub fn row_intervals(&self, rays: &[crate::ray::Ray]) -> RowIntervals {
        let mut scratch = Scratch::default();
        let mut all = Vec::new();
        let mut ends = Vec::with_capacity(rays.len() + 1);
        ends.push(0);
        for w in rays {
            self.append_intervals(w, &mut scratch, &mut all);
            ends.push(all.len());
        }
        RowIntervals { all, ends }
    }
}

/// The mesh intervals of a tile of rays, flat: ray `i` has `all[ends[i]..ends[i + 1]]`.
pub struct RowIntervals {
    all: Vec<MeshInterval>,
    ends: Vec<usize>,
}

impl RowIntervals {
    /// No intervals for `rays` rays.
    pub fn empty(rays: usize) -> Self {
        Self {
            all: Vec::new(),
            ends: vec![0; rays + 1],
        }
    }

    /// Ray `i`'s intervals.
    pub fn ray(&self, i: usize) -> &[MeshInterval] {
        &self.all[self.ends[i]..self.ends[i + 1]]
    }
}
