//! Analytic solids — box, ellipsoid (a sphere is one), finite elliptic cylinder (a circular
//! one is one) — with their chords in closed form, containment, bounds and volume. The one
//! definition behind every analytic shape of the project: the built-in thorax
//! ([`crate::phantom`]), the exact mesh primitives ([`crate::mesh`]), the scatter scoring
//! regions (tomograf-physics) and the quadrics of the procedural anatomy
//! (tomograf-datasets).
//!
//! A [`Solid`] lives in its own frame, centred on the origin (a cylinder's axis along local
//! z); a [`PlacedSolid`] puts it in the world (LPS, mm) by an affine map `p = A·q + c`. A
//! line `o + t·d` maps into the local frame as `A⁻¹(o − c) + t·A⁻¹d` — the same `t`, since
//! the map is affine — so the world interval is the local one, with no rescaling. The
//! quadratic's discriminant is formed from the line's closest point to the centre (no
//! cancellation for central lines); a line that only touches the surface (Δ ≤ 0) or runs
//! along a flat face has an empty interval, which is its exact length. Containment
//! includes the boundary.

use crate::ray::Ray;
use glam::{DMat3, DMat4, DVec3};

/// A solid in its own frame (mm), centred on the origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Solid {
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
    /// A closed elliptic cylinder of semi-axes `radii` (mm) along local x and y and length
    /// `height` (mm) along local z; circular when the two radii are equal.
    Cylinder {
        /// Semi-axes across the axis (local x, y), mm.
        radii: [f64; 2],
        /// Length along the axis, mm.
        height: f64,
    },
}

impl Solid {
    /// A circular cylinder of `radius` and `height` (mm) along local z.
    pub fn circular_cylinder(radius: f64, height: f64) -> Self {
        Self::Cylinder {
            radii: [radius; 2],
            height,
        }
    }

    /// What is wrong with its sizes (each must be finite and > 0), if anything.
    pub fn problem(&self) -> Option<String> {
        let sizes: Vec<(&str, f64)> = match *self {
            Self::Box { size } => vec![("size x", size.x), ("size y", size.y), ("size z", size.z)],
            Self::Ellipsoid { radii } => {
                vec![
                    ("radius x", radii.x),
                    ("radius y", radii.y),
                    ("radius z", radii.z),
                ]
            }
            Self::Cylinder { radii, height } if radii[0] == radii[1] => {
                vec![("radius", radii[0]), ("height", height)]
            }
            Self::Cylinder { radii, height } => {
                vec![
                    ("radius x", radii[0]),
                    ("radius y", radii[1]),
                    ("height", height),
                ]
            }
        };
        sizes
            .into_iter()
            .find(|&(_, v)| !(v.is_finite() && v > 0.0))
            .map(|(what, v)| {
                format!(
                    "{} {what} is {v} mm; it must be finite and > 0",
                    self.kind()
                )
            })
    }

