//! A collimated point source: photons emitted isotropically from a point, kept only where
//! they cross a rectangle (the collimated field) in a plane — the source model of the
//! AAPM TG-195 cases and of a radiograph whose field is the detector panel.
//!
//! Units: positions in mm (world LPS), solid angle in sr.

use glam::DVec3;
use rand::Rng;
use tomograf_sim::error::{Result, SimError};

/// A point source collimated to a rectangle or a disc: directions uniform in solid angle
/// over the field `centre + s·half_u + t·half_v` (rectangle: s, t ∈ [−1, 1]; disc: s² + t²
/// ≤ 1) as seen from `position`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldSource {
    disc: bool,
    position: DVec3,
    centre: DVec3,
    half_u: DVec3,
    half_v: DVec3,
    /// Unit normal of the field plane, pointing away from the source.
    normal: DVec3,
    /// Distance from the source to the field plane, mm.
    height: f64,
    /// Distance from the source to the nearest point of the rectangle, mm.
    nearest: f64,
}

impl FieldSource {
    /// A source at `position` collimated to the rectangle with centre `centre` and
    /// perpendicular half-side vectors `half_u`, `half_v` (mm). Errors on non-finite
    /// values, a degenerate or non-rectangular field, or a source in the field's plane.
    pub fn new(position: DVec3, centre: DVec3, half_u: DVec3, half_v: DVec3) -> Result<Self> {
        let bad = |m: String| Err(SimError::InvalidGeometry(format!("field source: {m}")));
        if ![position, centre, half_u, half_v]
            .iter()
            .all(|v| v.is_finite())
        {
            return bad("position, field centre and half sides must be finite".into());
        }
        let (lu, lv) = (half_u.length(), half_v.length());
        if lu <= 0.0 || lv <= 0.0 {
            return bad(format!("half sides {lu} mm × {lv} mm; both must be > 0"));
        }
        if half_u.dot(half_v).abs() > 1e-9 * lu * lv {
            return bad("the field's sides must be perpendicular".into());
        }
        let mut normal = half_u.cross(half_v).normalize();
        let mut height = (centre - position).dot(normal);
        if height < 0.0 {
            normal = -normal;
            height = -height;
        }
        if height <= 1e-9 * (centre - position).length().max(1.0) {
            return bad("the source lies in the field's plane".into());
        }
        // Nearest point of the rectangle to the source: clamp its in-plane offset.
        let off = position - centre;
        let s = (off.dot(half_u) / (lu * lu)).clamp(-1.0, 1.0);
        let t = (off.dot(half_v) / (lv * lv)).clamp(-1.0, 1.0);
        let nearest = (centre + half_u * s + half_v * t - position).length();
        Ok(Self {
            disc: false,
            position,
            centre,
            half_u,
            half_v,
            normal,
            height,
            nearest,
        })
    }

    /// A source at `position` collimated to the disc of `radius` (mm) centred on `centre`
    /// in the plane with normal `normal`. Errors as [`FieldSource::new`].
    pub fn disc(position: DVec3, centre: DVec3, normal: DVec3, radius: f64) -> Result<Self> {
        if !(normal.is_finite() && normal.length() > 0.0 && radius.is_finite() && radius > 0.0) {
            return Err(SimError::InvalidGeometry(format!(
                "field source: disc normal {normal} and radius {radius} mm must be non-zero \
                 and finite"
            )));
        }
        let n = normal.normalize();
        let a = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
        let u = n.cross(a).normalize() * radius;
        let v = n.cross(u);
        let mut f = Self::new(position, centre, u, v)?;
        f.disc = true;
        // The nearest point of the disc: the source's foot clamped to the radius.
        let off = position - centre;
        let inplane = off - f.normal * off.dot(f.normal);
        let foot = if inplane.length() > radius {
            inplane.normalize() * radius
        } else {
            inplane
        };
        f.nearest = (centre + foot - position).length();
        Ok(f)
    }

    /// The source position (mm).
    pub fn position(&self) -> DVec3 {
        self.position
    }

    /// Solid angle of the field seen from the source (sr): the two triangles of the
    /// rectangle by Van Oosterom & Strackee (IEEE Trans. Biomed. Eng. 30 (1983) 125).
    /// A disc's by a 2-D quadrature of h/r³ (relative error below 10⁻⁶ for the fields
    /// used here).
    pub fn solid_angle(&self) -> f64 {
        if self.disc {
            let (nr, na) = (2000, 720);
            let mut sum = 0.0;
            for i in 0..nr {
                let rho = (i as f64 + 0.5) / nr as f64;
                for j in 0..na {
                    let phi = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / na as f64;
                    let p = self.centre
                        + self.half_u * (rho * phi.cos())
                        + self.half_v * (rho * phi.sin());
                    let r = (p - self.position).length();
                    sum += self.height / (r * r * r) * rho;
                }
            }
            let area_per_unit = self.half_u.length() * self.half_v.length();
            return sum * area_per_unit / nr as f64 * 2.0 * std::f64::consts::PI / na as f64;
        }
        let c = |s: f64, t: f64| self.centre + self.half_u * s + self.half_v * t - self.position;
        let (a, b, cc, d) = (c(-1.0, -1.0), c(1.0, -1.0), c(1.0, 1.0), c(-1.0, 1.0));
        triangle_solid_angle(a, b, cc) + triangle_solid_angle(a, cc, d)
    }

