//! Scoring regions: exact analytic volumes (boxes, cylinders, half-cylinders) in which the energy imparted
//! is tallied at the interaction point itself, so a region's tally carries no voxelisation
//! error even where the material grid is coarse (TG-195's VOIs and scoring cylinders).
//!
//! Units: mm, world coordinates.

use glam::{DMat3, DVec3};
use serde::{Deserialize, Serialize};
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::solid::{PlacedSolid, Solid};

/// The shape of a scoring region.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "shape", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Shape {
    /// Axis-aligned box `min ≤ p ≤ max` (mm).
    Box {
        /// Lower corner, mm.
        min: [f64; 3],
        /// Upper corner, mm.
        max: [f64; 3],
    },
    /// Right circular cylinder: centre, unit axis, radius and half length (mm).
    Cylinder {
        /// Centre, mm.
        centre: [f64; 3],
        /// Axis direction (normalised on use).
        axis: [f64; 3],
        /// Radius, mm.
        radius: f64,
        /// Half the length along the axis, mm.
        half_length: f64,
    },
    /// The half of a right circular cylinder on one side of a plane through its axis:
    /// the points of the cylinder with (p − centre)·side ≥ 0 (TG-195's breast).
    HalfCylinder {
        /// Centre (on the cutting plane), mm.
        centre: [f64; 3],
        /// Axis direction (normalised on use).
        axis: [f64; 3],
        /// Radius, mm.
        radius: f64,
        /// Half the length along the axis, mm.
        half_length: f64,
        /// Normal of the cutting plane towards the half kept (perpendicular to the axis;
        /// normalised on use).
        side: [f64; 3],
    },
}

/// A named scoring region.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Region {
    /// Name used in tables and files.
    pub name: String,
    /// Where it is.
    #[serde(flatten)]
    pub shape: Shape,
}

impl Region {
    /// An axis-aligned box region with centre `centre` and full sides `size` (mm).
    pub fn cube(name: &str, centre: DVec3, size: DVec3) -> Self {
        Self {
            name: name.into(),
            shape: Shape::Box {
                min: (centre - size * 0.5).to_array(),
                max: (centre + size * 0.5).to_array(),
            },
        }
    }

    /// A cylinder region.
    pub fn cylinder(name: &str, centre: DVec3, axis: DVec3, radius: f64, length: f64) -> Self {
        Self {
            name: name.into(),
            shape: Shape::Cylinder {
                centre: centre.to_array(),
                axis: axis.to_array(),
                radius,
                half_length: length * 0.5,
            },
        }
    }

    /// A half-cylinder region: the half of the cylinder on the side of `side`.
    pub fn half_cylinder(
        name: &str,
        centre: DVec3,
        axis: DVec3,
        radius: f64,
        length: f64,
        side: DVec3,
    ) -> Self {
        Self {
            name: name.into(),
            shape: Shape::HalfCylinder {
                centre: centre.to_array(),
                axis: axis.to_array(),
                radius,
                half_length: length * 0.5,
                side: side.to_array(),
            },
        }
    }

    /// The full cylinder of a (half-)cylinder region, and the half kept (`None`: all).
    fn cylinder_part(&self) -> Option<(Shape, Option<(DVec3, DVec3)>)> {
        match self.shape {
            Shape::Box { .. } => None,
            Shape::Cylinder { .. } => Some((self.shape, None)),
            Shape::HalfCylinder {
                centre,
                axis,
                radius,
                half_length,
                side,
            } => Some((
                Shape::Cylinder {
                    centre,
                    axis,
                    radius,
                    half_length,
                },
                Some((DVec3::from(centre), DVec3::from(side).normalize())),
            )),
        }
    }