    /// The solid's name (`box`, `ellipsoid`, `cylinder`).
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
            Self::Cylinder { radii, height } => std::f64::consts::PI * radii[0] * radii[1] * height,
        }
    }

    /// Whether local point `q` (mm) lies inside, boundary included.
    pub fn contains(&self, q: DVec3) -> bool {
        match *self {
            Self::Box { size } => q.abs().cmple(size * 0.5).all(),
            Self::Ellipsoid { radii } => (q / radii).length_squared() <= 1.0,
            Self::Cylinder { radii, height } => {
                let u = q / DVec3::new(radii[0], radii[1], height * 0.5);
                u.x * u.x + u.y * u.y <= 1.0 && u.z.abs() <= 1.0
            }
        }
    }

    /// The parameter interval `(t0, t1)` of the line `o + t·d` (local frame) inside the
    /// solid, or `None` when it misses or only touches it.
    pub fn span(&self, o: DVec3, d: DVec3) -> Option<(f64, f64)> {
        match *self {
            Self::Box { size } => slab(o, d, size * 0.5, [true; 3]),
            Self::Ellipsoid { radii } => unit_quadric(o / radii, d / radii, [true, true, true]),
            Self::Cylinder { radii, height } => {
                let r = DVec3::new(radii[0], radii[1], 1.0);
                let (a, b) = unit_quadric(o / r, d / r, [true, true, false])?;
                let h = DVec3::new(f64::INFINITY, f64::INFINITY, height * 0.5);
                let (c, e) = slab(o, d, h, [false, false, true])?;
                let (t0, t1) = (a.max(c), b.min(e));
                (t1 > t0).then_some((t0, t1))
            }
        }
    }

    /// Half the world extent along each axis of the solid mapped by the linear map
    /// `linear` (exact: the support function of the mapped solid).
    fn reach(&self, linear: DMat3) -> DVec3 {
        let row = |i: usize| DVec3::new(linear.x_axis[i], linear.y_axis[i], linear.z_axis[i]);
        match *self {
            Self::Box { size } => {
                let abs = DMat3::from_cols(
                    linear.x_axis.abs(),
                    linear.y_axis.abs(),
                    linear.z_axis.abs(),
                );
                abs * (size * 0.5)
            }
            Self::Ellipsoid { radii } => DVec3::from_array([0, 1, 2].map(|i| {
                let l = row(i) * radii;
                l.x.hypot(l.y).hypot(l.z)
            })),
            Self::Cylinder { radii, height } => DVec3::from_array([0, 1, 2].map(|i| {
                let l = row(i);
                (l.x * radii[0]).hypot(l.y * radii[1]) + l.z.abs() * (height * 0.5)
            })),
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

/// A solid placed in the world (LPS, mm) by an affine map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlacedSolid {
    /// The solid in its own frame.
    pub solid: Solid,
    /// World → local: the inverse of the placement's linear part.
    to_local: DMat3,
    /// World position of the local origin, mm.
    centre: DVec3,
    /// World bounding box, mm (tight: the mapped solid touches each face).
    lo: DVec3,
    hi: DVec3,
    /// |det| of the placement's linear part (local → world volume factor).
    det: f64,
}

impl PlacedSolid {
    /// `solid` moved by the affine `placement` (local → world, mm); `Err` names the problem
    /// with the solid's sizes or a singular or non-finite placement.
    pub fn new(solid: Solid, placement: DMat4) -> Result<Self, String> {
        let linear = DMat3::from_mat4(placement);
        if !(placement.is_finite() && linear.determinant().abs() > 0.0) {
            return Err(format!(
                "{}: the placement must be finite and invertible",
                solid.kind()
            ));
        }
        Self::placed(solid, linear, linear.inverse(), placement.w_axis.truncate())
    }

    /// `solid` turned by the rotation `rotation` (orthonormal columns: the world directions
    /// of local x, y, z) and centred on `centre` (mm). World → local is then `rotationᵀ`.
    pub fn rotated(solid: Solid, centre: DVec3, rotation: DMat3) -> Result<Self, String> {
        if !(centre.is_finite() && rotation.is_finite()) {
            return Err(format!(
                "{}: the centre and rotation must be finite",
                solid.kind()
            ));
        }
        Self::placed(solid, rotation, rotation.transpose(), centre)
    }

    fn placed(solid: Solid, linear: DMat3, to_local: DMat3, centre: DVec3) -> Result<Self, String> {
        if let Some(p) = solid.problem() {
            return Err(p);
        }
        let reach = solid.reach(linear);
        Ok(Self {
            solid,
            to_local,
            centre,
            lo: centre - reach,
            hi: centre + reach,
            det: linear.determinant().abs(),
        })
    }

    /// World bounding box `(min, max)`, mm.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        (self.lo, self.hi)
    }

    /// Enclosed volume, mm³.
    pub fn volume_mm3(&self) -> f64 {
        self.solid.volume_mm3() * self.det
    }

    /// Whether world point `p` (mm) lies inside, boundary included.
    pub fn contains(&self, p: DVec3) -> bool {
        self.solid.contains(self.to_local * (p - self.centre))
    }

    /// Where the whole line `o + t·d` (world) enters and leaves the solid (`t`; mm when `d`
    /// is a unit vector), or `None` when it misses or only touches it.
    pub fn span(&self, o: DVec3, d: DVec3) -> Option<(f64, f64)> {
        self.solid
            .span(self.to_local * (o - self.centre), self.to_local * d)
    }

    /// Where the line of `ray` enters and leaves the solid (`t`, mm; not clipped to the
    /// ray's `[t_min, t_max]`), or `None`.
    pub fn ray_span(&self, ray: &Ray) -> Option<(f64, f64)> {
        self.span(ray.origin, ray.direction)
    }

    /// Length (mm) of `ray` inside the solid within its `[t_min, t_max]`.
    pub fn chord(&self, ray: &Ray) -> f64 {
        self.ray_span(ray).map_or(0.0, |(t0, t1)| {
            (t1.min(ray.t_max) - t0.max(ray.t_min)).max(0.0)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ray from `origin` along `direction`, `t` in [0, `t_max`].
    fn ray(origin: DVec3, direction: DVec3, t_max: f64) -> Ray {
        Ray {
            origin,
            direction,
            t_min: 0.0,
            t_max,
        }
    }

    /// Chords, containment, bounds and volume against hand-worked answers.
    #[test]
    fn solids_by_hand() {
        let sphere = PlacedSolid::rotated(
            Solid::Ellipsoid {
                radii: DVec3::splat(10.0),
            },
            DVec3::new(1.0, 2.0, 3.0),
            DMat3::IDENTITY,
        )
        .unwrap();
        // A line 6 mm off the centre: 2·√(100 − 36) = 16 mm.
        let (t0, t1) = sphere.span(DVec3::new(-50.0, 8.0, 3.0), DVec3::X).unwrap();
        assert!((t1 - t0 - 16.0).abs() < 1e-12);
        assert!(sphere.contains(DVec3::new(11.0, 2.0, 3.0)));
        assert!(!sphere.contains(DVec3::new(11.0, 2.1, 3.0)));
        assert_eq!(sphere.bounds().0, DVec3::new(-9.0, -8.0, -7.0));

        // An elliptic cylinder (semi-axes 20, 10; length 30) turned 90° about z: its local
        // x runs along world y.
        let cyl = PlacedSolid::rotated(
            Solid::Cylinder {
                radii: [20.0, 10.0],
                height: 30.0,
            },
            DVec3::ZERO,
            DMat3::from_cols(DVec3::Y, -DVec3::X, DVec3::Z),
        )
        .unwrap();
        let (lo, hi) = cyl.bounds();
        assert_eq!(
            (lo, hi),
            (
                DVec3::new(-10.0, -20.0, -15.0),
                DVec3::new(10.0, 20.0, 15.0)
            )
        );
        let along_y = ray(DVec3::new(0.0, -100.0, 0.0), DVec3::Y, 1e3);
        assert!((cyl.chord(&along_y) - 40.0).abs() < 1e-12);
        // Clipped by the ray's own end.
        let short = ray(DVec3::new(0.0, -100.0, 0.0), DVec3::Y, 90.0);
        assert!((cyl.chord(&short) - 10.0).abs() < 1e-12);
        // Along the axis: the height.
        let along_z = ray(DVec3::new(5.0, 5.0, -100.0), DVec3::Z, 1e3);
        assert!((cyl.chord(&along_z) - 30.0).abs() < 1e-12);
        assert!(cyl.contains(DVec3::new(10.0, 0.0, 15.0)));
        assert!(!cyl.contains(DVec3::new(10.0, 0.1, 15.0)));
        assert!((cyl.volume_mm3() - std::f64::consts::PI * 200.0 * 30.0).abs() < 1e-9);

        // A box scaled 2× along x by its placement: twice the chord and the volume.
        let b = PlacedSolid::new(
            Solid::Box {
                size: DVec3::new(4.0, 6.0, 8.0),
            },
            DMat4::from_scale(DVec3::new(2.0, 1.0, 1.0)),
        )
        .unwrap();
        let (t0, t1) = b.span(DVec3::new(-20.0, 0.0, 0.0), DVec3::X).unwrap();
        assert!((t1 - t0 - 8.0).abs() < 1e-12);
        assert!((b.volume_mm3() - 384.0).abs() < 1e-9);
        // A line along a face only touches it: empty.
        assert!(b.span(DVec3::new(-20.0, 3.0, 0.0), DVec3::X).is_none());
    }

    /// Impossible sizes and placements are refused by name.
    #[test]
    fn bad_solids_are_refused() {
        let e = PlacedSolid::new(Solid::circular_cylinder(-1.0, 2.0), DMat4::IDENTITY).unwrap_err();
        assert!(e.contains("cylinder radius is -1"), "{e}");
        let e = PlacedSolid::new(
            Solid::Ellipsoid { radii: DVec3::ONE },
            DMat4::from_scale(DVec3::new(1.0, 0.0, 1.0)),
        )
        .unwrap_err();
        assert!(e.contains("invertible"), "{e}");
    }
}
