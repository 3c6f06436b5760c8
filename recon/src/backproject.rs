//! The Siddon projector as a linear operator `A` and its exact adjoint `Aᵀ`.
//!
//! `A` maps a volume `x` (one value per voxel of a template grid) to one line integral per
//! detector pixel: `(Ax)_ray = Σ_voxels x_v · l(ray, v)`, with `l` the exact path lengths
//! (mm) that [`tomograf_sim::trace::siddon`] reports. `Aᵀ` spreads each pixel value `y_ray` along
//! **the same** `(voxel, length)` segments: `(Aᵀy)_v = Σ_rays y_ray · l(ray, v)`. Both use
//! the same clipped rays and the same tracer, so `⟨Ax, y⟩ = ⟨x, Aᵀy⟩` holds up to the
//! order of f64 additions (tested to 1e-10 relative).
//!
//! # Parallelism and determinism
//! The forward projection computes each pixel independently (rayon over detector rows).
//! The adjoint splits the volume into slabs of whole k-slices; each slab task walks every
//! ray that can reach it and keeps only the segments inside its slab, so no two tasks
//! write the same voxel. Every voxel therefore receives its contributions in one fixed
//! order — views in the order given, pixels row-major, segments along the ray — and the
//! result is bit-identical whatever the number of threads or slabs.
//!
//! Rays are clipped to the **whole** template grid (not to the non-zero part of a volume,
//! as [`tomograf_sim::render::Renderer`] does), so the operator does not depend on `x`.

use rayon::prelude::*;
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::geometry::View;
use tomograf_sim::ray::GridRay;
use tomograf_sim::render::Projection;
use tomograf_sim::trace::{LineIntegral, PathAccumulator, siddon};
use tomograf_sim::volume::Volume;

/// The Siddon projection operator for a set of views on a template grid.
#[derive(Debug, Clone, Copy)]
pub struct SiddonOperator<'a> {
    grid: &'a Volume,
    views: &'a [View],
}

/// A ray clipped to the grid and the k-slices (grid units) it can touch.
#[derive(Debug, Clone, Copy)]
struct SlabRay {
    ray: GridRay,
    k_lo: usize,
    k_hi: usize,
}

impl<'a> SiddonOperator<'a> {
    /// The operator for `views` on the grid of `template` (dims, spacing, origin,
    /// direction; its values are not used). Errors if a view is invalid or there are none.
    pub fn new(template: &'a Volume, views: &'a [View]) -> Result<Self> {
        if views.is_empty() {
            return Err(SimError::InvalidGeometry(
                "no views: the projection operator needs at least one".into(),
            ));
        }
        for v in views {
            v.validate()?;
        }
        Ok(Self {
            grid: template,
            views,
        })
    }

    /// The views, in order.
    pub fn views(&self) -> &[View] {
        self.views
    }

    /// The template grid.
    pub fn grid(&self) -> &Volume {
        self.grid
    }

    /// Pixels of view `v` (rows × cols).
    pub fn pixels(&self, v: usize) -> usize {
        self.views[v].rows * self.views[v].cols
    }

    fn clip(&self, view: &View, r: usize, c: usize) -> Option<GridRay> {
        GridRay::clip(self.grid, &view.ray(r as f64, c as f64))
    }

    /// `A x` for view `v`: f64 line integrals (dimensionless for `x` in mm⁻¹), row-major.
    /// `x` holds one value per voxel of the template, in its layout.
    ///
    /// # Panics
    /// If `x.len()` is not the template's voxel count (a programming error).
    pub fn forward_view(&self, x: &[f32], v: usize) -> Vec<f64> {
        assert_eq!(
            x.len(),
            self.grid.len(),
            "volume size differs from the grid"
        );
        let view = &self.views[v];
        let dims = self.grid.dims();
        let mut out = vec![0.0f64; view.rows * view.cols];
        out.par_chunks_mut(view.cols)
            .enumerate()
            .for_each(|(r, row)| {
                for (c, px) in row.iter_mut().enumerate() {
                    if let Some(g) = self.clip(view, r, c) {
                        let mut acc = LineIntegral::new(x);
                        siddon::trace(dims, &g, &mut acc);
                        *px = acc.value();
                    }
                }
            });
        out
    }