    /// Checks the region, naming it in the error.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: &str| {
            Err(SimError::InvalidGeometry(format!(
                "scoring region '{}': {m}",
                self.name
            )))
        };
        if self.name.trim().is_empty() {
            return Err(SimError::InvalidGeometry(
                "a scoring region has an empty name".into(),
            ));
        }
        match self.shape {
            Shape::Box { min, max } => {
                if !(min.iter().chain(&max).all(|v| v.is_finite())) {
                    return bad("corners must be finite");
                }
                if (0..3).any(|a| max[a] <= min[a]) {
                    return bad("max must exceed min on every axis");
                }
            }
            Shape::Cylinder {
                centre,
                axis,
                radius,
                half_length,
            } => {
                if !(centre.iter().all(|v| v.is_finite()) && DVec3::from(axis).is_finite()) {
                    return bad("centre and axis must be finite");
                }
                if DVec3::from(axis).length() == 0.0 {
                    return bad("the axis is the zero vector");
                }
                if !(radius.is_finite()
                    && radius > 0.0
                    && half_length.is_finite()
                    && half_length > 0.0)
                {
                    return bad("radius and length must be finite and > 0");
                }
            }
            Shape::HalfCylinder { axis, side, .. } => {
                let (full, _) = self.cylinder_part().expect("a cylinder");
                Region {
                    name: self.name.clone(),
                    shape: full,
                }
                .validate()?;
                let (a, n) = (DVec3::from(axis), DVec3::from(side));
                if !n.is_finite() || n.length() == 0.0 {
                    return bad("the side must be a finite, non-zero vector");
                }
                if a.normalize().dot(n.normalize()).abs() > 1e-9 {
                    return bad("the side must be perpendicular to the axis");
                }
            }
        }
        Ok(())
    }

    /// The region as a placed [`Solid`] and the half-space that cuts it (a point on the
    /// plane and the unit normal towards the half kept), for scoring many flights: its
    /// containment, chords and bounds. `Err` as [`Region::validate`].
    pub fn placed(&self) -> Result<PlacedRegion> {
        self.validate()?;
        let turned = |centre: [f64; 3], axis: [f64; 3], radius: f64, half_length: f64| {
            let a = DVec3::from(axis).normalize();
            let (u, v) = a.any_orthonormal_pair();
            PlacedSolid::rotated(
                Solid::circular_cylinder(radius, 2.0 * half_length),
                DVec3::from(centre),
                DMat3::from_cols(u, v, a),
            )
        };
        let (solid, cut) = match self.shape {
            Shape::Box { min, max } => {
                let (min, max) = (DVec3::from(min), DVec3::from(max));
                let size = max - min;
                (
                    PlacedSolid::rotated(Solid::Box { size }, min + size * 0.5, DMat3::IDENTITY),
                    None,
                )
            }
            Shape::Cylinder {
                centre,
                axis,
                radius,
                half_length,
            } => (turned(centre, axis, radius, half_length), None),
            Shape::HalfCylinder {
                centre,
                axis,
                radius,
                half_length,
                side,
            } => (
                turned(centre, axis, radius, half_length),
                Some((DVec3::from(centre), DVec3::from(side).normalize())),
            ),
        };
        let solid = solid.map_err(|m| {
            SimError::InvalidGeometry(format!("scoring region '{}': {m}", self.name))
        })?;
        Ok(PlacedRegion { solid, cut })
    }

    /// Whether world point `p` (mm) lies inside (false for an invalid region). To test
    /// many points, use [`Region::placed`] once.
    pub fn contains(&self, p: DVec3) -> bool {
        self.placed().is_ok_and(|r| r.contains(p))
    }

    /// Where the line `p + t·d` (mm) runs inside the region, clipped to
    /// `t_min ≤ t ≤ t_max` ([`PlacedRegion::chord`]; `None` for an invalid region).
    pub fn chord(&self, p: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<(f64, f64)> {
        self.placed().ok()?.chord(p, d, t_min, t_max)
    }

    /// The axis-aligned box that holds the region: (lower, upper corner), mm.
    /// (A half-cylinder's are its full cylinder's: a box that holds it, not the tightest.)
    /// Errors as [`Region::validate`].
    pub fn bounds(&self) -> Result<(DVec3, DVec3)> {
        Ok(self.placed()?.bounds())
    }

    /// Volume in mm³.
    pub fn volume_mm3(&self) -> f64 {
        match self.shape {
            Shape::Box { min, max } => (0..3).map(|a| max[a] - min[a]).product(),
            Shape::Cylinder {
                radius,
                half_length,
                ..
            } => std::f64::consts::PI * radius * radius * 2.0 * half_length,
            Shape::HalfCylinder {
                radius,
                half_length,
                ..
            } => std::f64::consts::PI * radius * radius * half_length,
        }
    }
}

/// A region ready to score: its solid and the half-space that cuts it, if any.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlacedRegion {
    solid: PlacedSolid,
    /// A point on the cutting plane and its unit normal towards the half kept.
    cut: Option<(DVec3, DVec3)>,
}

impl PlacedRegion {
    /// Whether world point `p` (mm) lies inside, boundary included.
    #[inline]
    pub fn contains(&self, p: DVec3) -> bool {
        self.cut.is_none_or(|(c, n)| (p - c).dot(n) >= 0.0) && self.solid.contains(p)
    }

