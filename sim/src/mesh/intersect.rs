//! The watertight ray–triangle test of S. Woop, C. Benthin, I. Wald, "Watertight
//! ray/triangle intersection", JCGT 2(1) 2013, in f64, with a tie-break for rays that pass
//! exactly through an edge or a vertex.
//!
//! The ray is fixed by a shear that maps it onto the +z axis of a permuted frame; every
//! vertex is transformed once, the same way for every triangle that uses it, so the 2-D
//! edge functions of an edge shared by two triangles are exact negatives of each other
//! (`fl(a − b) = −fl(b − a)`): no ray can pass between two triangles (no leak).
//!
//! Woop et al. accept a hit when an edge function is exactly 0, so a ray through a shared
//! edge would hit both triangles (a double count). Here a zero edge function counts only
//! when the edge, oriented as in a front-facing copy of the triangle, is a "top-left" edge
//! of the projection (the rasteriser's rule): an edge shared by two triangles seen from
//! the same side belongs to exactly one of them, and a vertex to exactly one triangle of
//! its fan. An edge on the silhouette (one triangle seen from the front, one from the
//! back) is hit by both or neither — an entry and an exit at the same `t`, zero length.

use glam::DVec3;

/// A ray prepared for the watertight test.
#[derive(Debug, Clone, Copy)]
pub struct ShearedRay {
    origin: DVec3,
    k: [usize; 3],
    shear: [f64; 3],
}

/// One ray–triangle intersection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Ray parameter, mm.
    pub t: f64,
    /// +1 where the ray enters the mesh (triangle faces the ray), −1 where it leaves.
    pub sign: i32,
}

impl ShearedRay {
    /// Prepares the ray `origin + t·dir` (`dir` non-zero; `t` is in units of |dir|).
    pub fn new(origin: DVec3, dir: DVec3) -> Self {
        let a = dir.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        if dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        Self {
            origin,
            k: [kx, ky, kz],
            shear: [dir[kx] / dir[kz], dir[ky] / dir[kz], 1.0 / dir[kz]],
        }
    }

    /// A vertex in the ray's sheared frame (the ray is the +z axis there).
    #[inline(always)]
    pub fn project(&self, v: DVec3) -> DVec3 {
        let a = v - self.origin;
        let [kx, ky, kz] = self.k;
        DVec3::new(
            a[kx] - self.shear[0] * a[kz],
            a[ky] - self.shear[1] * a[kz],
            self.shear[2] * a[kz],
        )
    }

    /// Intersects triangle `(a, b, c)` (counter-clockwise seen from outside).
    #[inline]
    pub fn hit(&self, a: DVec3, b: DVec3, c: DVec3) -> Option<Hit> {
        hit_projected(self.project(a), self.project(b), self.project(c))
    }
}

/// Whether a zero edge function on the edge with 2-D direction `d` counts (top-left).
#[inline(always)]
fn owns(dx: f64, dy: f64) -> bool {
    dy > 0.0 || (dy == 0.0 && dx < 0.0)
}

/// The test on already projected vertices.
#[inline]
pub fn hit_projected(a: DVec3, b: DVec3, c: DVec3) -> Option<Hit> {
    let u = c.x * b.y - c.y * b.x;
    let v = a.x * c.y - a.y * c.x;
    let w = b.x * a.y - b.y * a.x;
    let det = u + v + w;
    if det == 0.0 || det.is_nan() {
        return None;
    }
    let s = det.signum();
    let (su, sv, sw) = (s * u, s * v, s * w);
    if su < 0.0 || sv < 0.0 || sw < 0.0 {
        return None;
    }
    // Edges opposite a, b, c, oriented along the triangle's front-facing order.
    let edge = |p: DVec3, q: DVec3| owns(s * (q.x - p.x), s * (q.y - p.y));
    if (su == 0.0 && !edge(b, c)) || (sv == 0.0 && !edge(c, a)) || (sw == 0.0 && !edge(a, b)) {
        return None;
    }
    let t = (u * a.z + v * b.z + w * c.z) / det;
    Some(Hit {
        t,
        sign: if det > 0.0 { 1 } else { -1 },
    })
}
