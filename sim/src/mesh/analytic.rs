//! Analytic solids — box, ellipsoid (a sphere is one), finite cylinder — whose ray
//! intervals are computed in closed form instead of from triangles, so a cylinder has no
//! facets (a 64-sided mesh cylinder is 0.11 % short through its centre) and costs nothing
//! to set up.
//!
//! Each primitive lives in its own frame, centred on the origin (a cylinder's axis along
//! local z), and is placed in the world (LPS, mm) by an affine [`super::Placement`]. A ray
//! `o + t·d` is mapped into the local frame as `A⁻¹(o − b) + t·A⁻¹d` — the same `t`, since
//! the map is affine — so the world interval is the local one, with no rescaling. The
//! quadratic's discriminant is formed from the line's closest point to the centre (no
//! cancellation for central rays); a ray that only touches the surface (Δ ≤ 0) or runs
//! along a flat face has an empty interval, which is its exact length.

use super::{MeshError, Result};
use crate::ray::Ray;
use glam::{DMat3, DMat4, DVec3};

/// A solid in its own frame (mm), centred on the origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Primitive {
    /// An axis-aligned box of edge lengths `size` (mm).
    Box {
        /// Edge lengths along local x, y, z, mm.
        size: DVec3,
    },
    /// An ellipsoid of semi-axes `radii` (mm) along local x, y, z; a sphere when equal.
    Ellipsoid {
        /// Semi-axes, mm.
        radii: DVec3,
    },
    /// A closed circular cylinder of `radius` (mm) and `height` (mm) along local z.
    Cylinder {
        /// Radius, mm.
        radius: f64,
        /// Length along the axis, mm.
        height: f64,
    },
}

impl Primitive {
    /// Checks that every size is finite and > 0.
    pub fn validate(&self) -> Result<()> {
        let sizes: Vec<(&str, f64)> = match *self {
            Self::Box { size } => vec![("size x", size.x), ("size y", size.y), ("size z", size.z)],
            Self::Ellipsoid { radii } => {
                vec![
                    ("radius x", radii.x),
                    ("radius y", radii.y),
                    ("radius z", radii.z),
                ]
            }
            Self::Cylinder { radius, height } => vec![("radius", radius), ("height", height)],
        };
        for (what, v) in sizes {
            if !(v.is_finite() && v > 0.0) {
                return Err(MeshError::OutOfRange(format!(
                    "{} {what} is {v} mm; it must be finite and > 0",
                    self.kind()
                )));
            }
        }
        Ok(())
    }

    /// The primitive's name (`box`, `ellipsoid`, `cylinder`).
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Box { .. } => "box",
            Self::Ellipsoid { .. } => "ellipsoid",
            Self::Cylinder { .. } => "cylinder",
        }
    }

    /// Volume in the local frame, mm³.
    pub fn volume_mm3(&self) -> f64 {
        match *self {
            Self::Box { size } => size.x * size.y * size.z,
            Self::Ellipsoid { radii } => {
                4.0 / 3.0 * std::f64::consts::PI * radii.x * radii.y * radii.z
            }
            Self::Cylinder { radius, height } => std::f64::consts::PI * radius * radius * height,
        }
    }

    /// Half-extents of the local bounding box, mm.
    fn half_extent(&self) -> DVec3 {
        match *self {
            Self::Box { size } => size * 0.5,
            Self::Ellipsoid { radii } => radii,
            Self::Cylinder { radius, height } => DVec3::new(radius, radius, height * 0.5),
        }
    }

    /// The parameter interval `(t0, t1)` of the line `o + t·d` (local frame) inside the
    /// solid, or `None` when it misses or only touches it.
    pub fn span(&self, o: DVec3, d: DVec3) -> Option<(f64, f64)> {
        match *self {
            Self::Box { size } => slab(o, d, size * 0.5, [true; 3]),
            Self::Ellipsoid { radii } => unit_quadric(o / radii, d / radii, [true, true, true]),
            Self::Cylinder { radius, height } => {
                let (a, b) = unit_quadric(o / radius, d / radius, [true, true, false])?;
                let h = DVec3::new(f64::INFINITY, f64::INFINITY, height * 0.5);
                let (c, e) = slab(o, d, h, [false, false, true])?;
                let (t0, t1) = (a.max(c), b.min(e));
                (t1 > t0).then_some((t0, t1))
            }
        }
    }
}

