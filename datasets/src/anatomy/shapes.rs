//! The analytic shapes a phantom is built from: superelliptic sections interpolated along
//! z (optionally one-sided and cut by a dome), ellipsoids and elliptic z-cylinders (the
//! project's analytic solids, [`tomograf_sim::solid`]), tapered capsules, rounded boxes and
//! the curved couch profile. Each knows its bounding box and
//! whether it contains a point; sections, ellipsoids and z-cylinders also give the exact
//! x-intervals of a voxel row, which [`super::raster`] fills in one go.

use glam::{DMat3, DVec3};
use tomograf_sim::solid::{PlacedSolid, Solid};

/// One key of a [`Section`]: a superelliptic cross-section at height `z`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SecKey {
    pub z: f64,
    /// Centre.
    pub cx: f64,
    pub cy: f64,
    /// Lateral semi-axis.
    pub a: f64,
    /// Anterior (−y) and posterior (+y) semi-axes.
    pub ba: f64,
    pub bp: f64,
    /// Medial limit for one-sided sections (`side ≠ 0`): keep `side·x ≥ xm`.
    pub xm: f64,
}

impl SecKey {
    fn lerp(&self, o: &SecKey, t: f64) -> SecKey {
        let l = |a: f64, b: f64| a + (b - a) * t;
        SecKey {
            z: l(self.z, o.z),
            cx: l(self.cx, o.cx),
            cy: l(self.cy, o.cy),
            a: l(self.a, o.a),
            ba: l(self.ba, o.ba),
            bp: l(self.bp, o.bp),
            xm: l(self.xm, o.xm),
        }
    }
}

/// A dome cut from below: points with `z < zb + height·sqrt(1 − X² − Y²)` (X, Y the
/// offsets from the dome centre in units of `rx`, `ry`) are removed. Models a
/// hemidiaphragm under a lung.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Dome {
    pub zb: f64,
    pub height: f64,
    pub cx: f64,
    pub cy: f64,
    pub rx: f64,
    pub ry: f64,
}

/// A generalised cylinder along z: superelliptic cross-sections interpolated linearly
/// between keys (exponent `p_ant` on the anterior half, `p_post` on the posterior half),
/// optionally restricted to one side of the midline and cut by a dome from below.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Section {
    pub keys: Vec<SecKey>,
    pub p_ant: f64,
    pub p_post: f64,
    /// 0: both sides; +1: only `x ≥ xm`; −1: only `x ≤ −xm`.
    pub side: f64,
    pub dome: Option<Dome>,
}

/// Up to two x-intervals of one voxel row.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Spans {
    n: usize,
    s: [(f64, f64); 2],
}

impl Spans {
    fn one(lo: f64, hi: f64) -> Self {
        let mut s = Spans::default();
        s.push(lo, hi);
        s
    }
    fn push(&mut self, lo: f64, hi: f64) {
        if lo <= hi && self.n < 2 {
            self.s[self.n] = (lo, hi);
            self.n += 1;
        }
    }
    pub fn iter(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.s[..self.n].iter().copied()
    }
    pub fn contains(&self, x: f64) -> bool {
        self.iter().any(|(a, b)| a <= x && x <= b)
    }
}

impl Section {
    /// The interpolated key at height `z`, or `None` outside the keys.
    pub fn at(&self, z: f64) -> Option<SecKey> {
        let (first, last) = (self.keys.first()?, self.keys.last()?);
        if z < first.z || z > last.z {
            return None;
        }
        let i = self
            .keys
            .partition_point(|k| k.z <= z)
            .min(self.keys.len() - 1);
        if i == 0 {
            return Some(*first);
        }
        let (a, b) = (&self.keys[i - 1], &self.keys[i]);
        let t = if b.z > a.z {
            (z - a.z) / (b.z - a.z)
        } else {
            0.0
        };
        Some(a.lerp(b, t.clamp(0.0, 1.0)))
    }

    /// Half-width of the cross-section `k` at row `y`, or `None` outside it.
    pub fn half_width(&self, k: &SecKey, y: f64) -> Option<f64> {
        let (b, p) = if y < k.cy {
            (k.ba, self.p_ant)
        } else {
            (k.bp, self.p_post)
        };
        if b <= 0.0 || k.a <= 0.0 {
            return None;
        }
        let yy = ((y - k.cy) / b).abs();
        if yy >= 1.0 {
            return None;
        }
        let f = if p == 2.0 {
            (1.0 - yy * yy).sqrt()
        } else {
            (1.0 - yy.powf(p)).powf(1.0 / p)
        };
        Some(k.a * f)
    }

    /// The x-intervals inside the section on row `(y, z)`, given the key at `z`.
    pub fn spans(&self, k: &SecKey, y: f64, z: f64) -> Spans {
        let Some(h) = self.half_width(k, y) else {
            return Spans::default();
        };
        let (mut lo, mut hi) = (k.cx - h, k.cx + h);
        if self.side > 0.0 {
            lo = lo.max(k.xm);
        } else if self.side < 0.0 {
            hi = hi.min(-k.xm);
        }
        if lo > hi {
            return Spans::default();
        }
        let Some(d) = &self.dome else {
            return Spans::one(lo, hi);
        };
        if z < d.zb {
            return Spans::default();
        }
        let c = (z - d.zb) / d.height;
        let q = 1.0 - c * c - ((y - d.cy) / d.ry).powi(2);
        if c >= 1.0 || q <= 0.0 {
            return Spans::one(lo, hi);
        }
        let w = d.rx * q.sqrt();
        let mut s = Spans::default();
        s.push(lo, hi.min(d.cx - w));
        s.push(lo.max(d.cx + w), hi);
        s
    }