    /// A unit direction uniform in solid angle over the field: a point drawn uniformly on
    /// the rectangle is accepted with probability (nearest distance / distance)³ ∝ the
    /// solid angle its area element subtends (cos θ / r² = h / r³).
    pub fn sample<R: Rng>(&self, rng: &mut R) -> DVec3 {
        loop {
            let s = 2.0 * rng.random::<f64>() - 1.0;
            let t = 2.0 * rng.random::<f64>() - 1.0;
            if self.disc && s * s + t * t > 1.0 {
                continue;
            }
            let v = self.centre + self.half_u * s + self.half_v * t - self.position;
            let r = v.length();
            let accept = (self.nearest / r).powi(3);
            if rng.random::<f64>() < accept {
                return v / r;
            }
        }
    }

    /// Distance from the source to the field plane, mm.
    pub fn height(&self) -> f64 {
        self.height
    }

    /// Unit normal of the field plane, away from the source.
    pub fn normal(&self) -> DVec3 {
        self.normal
    }
}

/// Solid angle (sr) of the triangle with vertices `a`, `b`, `c` seen from the origin.
fn triangle_solid_angle(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let num = a.dot(b.cross(c)).abs();
    let den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    2.0 * num.atan2(den)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn solid_angle_of_a_cube_face_is_a_sixth_of_the_sphere() {
        let f = FieldSource::new(DVec3::ZERO, DVec3::Z, DVec3::X, DVec3::Y).unwrap();
        let want = 4.0 * std::f64::consts::PI / 6.0;
        assert!(
            (f.solid_angle() - want).abs() < 1e-12,
            "{}",
            f.solid_angle()
        );
    }

    #[test]
    fn samples_cover_the_field_uniformly_in_solid_angle() {
        // Cube face again: by symmetry each quadrant holds a quarter of the directions,
        // and the central square |x|,|y| < 0.5 at z = 1 holds Ω(small)/Ω(face).
        let f = FieldSource::new(DVec3::ZERO, DVec3::Z, DVec3::X, DVec3::Y).unwrap();
        let small = FieldSource::new(DVec3::ZERO, DVec3::Z, DVec3::X * 0.5, DVec3::Y * 0.5)
            .unwrap()
            .solid_angle();
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let n = 200_000;
        let (mut inner, mut quadrant) = (0usize, 0usize);
        for _ in 0..n {
            let d = f.sample(&mut rng);
            let (x, y) = (d.x / d.z, d.y / d.z);
            assert!(x.abs() <= 1.0 + 1e-12 && y.abs() <= 1.0 + 1e-12);
            inner += usize::from(x.abs() < 0.5 && y.abs() < 0.5);
            quadrant += usize::from(x > 0.0 && y > 0.0);
        }
        let p = small / f.solid_angle();
        let sigma = (p * (1.0 - p) / n as f64).sqrt();
        assert!((inner as f64 / n as f64 - p).abs() < 4.0 * sigma);
        assert!((quadrant as f64 / n as f64 - 0.25).abs() < 4.0 * (0.1875 / n as f64).sqrt());
    }

    #[test]
    fn solid_angle_of_an_on_axis_disc() {
        // Ω = 2π(1 − h/√(h² + R²)).
        let (h, r) = (1000.0, 5.0);
        let f = FieldSource::disc(DVec3::ZERO, DVec3::Z * h, DVec3::Z, r).unwrap();
        let want = 2.0 * std::f64::consts::PI * (1.0 - h / (h * h + r * r).sqrt());
        assert!(
            (f.solid_angle() / want - 1.0).abs() < 1e-6,
            "{} {want}",
            f.solid_angle()
        );
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for _ in 0..1000 {
            let d = f.sample(&mut rng);
            let p = d * (h / d.z);
            assert!(p.x.hypot(p.y) <= r * (1.0 + 1e-12));
        }
    }

    #[test]
    fn degenerate_fields_are_refused() {
        assert!(FieldSource::new(DVec3::ZERO, DVec3::Z, DVec3::ZERO, DVec3::Y).is_err());
        assert!(FieldSource::new(DVec3::ZERO, DVec3::X, DVec3::X, DVec3::Y).is_err());
        assert!(
            FieldSource::new(DVec3::ZERO, DVec3::Z, DVec3::X, DVec3::new(1.0, 1.0, 0.0)).is_err()
        );
    }
}