    /// Length (mm) of every ray of view `v` inside the grid: `A·1`, the row sums of `A`.
    pub fn ray_lengths(&self, v: usize) -> Vec<f64> {
        let ones = vec![1.0f32; self.grid.len()];
        self.forward_view(&ones, v)
    }

    /// Clipped rays of view `v`, with the k-slices each may reach (one slice of margin
    /// either side, so a rounding-sized sliver is never skipped).
    fn slab_rays(&self, v: usize) -> Vec<Option<SlabRay>> {
        let view = &self.views[v];
        let nz = self.grid.dims()[2];
        (0..view.rows * view.cols)
            .into_par_iter()
            .map(|p| {
                let ray = self.clip(view, p / view.cols, p % view.cols)?;
                let (a, b) = (ray.at(ray.t_enter)[2], ray.at(ray.t_exit)[2]);
                let lo = (a.min(b).floor() - 1.0).max(0.0) as usize;
                let hi = ((a.max(b).ceil() + 1.0).max(0.0) as usize).min(nz);
                Some(SlabRay {
                    ray,
                    k_lo: lo,
                    k_hi: hi,
                })
            })
            .collect()
    }

    /// Adds `Aᵀ y` over the views `subset` to `out` (one f64 per voxel, template layout):
    /// `images[m]` holds view `subset[m]`'s pixel values, row-major. When `weights_out` is
    /// given, the backprojection of ones (the column sums of `A` restricted to the subset,
    /// in mm) is added to it in the same pass. Pixels whose value is 0 still count in
    /// `weights_out`.
    ///
    /// # Panics
    /// If sizes disagree (a programming error): `images.len() != subset.len()`, an image of
    /// the wrong size, or `out` / `weights_out` not one value per voxel.
    pub fn adjoint_into(
        &self,
        subset: &[usize],
        images: &[&[f64]],
        out: &mut [f64],
        mut weights_out: Option<&mut [f64]>,
    ) {
        assert_eq!(subset.len(), images.len(), "one image per view");
        assert_eq!(
            out.len(),
            self.grid.len(),
            "output size differs from the grid"
        );
        if let Some(w) = &weights_out {
            assert_eq!(
                w.len(),
                self.grid.len(),
                "weights size differs from the grid"
            );
        }
        for (&v, img) in subset.iter().zip(images) {
            assert_eq!(
                img.len(),
                self.pixels(v),
                "image size differs from view {v}"
            );
        }
        let [nx, ny, nz] = self.grid.dims();
        let slice = nx * ny;
        let dims = self.grid.dims();
        // Slabs of whole k-slices; the result does not depend on their thickness.
        let thick = nz.div_ceil(2 * rayon::current_num_threads()).max(1);
        // Views in batches, so that only a few views' rays are held at once.
        for batch in (0..subset.len()).collect::<Vec<_>>().chunks(8) {
            let rays: Vec<Vec<Option<SlabRay>>> =
                batch.iter().map(|&m| self.slab_rays(subset[m])).collect();
            let work = |(s, (slab, mut wslab)): (usize, (&mut [f64], Option<&mut [f64]>))| {
                let (k0, k1) = (s * thick, s * thick + slab.len() / slice);
                for (b, &m) in batch.iter().enumerate() {
                    let img = images[m];
                    for (p, r) in rays[b].iter().enumerate() {
                        let Some(r) = r else { continue };
                        if r.k_hi <= k0 || r.k_lo >= k1 {
                            continue;
                        }
                        let y = img[p];
                        if let Some(w) = wslab.as_deref_mut() {
                            let mut acc = SlabAdd2 {
                                out: &mut *slab,
                                weights: w,
                                lo: k0 * slice,
                                y,
                            };
                            siddon::trace(dims, &r.ray, &mut acc);
                        } else if y != 0.0 {
                            let mut acc = SlabAdd {
                                out: &mut *slab,
                                lo: k0 * slice,
                                y,
                            };
                            siddon::trace(dims, &r.ray, &mut acc);
                        }
                    }
                }
            };
            match weights_out.as_deref_mut() {
                Some(w) => out
                    .par_chunks_mut(thick * slice)
                    .zip(w.par_chunks_mut(thick * slice))
                    .map(|(a, b)| (a, Some(b)))
                    .enumerate()
                    .for_each(work),
                None => out
                    .par_chunks_mut(thick * slice)
                    .map(|a| (a, None))
                    .enumerate()
                    .for_each(work),
            }
        }
    }