    pub fn contains(&self, p: DVec3) -> bool {
        self.at(p.z)
            .is_some_and(|k| self.spans(&k, p.y, p.z).contains(p.x))
    }

    fn bounds(&self) -> (DVec3, DVec3) {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for k in &self.keys {
            lo = lo.min(DVec3::new(k.cx - k.a, k.cy - k.ba, k.z));
            hi = hi.max(DVec3::new(k.cx + k.a, k.cy + k.bp, k.z));
        }
        (lo, hi)
    }
}

/// The shapes a phantom is made of (all dimensions in mm, world LPS frame).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Shape {
    Section(Section),
    /// An analytic solid (ellipsoid or elliptic cylinder) of the project's one definition.
    Solid(PlacedSolid),
    /// A solid whose sizes came out ≤ 0 for this patient: it holds nothing.
    Nothing,
    /// Tapered capsule from `a` (radius `ra`) to `b` (radius `rb`).
    Tube {
        a: DVec3,
        b: DVec3,
        ra: f64,
        rb: f64,
    },
    /// Box with rounded edges: local `q = rt·(p − c)`, inner half-size `half`, rounding
    /// radius `round`.
    RBox {
        c: DVec3,
        rt: DMat3,
        half: DVec3,
        round: f64,
    },
    /// Curved couch top: `|x| ≤ half_w`, `top(x) ≤ y ≤ top(x) + thick` with
    /// `top(x) = y0 − (rc − sqrt(rc² − x²))` (the edges curve up, towards −y).
    Couch {
        y0: f64,
        rc: f64,
        thick: f64,
        half_w: f64,
    },
}

impl Shape {
    /// Ellipsoid with the given semi-axes along the columns of `rot` (world directions,
    /// orthonormal).
    pub fn ellipsoid(c: DVec3, semi: DVec3, rot: DMat3) -> Shape {
        PlacedSolid::rotated(Solid::Ellipsoid { radii: semi }, c, rot)
            .map_or(Shape::Nothing, Shape::Solid)
    }

    /// Elliptic cylinder along z, centred on `(cx, cy)` with semi-axes `a` (x) and `b` (y),
    /// between `z0` and `z1`.
    pub fn z_cylinder(cx: f64, cy: f64, a: f64, b: f64, z0: f64, z1: f64) -> Shape {
        let solid = Solid::Cylinder {
            radii: [a, b],
            height: z1 - z0,
        };
        let centre = DVec3::new(cx, cy, 0.5 * (z0 + z1));
        PlacedSolid::rotated(solid, centre, DMat3::IDENTITY).map_or(Shape::Nothing, Shape::Solid)
    }

    /// Rounded box with half-size `half` (rounding included) along the columns of `rot`.
    pub fn rbox(c: DVec3, half: DVec3, round: f64, rot: DMat3) -> Shape {
        let round = round.min(half.min_element());
        Shape::RBox {
            c,
            rt: rot.transpose(),
            half: half - round,
            round,
        }
    }

    pub fn bounds(&self) -> (DVec3, DVec3) {
        match self {
            Shape::Section(s) => s.bounds(),
            Shape::Solid(solid) => solid.bounds(),
            Shape::Nothing => (DVec3::INFINITY, DVec3::NEG_INFINITY),
            Shape::Tube { a, b, ra, rb } => ((*a - *ra).min(*b - *rb), (*a + *ra).max(*b + *rb)),
            Shape::RBox { c, rt, half, round } => {
                let r = rt.transpose();
                let h = *half + *round;
                let ext = r.x_axis.abs() * h.x + r.y_axis.abs() * h.y + r.z_axis.abs() * h.z;
                (*c - ext, *c + ext)
            }
            Shape::Couch {
                y0,
                rc,
                thick,
                half_w,
            } => {
                let rise = rc - (rc * rc - half_w * half_w).max(0.0).sqrt();
                (
                    DVec3::new(-half_w, y0 - rise, -1e4),
                    DVec3::new(*half_w, y0 + thick, 1e4),
                )
            }
        }
    }

    pub fn contains(&self, p: DVec3) -> bool {
        match self {
            Shape::Section(s) => s.contains(p),
            Shape::Solid(solid) => solid.contains(p),
            Shape::Nothing => false,
            Shape::Tube { a, b, ra, rb } => {
                let d = *b - *a;
                let l2 = d.length_squared();
                let t = if l2 > 0.0 {
                    ((p - *a).dot(d) / l2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let r = ra + (rb - ra) * t;
                (p - (*a + d * t)).length_squared() <= r * r
            }
            Shape::RBox { c, rt, half, round } => {
                let q = (*rt * (p - *c)).abs() - *half;
                let out = q.max(DVec3::ZERO).length() + q.max_element().min(0.0);
                out <= *round
            }
            Shape::Couch {
                y0,
                rc,
                thick,
                half_w,
            } => {
                if p.x.abs() > *half_w {
                    return false;
                }
                let top = y0 - (rc - (rc * rc - p.x * p.x).max(0.0).sqrt());
                p.y >= top && p.y <= top + thick
            }
        }
    }
}
