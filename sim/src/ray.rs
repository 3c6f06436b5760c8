//! Rays in the world frame and their clipping to a volume's grid.

use crate::grid_box::GridBox;
use crate::volume::Volume;
use glam::DVec3;

/// A ray `p(t) = origin + t · direction` in world LPS mm, restricted to `t ∈ [t_min, t_max]`.
///
/// `direction` is a unit vector, so `t` is a distance in mm. For cone beam the origin is
/// the X-ray **source** and `t_max` is the distance to the detector pixel centre; for
/// parallel beam the origin is the pixel centre and the ray extends to ±∞.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    /// Start point (world, mm). For cone beam, the source.
    pub origin: DVec3,
    /// Unit direction, pointing from the source towards the detector.
    pub direction: DVec3,
    /// Lower bound of the integration parameter, mm (may be −∞).
    pub t_min: f64,
    /// Upper bound of the integration parameter, mm (may be +∞).
    pub t_max: f64,
}

impl Ray {
    /// The segment from `from` to `to` (e.g. source to pixel centre).
    pub fn segment(from: DVec3, to: DVec3) -> Self {
        let d = to - from;
        let len = d.length();
        Self {
            origin: from,
            direction: d / len,
            t_min: 0.0,
            t_max: len,
        }
    }
}

/// A ray expressed in a volume's grid coordinates (voxel `(i,j,k)` = `[i,i+1)×…`) and
/// clipped to the grid box `[0, n]³`: `g(t) = g0 + t·gd` for `t ∈ [t_enter, t_exit]`,
/// `t` still in world mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridRay {
    /// Grid coordinates at `t = 0`.
    pub g0: [f64; 3],
    /// Grid-coordinate change per mm of `t`.
    pub gd: [f64; 3],
    /// `1 / gd` per axis (±∞ where `gd` is 0).
    pub inv: [f64; 3],
    /// Where the ray enters the box (or its own `t_min`), mm.
    pub t_enter: f64,
    /// Where the ray leaves the box (or its own `t_max`), mm.
    pub t_exit: f64,
}

/// Parameter `t` at which the ray crosses grid plane `plane` of an axis. Every crossing
/// and the box exit are computed with this one expression, so a tracer never steps
/// across a plane "before" the exit that the same plane defines.
#[inline(always)]
pub fn plane_t(plane: f64, g0: f64, inv: f64) -> f64 {
    (plane - g0) * inv
}

impl GridRay {
    /// Transforms `ray` into `volume`'s grid and clips it to the grid box. `None` when the
    /// ray misses the volume or only grazes it with zero length.
    pub fn clip(volume: &Volume, ray: &Ray) -> Option<Self> {
        Self::clip_grid(
            volume.dims(),
            volume.world_to_grid(ray.origin).to_array(),
            volume.world_dir_to_grid(ray.direction).to_array(),
            ray.t_min,
            ray.t_max,
        )
    }

    /// As [`GridRay::clip`], for a ray already in grid coordinates.
    pub fn clip_grid(
        dims: [usize; 3],
        g0: [f64; 3],
        gd: [f64; 3],
        t_min: f64,
        t_max: f64,
    ) -> Option<Self> {
        Self::clip_box(&GridBox::whole(dims), g0, gd, t_min, t_max)
    }

    /// Clips `ray` to a sub-box of `volume`'s grid (e.g. the part holding non-zero values,
    /// [`crate::occupancy::occupied`]).
    pub fn clip_to(volume: &Volume, ray: &Ray, bounds: &GridBox) -> Option<Self> {
        Self::clip_box(
            bounds,
            volume.world_to_grid(ray.origin).to_array(),
            volume.world_dir_to_grid(ray.direction).to_array(),
            ray.t_min,
            ray.t_max,
        )
    }

    /// As [`GridRay::clip_grid`], clipping to the grid-coordinate box `[lo, hi)`.
    pub fn clip_box(
        bounds: &GridBox,
        g0: [f64; 3],
        gd: [f64; 3],
        t_min: f64,
        t_max: f64,
    ) -> Option<Self> {
        let mut t_enter = t_min;
        let mut t_exit = t_max;
        let mut inv = [f64::INFINITY; 3];
        let mut gd = gd;
        for a in 0..3 {
            // A subnormal component would overflow 1/gd; such a ray is parallel to the
            // planes for any volume that fits in memory.
            if gd[a].abs() < 1e-300 {
                gd[a] = 0.0;
            }
            let (b_lo, b_hi) = (bounds.lo[a] as f64, bounds.hi[a] as f64);
            if gd[a] == 0.0 {
                // Parallel to this axis' planes: inside iff the (constant) coordinate is in
                // the half-open range [lo, hi) — the same convention voxels use.
                if !(g0[a] >= b_lo && g0[a] < b_hi) {
                    return None;
                }
                continue;
            }
            inv[a] = 1.0 / gd[a];
            let (lo, hi) = if gd[a] > 0.0 {
                (b_lo, b_hi)
            } else {
                (b_hi, b_lo)
            };
            t_enter = t_enter.max(plane_t(lo, g0[a], inv[a]));
            t_exit = t_exit.min(plane_t(hi, g0[a], inv[a]));
        }
        (t_exit > t_enter && t_enter.is_finite() && t_exit.is_finite()).then_some(Self {
            g0,
            gd,
            inv,
            t_enter,
            t_exit,
        })
    }

    /// Grid point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f64) -> [f64; 3] {
        [
            self.g0[0] + t * self.gd[0],
            self.g0[1] + t * self.gd[1],
            self.g0[2] + t * self.gd[2],
        ]
    }

    /// The axis along which the ray advances fastest in grid units (largest |gd|); the
    /// exact tracers walk whole slabs along it.
    #[inline]
    pub fn dominant_axis(&self) -> usize {
        let a = self.gd.map(f64::abs);
        if a[0] >= a[1] && a[0] >= a[2] {
            0
        } else if a[1] >= a[2] {
            1
        } else {
            2
        }
    }

    /// Length of the clipped ray inside the box, mm.
    pub fn length(&self) -> f64 {
        self.t_exit - self.t_enter
    }
}