    /// Where the line `p + t·d` (mm) runs inside the region, clipped to
    /// `t_min ≤ t ≤ t_max`: the parameter interval `(t0, t1)` with `t0 < t1`, or `None` if
    /// the clipped line misses it (or only touches it).
    pub fn chord(&self, p: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<(f64, f64)> {
        let (mut t0, mut t1) = (t_min, t_max);
        if let Some((c, n)) = self.cut {
            // The half-space (p + t·d − c)·n ≥ 0.
            let (h, dn) = ((p - c).dot(n), d.dot(n));
            if dn == 0.0 {
                if h < 0.0 {
                    return None;
                }
            } else if dn > 0.0 {
                t0 = t0.max(-h / dn);
            } else {
                t1 = t1.min(-h / dn);
            }
        }
        let (a, b) = self.solid.span(p, d)?;
        let (t0, t1) = (t0.max(a), t1.min(b));
        (t0 < t1).then_some((t0, t1))
    }

    /// The axis-aligned box that holds the region: (lower, upper corner), mm (a
    /// half-cylinder's is its full cylinder's).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        self.solid.bounds()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A half-cylinder keeps the side it names, holds half the volume, and refuses a side
    /// along its axis.
    #[test]
    fn a_half_cylinder_is_the_half_it_names() {
        let h = Region::half_cylinder("h", DVec3::ZERO, DVec3::Z, 10.0, 4.0, DVec3::X);
        h.validate().unwrap();
        assert!(h.contains(DVec3::new(5.0, 0.0, 1.0)));
        assert!(!h.contains(DVec3::new(-5.0, 0.0, 1.0)));
        assert!(!h.contains(DVec3::new(5.0, 0.0, 3.0)));
        let full = Region::cylinder("c", DVec3::ZERO, DVec3::Z, 10.0, 4.0);
        assert!((2.0 * h.volume_mm3() - full.volume_mm3()).abs() < 1e-9);
        // A line along x through the centre: 10 mm inside the half, 20 in the full one.
        let (t0, t1) = h
            .chord(DVec3::new(-20.0, 0.0, 0.0), DVec3::X, 0.0, 100.0)
            .unwrap();
        assert!((t0 - 20.0).abs() < 1e-12 && (t1 - 30.0).abs() < 1e-12);
        assert!(
            h.chord(DVec3::new(-5.0, -20.0, 0.0), DVec3::Y, 0.0, 100.0)
                .is_none()
        );
        let bad = Region::half_cylinder("b", DVec3::ZERO, DVec3::Z, 10.0, 4.0, DVec3::Z);
        assert!(
            bad.validate()
                .unwrap_err()
                .to_string()
                .contains("perpendicular")
        );
    }

    /// A cylinder on an oblique axis: chords across and along it, and its bounds, by hand.
    #[test]
    fn an_oblique_cylinder_by_hand() {
        let axis = DVec3::new(1.0, 1.0, 0.0);
        let c = Region::cylinder("c", DVec3::new(5.0, 0.0, 0.0), axis, 3.0, 20.0);
        let r = c.placed().unwrap();
        // Across the axis through the centre: the diameter; along it: the length.
        let (t0, t1) = r
            .chord(DVec3::new(5.0, 0.0, -50.0), DVec3::Z, 0.0, 1e3)
            .unwrap();
        assert!((t1 - t0 - 6.0).abs() < 1e-12 && (t0 - 47.0).abs() < 1e-12);
        let u = axis.normalize();
        let (t0, t1) = r
            .chord(DVec3::new(5.0, 0.0, 0.0) - 50.0 * u, u, 0.0, 1e3)
            .unwrap();
        assert!((t1 - t0 - 20.0).abs() < 1e-12);
        // Clipped by t_max.
        let (_, t1) = r
            .chord(DVec3::new(5.0, 0.0, 0.0) - 50.0 * u, u, 0.0, 45.0)
            .unwrap();
        assert_eq!(t1, 45.0);
        // Bounds: 10·cos 45° + 3·sin 45° in x and y, the radius in z.
        let (lo, hi) = c.bounds().unwrap();
        let half = 13.0 / 2f64.sqrt();
        assert!((hi.x - 5.0 - half).abs() < 1e-12 && (hi.y - half).abs() < 1e-12);
        assert!((hi.z - 3.0).abs() < 1e-12 && (lo.z + 3.0).abs() < 1e-12);
        assert!(c.contains(DVec3::new(5.0, 0.0, 2.9)) && !c.contains(DVec3::new(5.0, 0.0, 3.1)));
    }
}