/// The line `o + t·d` inside `|x_a| ≤ h_a` for the axes in `use_axis`.
fn slab(o: DVec3, d: DVec3, h: DVec3, use_axis: [bool; 3]) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for a in (0..3).filter(|&a| use_axis[a]) {
        if d[a] == 0.0 {
            if o[a].abs() >= h[a] {
                return None;
            }
            continue;
        }
        let (p, q) = ((-h[a] - o[a]) / d[a], (h[a] - o[a]) / d[a]);
        t0 = t0.max(p.min(q));
        t1 = t1.min(p.max(q));
    }
    (t1 > t0).then_some((t0, t1))
}

/// The line `o + t·d` inside `Σ x_a² ≤ 1` over the axes in `use_axis` (the unit sphere, or
/// the unit infinite cylinder about z).
fn unit_quadric(o: DVec3, d: DVec3, use_axis: [bool; 3]) -> Option<(f64, f64)> {
    let m = DVec3::new(
        f64::from(u8::from(use_axis[0])),
        f64::from(u8::from(use_axis[1])),
        f64::from(u8::from(use_axis[2])),
    );
    let (o, d) = (o * m, d * m);
    let alpha = d.dot(d);
    let c = o.dot(o) - 1.0;
    if alpha == 0.0 {
        // Parallel to the cylinder's axis: inside everywhere or nowhere.
        return (c < 0.0).then_some((f64::NEG_INFINITY, f64::INFINITY));
    }
    // Roots t = (−β ± √Δ)/α with Δ = β² − αc = α(1 − |p|²), p the line's closest point
    // to the axis or centre: written through p, Δ does not cancel for a line near the
    // centre, and the chord 2√Δ/α is exact to rounding.
    let beta = o.dot(d);
    let mid = -beta / alpha;
    let p = o + d * mid;
    let delta = alpha * (1.0 - p.dot(p));
    if delta.is_nan() || delta <= 0.0 {
        return None;
    }
    let half = delta.sqrt() / alpha;
    Some((mid - half, mid + half))
}

/// A primitive placed in the world by an affine map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlacedPrimitive {
    /// The solid in its own frame.
    pub primitive: Primitive,
    /// World → local: the inverse of the placement's linear part.
    to_local: DMat3,
    /// The placement's translation (world position of the local origin), mm.
    centre: DVec3,
    /// World bounding box, mm.
    lo: DVec3,
    hi: DVec3,
    /// |det| of the placement's linear part (local → world volume factor).
    det: f64,
}

impl PlacedPrimitive {
    /// `primitive` moved by the affine `placement` (from [`super::Placement::matrix`]).
    pub fn new(primitive: Primitive, placement: DMat4) -> Result<Self> {
        primitive.validate()?;
        let linear = DMat3::from_mat4(placement);
        let det = linear.determinant();
        let centre = placement.w_axis.truncate();
        // The world box of the local box: |A|·h about the centre (exact for a box, a
        // bound for the round solids).
        let h = primitive.half_extent();
        let abs = DMat3::from_cols(
            linear.x_axis.abs(),
            linear.y_axis.abs(),
            linear.z_axis.abs(),
        );
        let reach = abs * h;
        Ok(Self {
            primitive,
            to_local: linear.inverse(),
            centre,
            lo: centre - reach,
            hi: centre + reach,
            det: det.abs(),
        })
    }

    /// World bounding box, mm.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        (self.lo, self.hi)
    }

    /// Enclosed volume, mm³.
    pub fn volume_mm3(&self) -> f64 {
        self.primitive.volume_mm3() * self.det
    }

    /// Where the whole line of `ray` enters and leaves the solid (`t`, mm; unclipped),
    /// or `None` when it misses or only touches it.
    pub fn span(&self, ray: &Ray) -> Option<(f64, f64)> {
        let o = self.to_local * (ray.origin - self.centre);
        let d = self.to_local * ray.direction;
        self.primitive.span(o, d)
    }
}