    /// `Aᵀ y` over all views: `images[v]` is view `v`'s image; one f64 per voxel.
    pub fn adjoint(&self, images: &[&[f64]]) -> Vec<f64> {
        let mut out = vec![0.0; self.grid.len()];
        let all: Vec<usize> = (0..self.views.len()).collect();
        self.adjoint_into(&all, images, &mut out, None);
        out
    }
}

/// Adds `y · length` to the voxels of one slab (linear indices `lo..lo + out.len()`);
/// segments outside the slab belong to another task and are skipped.
struct SlabAdd<'s> {
    out: &'s mut [f64],
    lo: usize,
    y: f64,
}

impl PathAccumulator for SlabAdd<'_> {
    #[inline(always)]
    fn segment(&mut self, voxel: usize, length_mm: f64) {
        if let Some(o) = self.out.get_mut(voxel.wrapping_sub(self.lo)) {
            *o += self.y * length_mm;
        }
    }
}

/// As [`SlabAdd`], also adding the bare length to `weights` (backprojection of ones).
struct SlabAdd2<'s> {
    out: &'s mut [f64],
    weights: &'s mut [f64],
    lo: usize,
    y: f64,
}

impl PathAccumulator for SlabAdd2<'_> {
    #[inline(always)]
    fn segment(&mut self, voxel: usize, length_mm: f64) {
        let i = voxel.wrapping_sub(self.lo);
        if i < self.out.len() {
            self.out[i] += self.y * length_mm;
            self.weights[i] += length_mm;
        }
    }
}

/// Line-integral images of `volume` (mm⁻¹) in `views` with the exact Siddon operator on
/// the volume's own grid (f32 images of f64 sums). Equal to [`tomograf_sim::render::Renderer`]
/// with [`tomograf_sim::render::Projector::Siddon`] up to the rounding of f64 additions.
pub fn forward_project(volume: &Volume, views: &[View]) -> Result<Vec<Projection>> {
    let op = SiddonOperator::new(volume, views)?;
    Ok((0..views.len())
        .map(|v| Projection {
            rows: views[v].rows,
            cols: views[v].cols,
            data: op
                .forward_view(volume.data(), v)
                .into_iter()
                .map(|x| x as f32)
                .collect(),
        })
        .collect())
}

/// Unfiltered backprojection `Aᵀ y` of line-integral images onto the grid of `template`:
/// each pixel's value spread along its Siddon path, weighted by the path length in each
/// voxel (result in mm per unit of the images). The exact adjoint of [`forward_project`].
pub fn backproject(images: &[Projection], views: &[View], template: &Volume) -> Result<Volume> {
    super::check_projections(images, views)?;
    let op = SiddonOperator::new(template, views)?;
    let ys: Vec<Vec<f64>> = images
        .iter()
        .map(|p| p.data.iter().map(|&x| f64::from(x)).collect())
        .collect();
    let refs: Vec<&[f64]> = ys.iter().map(Vec::as_slice).collect();
    let out = op.adjoint(&refs);
    super::on_grid(template, out.into_iter().map(|x| x as f32).collect())
}
