//! Scoring regions: exact analytic volumes (boxes, cylinders, half-cylinders) in which the energy imparted
//! is tallied at the interaction point itself, so a region's tally carries no voxelisation
//! error even where the material grid is coarse (TG-195's VOIs and scoring cylinders).
//!
//! Units: mm, world coordinates.

use glam::DVec3;
use serde::{Deserialize, Serialize};
use tomograf_sim::error::{Result, SimError};

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

    /// Whether world point `p` (mm) lies inside.
    #[inline]
    pub fn contains(&self, p: DVec3) -> bool {
        match self.shape {
            Shape::Box { min, max } => (0..3).all(|a| p[a] >= min[a] && p[a] <= max[a]),
            Shape::Cylinder {
                centre,
                axis,
                radius,
                half_length,
            } => {
                let a = DVec3::from(axis).normalize();
                let r = p - DVec3::from(centre);
                let along = r.dot(a);
                along.abs() <= half_length && (r - a * along).length_squared() <= radius * radius
            }
            Shape::HalfCylinder { centre, side, .. } => {
                let (full, _) = self.cylinder_part().expect("a cylinder");
                (p - DVec3::from(centre)).dot(DVec3::from(side)) >= 0.0
                    && Region {
                        name: String::new(),
                        shape: full,
                    }
                    .contains(p)
            }
        }
    }

    /// Where the line `p + t·d` (mm, `d` a unit vector) runs inside the region, clipped to
    /// `t_min ≤ t ≤ t_max`: the parameter interval `(t0, t1)` with `t0 < t1`, or `None` if
    /// the clipped line misses it (or only touches it).
    pub fn chord(&self, p: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<(f64, f64)> {
        let (mut t0, mut t1) = (t_min, t_max);
        if let Some((full, Some((c, n)))) = self.cylinder_part() {
            // The half-space (p + t·d − c)·n ≥ 0, then the full cylinder.
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
            if t0 >= t1 {
                return None;
            }
            let cylinder = Region {
                name: String::new(),
                shape: full,
            };
            return cylinder.chord(p, d, t0, t1);
        }
        match self.shape {
            Shape::HalfCylinder { .. } => unreachable!("handled above"),
            Shape::Box { min, max } => {
                for a in 0..3 {
                    if d[a] == 0.0 {
                        if p[a] < min[a] || p[a] > max[a] {
                            return None;
                        }
                        continue;
                    }
                    let (u, v) = ((min[a] - p[a]) / d[a], (max[a] - p[a]) / d[a]);
                    t0 = t0.max(u.min(v));
                    t1 = t1.min(u.max(v));
                }
            }
            Shape::Cylinder {
                centre,
                axis,
                radius,
                half_length,
            } => {
                let a = DVec3::from(axis);
                let a = if (a.length_squared() - 1.0).abs() < 1e-12 {
                    a
                } else {
                    a.normalize()
                };
                let r = p - DVec3::from(centre);
                // Along the axis: |r·a + t·d·a| ≤ half_length.
                let (ra, da) = (r.dot(a), d.dot(a));
                if da == 0.0 {
                    if ra.abs() > half_length {
                        return None;
                    }
                } else {
                    let (u, v) = ((-half_length - ra) / da, (half_length - ra) / da);
                    t0 = t0.max(u.min(v));
                    t1 = t1.min(u.max(v));
                }
                // Across it: |r⊥ + t·d⊥|² ≤ radius².
                let (rp, dp) = (r - a * ra, d - a * da);
                let qa = dp.length_squared();
                let qc = rp.length_squared() - radius * radius;
                if qa == 0.0 {
                    if qc > 0.0 {
                        return None;
                    }
                } else {
                    let qb = rp.dot(dp);
                    let disc = qb * qb - qa * qc;
                    if disc <= 0.0 {
                        return None;
                    }
                    let s = disc.sqrt();
                    // The stable pair of roots of qa·t² + 2·qb·t + qc.
                    let q = -(qb + qb.signum() * s);
                    let (u, v) = if q == 0.0 {
                        (0.0, 0.0)
                    } else {
                        (q / qa, qc / q)
                    };
                    t0 = t0.max(u.min(v));
                    t1 = t1.min(u.max(v));
                }
            }
        }
        (t0 < t1).then_some((t0, t1))
    }

    /// The same region with its axis (if any) scaled to unit length.
    pub fn with_unit_axis(&self) -> Self {
        let mut r = self.clone();
        match r.shape {
            Shape::Cylinder { ref mut axis, .. } => {
                *axis = DVec3::from(*axis).normalize().to_array();
            }
            Shape::HalfCylinder {
                ref mut axis,
                ref mut side,
                ..
            } => {
                *axis = DVec3::from(*axis).normalize().to_array();
                *side = DVec3::from(*side).normalize().to_array();
            }
            Shape::Box { .. } => {}
        }
        r
    }

    /// The axis-aligned box that holds the region: (lower, upper corner), mm.
    /// (A half-cylinder's are its full cylinder's: a box that holds it, not the tightest.)
    pub fn bounds(&self) -> (DVec3, DVec3) {
        if let Some((full, Some(_))) = self.cylinder_part() {
            return Region {
                name: String::new(),
                shape: full,
            }
            .bounds();
        }
        match self.shape {
            Shape::HalfCylinder { .. } => unreachable!("handled above"),
            Shape::Box { min, max } => (min.into(), max.into()),
            Shape::Cylinder {
                centre,
                axis,
                radius,
                half_length,
            } => {
                let a = DVec3::from(axis).normalize();
                let half = DVec3::new(
                    half_length * a.x.abs() + radius * (1.0 - a.x * a.x).max(0.0).sqrt(),
                    half_length * a.y.abs() + radius * (1.0 - a.y * a.y).max(0.0).sqrt(),
                    half_length * a.z.abs() + radius * (1.0 - a.z * a.z).max(0.0).sqrt(),
                );
                (DVec3::from(centre) - half, DVec3::from(centre) + half)
            }
        }
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
}
