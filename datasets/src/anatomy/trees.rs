//! Airways (trachea, main bronchi, a seeded bronchial tree) with the pulmonary arteries
//! running beside the bronchi, and an independent pulmonary vein tree from the left atrium.
//!
//! The trees fill the lungs by territory splitting (after Kitaoka, Takaki & Suki 1999, *J.
//! Appl. Physiol.* 87:2207): each lung is represented by seeded random points; each root
//! branch owns the points it points at. A branch runs from its start towards the centroid
//! of its territory (30–50 % of the way), then its territory is cut in two by a plane
//! through the centroid, containing the branch and across the territory's widest spread;
//! each half feeds one child. Radii follow Murray's law with flow proportional to the
//! territory (`r_child = r · (n_child / n)^(1/3)`), so they shrink smoothly to the
//! terminal branches. A branch whose end leaves the lung is halved, then dropped.

use super::heart::Heart;
use super::mediastinum::{trachea_radius, trachea_y, z_carina};
use super::patient::{Params, rng, stream};
use super::shapes::Shape;
use super::{Scene, Structure, Tissue};
use glam::DVec3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use std::collections::VecDeque;

/// One tapered segment of a tree.
#[derive(Debug, Clone)]
pub(crate) struct Seg {
    pub a: DVec3,
    pub b: DVec3,
    pub ra: f64,
    pub rb: f64,
    pub parent: Option<usize>,
    pub side: f64,
}

/// A root of a tree: start, preferred direction (to share the lung among roots), radius.
struct Root {
    start: DVec3,
    dir: DVec3,
    r: f64,
}

struct Branch {
    start: DVec3,
    r: f64,
    lo: usize,
    hi: usize,
    parent: Option<usize>,
    root: bool,
    side: f64,
}

/// Seeded points filling the free lung on `side`.
fn lung_points(
    p: &Params,
    side: f64,
    n: usize,
    free: &dyn Fn(DVec3, f64) -> bool,
    rng: &mut ChaCha8Rng,
) -> Vec<DVec3> {
    let mut pts = Vec::with_capacity(n);
    for _ in 0..60 * n {
        if pts.len() == n {
            break;
        }
        let q = DVec3::new(
            side * rng.random_range(0.0..p.a_e),
            rng.random_range(p.ya_e..p.yp_e),
            rng.random_range(p.z_base..p.z_apex),
        );
        if free(q, side) {
            pts.push(q);
        }
    }
    pts
}

/// Unit vector perpendicular to `d` along which `pts` spread most (power iteration on
/// their covariance projected across `d`).
fn widest(pts: &[DVec3], c: DVec3, d: DVec3) -> DVec3 {
    let (mut xx, mut xy, mut xz, mut yy, mut yz, mut zz) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for q in pts {
        let v = *q - c;
        let v = v - d * v.dot(d);
        xx += v.x * v.x;
        xy += v.x * v.y;
        xz += v.x * v.z;
        yy += v.y * v.y;
        yz += v.y * v.z;
        zz += v.z * v.z;
    }
    let mut e = d.any_orthonormal_vector();
    for _ in 0..12 {
        let m = DVec3::new(
            xx * e.x + xy * e.y + xz * e.z,
            xy * e.x + yy * e.y + yz * e.z,
            xz * e.x + yz * e.y + zz * e.z,
        );
        let m = m - d * m.dot(d);
        if m.length_squared() < 1e-18 {
            break;
        }
        e = m.normalize();
    }
    e
}

/// Grows one tree from `roots` over the lung points of each side.
fn grow(
    roots: &[Root],
    points: [Vec<DVec3>; 2],
    r_min: f64,
    free: &dyn Fn(DVec3, f64) -> bool,
    rng: &mut ChaCha8Rng,
) -> Vec<Seg> {
    // Share each lung's points among the roots on that side by direction.
    let mut all = Vec::new();
    let mut queue = VecDeque::new();
    for (pts, side) in points.into_iter().zip([-1.0, 1.0]) {
        let mine: Vec<&Root> = roots.iter().filter(|r| r.dir.x.signum() == side).collect();
        let mut owned: Vec<Vec<DVec3>> = vec![Vec::new(); mine.len()];
        for q in pts {
            let best = (0..mine.len())
                .max_by(|&a, &b| {
                    let score = |r: &Root| (q - r.start).normalize_or_zero().dot(r.dir);
                    score(mine[a]).total_cmp(&score(mine[b]))
                })
                .unwrap_or(0);
            owned[best].push(q);
        }
        for (root, pts) in mine.iter().zip(owned) {
            let lo = all.len();
            all.extend(pts);
            queue.push_back(Branch {
                start: root.start,
                r: root.r,
                lo,
                hi: all.len(),
                parent: None,
                root: true,
                side,
            });
        }
    }
    let mut segs = Vec::new();
    while let Some(br) = queue.pop_front() {
        let pts = &mut all[br.lo..br.hi];
        let n = pts.len();
        if n == 0 {
            continue;
        }
        let c = pts.iter().copied().sum::<DVec3>() / n as f64;
        let to = c - br.start;
        let dist = to.length();
        if dist < 1e-6 {
            continue;
        }
        let d = to / dist;
        let mut len = rng.random_range(0.3..0.5) * dist;
        let mut end = br.start + d * len;
        if !br.root && !free(end, br.side) {
            len *= 0.5;
            end = br.start + d * len;
            if !free(end, br.side) {
                continue;
            }
        }
        let idx = segs.len();
        segs.push(Seg {
            a: br.start,
            b: end,
            ra: br.r,
            rb: 0.97 * br.r,
            parent: br.parent,
            side: br.side,
        });
        if n < 2 {
            continue;
        }
        let e = widest(pts, c, d);
        let mut k = partition(pts, |q| (*q - c).dot(e) < 0.0);
        if k == 0 || k == n {
            k = n / 2;
        }
        for (lo, hi) in [(br.lo, br.lo + k), (br.lo + k, br.hi)] {
            let r = br.r * ((hi - lo) as f64 / n as f64).cbrt();
            if r >= r_min {
                queue.push_back(Branch {
                    start: end,
                    r,
                    lo,
                    hi,
                    parent: Some(idx),
                    root: false,
                    side: br.side,
                });
            }
        }
    }
    segs
}

/// Moves the elements satisfying `pred` to the front; returns how many there are.
fn partition(v: &mut [DVec3], pred: impl Fn(&DVec3) -> bool) -> usize {
    let mut k = 0;
    for i in 0..v.len() {
        if pred(&v[i]) {
            v.swap(i, k);
            k += 1;
        }
    }
    k
}

/// Smallest bronchus drawn (outer radius, mm).
const AIRWAY_MIN_RADIUS: f64 = 1.0;

/// Airways and the pulmonary vessel trees.
pub(crate) struct Airways {
    /// Trachea and main/intermediate bronchi (outer radius; the lumen is 2 mm less).
    main: Vec<Seg>,
    tree: Vec<Seg>,
    arteries: Vec<Seg>,
    veins: Vec<Seg>,
}

impl Airways {
    pub fn new(p: &Params, heart: &Heart, free: &dyn Fn(DVec3, f64) -> bool) -> Self {
        let (s, sv) = (p.s, p.sv);
        let mut r = rng(p.seed, stream::TREES);
        let zc = z_carina(p);
        let x_tr = -2.0 * s;
        let carina = DVec3::new(x_tr, trachea_y(p, zc), zc);
        let top = p.z_neck_top() - 10.0;
        let seg = |a: DVec3, b: DVec3, ra: f64, rb: f64| Seg {
            a,
            b,
            ra,
            rb,
            parent: None,
            side: 0.0,
        };
        let mut main = Vec::new();
        let r_tr = trachea_radius(p);
        let n = 10;
        let pts: Vec<DVec3> = (0..=n)
            .map(|i| {
                let z = top + (zc + 8.0 - top) * i as f64 / n as f64;
                DVec3::new(x_tr, trachea_y(p, z), z)
            })
            .chain([carina])
            .collect();
        for w in pts.windows(2) {
            main.push(seg(w[0], w[1], r_tr, r_tr));
        }
        let r1 = carina + DVec3::new(-28.0, 6.0, -20.0) * s;
        let r2 = r1 + DVec3::new(-6.0, 5.0, -24.0) * s;
        let l1 = carina + DVec3::new(42.0, 10.0, -32.0) * s;
        main.push(seg(carina, r1, 7.5 * sv, 7.0 * sv));
        main.push(seg(r1, r2, 6.0 * sv, 5.8 * sv));
        main.push(seg(carina, l1, 6.8 * sv, 6.4 * sv));
        let lobes = [
            (r1, DVec3::new(-0.75, 0.1, 0.65), 4.8),
            (r2, DVec3::new(-0.55, -0.75, -0.35), 3.8),
            (r2, DVec3::new(-0.35, 0.45, -0.82), 5.2),
            (l1, DVec3::new(0.65, -0.15, 0.75), 5.0),
            (l1, DVec3::new(0.5, -0.75, -0.35), 3.8),
            (l1, DVec3::new(0.35, 0.45, -0.82), 5.2),
        ]
        .map(|(start, dir, r)| Root {
            start,
            dir: dir.normalize(),
            r: r * sv,
        });
        let n_pts = 2700;
        let pts = [-1.0, 1.0].map(|side| lung_points(p, side, n_pts, free, &mut r));
        let tree = grow(&lobes, pts, 0.55, free, &mut r);
        // Arteries run beside the bronchi, on a consistent side of each segment.
        let off = |sg: &Seg| {
            let d = (sg.b - sg.a).normalize_or(DVec3::Z);
            let n = d.cross(DVec3::Z).normalize_or(d.any_orthonormal_vector());
            n * (2.0 * sg.rb + 0.4)
        };
        let arteries = tree
            .iter()
            .map(|sg| {
                let start = match sg.parent {
                    Some(i) => tree[i].b + off(&tree[i]),
                    None => sg.a + off(sg),
                };
                Seg {
                    a: start,
                    b: sg.b + off(sg),
                    ..sg.clone()
                }
            })
            .collect();
        let la = heart.la;
        let vein_roots = [
            (DVec3::new(-22.0, 0.0, 10.0), DVec3::new(-0.85, 0.05, 0.5)),
            (DVec3::new(-22.0, 5.0, -8.0), DVec3::new(-0.85, 0.25, -0.45)),
            (DVec3::new(22.0, 0.0, 10.0), DVec3::new(0.85, 0.05, 0.5)),
            (DVec3::new(22.0, 5.0, -8.0), DVec3::new(0.85, 0.25, -0.45)),
        ]
        .map(|(o, d)| Root {
            start: la + o * s,
            dir: d.normalize(),
            r: 6.5 * sv,
        });
        let pts = [-1.0, 1.0].map(|side| lung_points(p, side, n_pts, free, &mut r));
        let veins = grow(&vein_roots, pts, 0.55, free, &mut r);
        Airways {
            main,
            tree,
            arteries,
            veins,
        }
    }

    /// Start and radius of the root arteries on `side` (where the pulmonary artery
    /// branches connect).
    pub fn artery_roots(&self, side: f64) -> Vec<(DVec3, f64)> {
        self.arteries
            .iter()
            .filter(|a| a.parent.is_none() && a.side == side)
            .map(|a| (a.a, a.ra))
            .collect()
    }

    /// The bronchi that are drawn: the tree down to 1 mm radius (smaller airways are
    /// below CT resolution; the arteries beside them continue).
    fn bronchi(&self) -> impl Iterator<Item = &Seg> {
        self.tree.iter().filter(|s| s.ra >= AIRWAY_MIN_RADIUS)
    }

    /// Phase 8: pulmonary arteries and veins.
    pub fn paint_vessels(&self, sc: &mut Scene) {
        for sg in self.arteries.iter().chain(&self.veins) {
            sc.add(tube(sg, 0.0), Tissue::Blood, Structure::PulmonaryVessel);
        }
    }

    /// Phase 9: airway walls.
    pub fn paint_walls(&self, sc: &mut Scene) {
        for sg in self.main.iter().chain(self.bronchi()) {
            sc.add(tube(sg, 0.0), Tissue::SoftTissue, Structure::AirwayWall);
        }
    }

    /// Phase 12: airway lumens (air).
    pub fn paint_lumens(&self, sc: &mut Scene) {
        for sg in &self.main {
            sc.add(tube(sg, 2.0), Tissue::Air, Structure::AirwayLumen);
        }
        for sg in self.bronchi() {
            let wall = (0.28 * sg.ra).max(0.5);
            sc.add(tube(sg, wall), Tissue::Air, Structure::AirwayLumen);
        }
    }
}

fn tube(sg: &Seg, shrink: f64) -> Shape {
    Shape::Tube {
        a: sg.a,
        b: sg.b,
        ra: (sg.ra - shrink).max(0.2),
        rb: (sg.rb - shrink).max(0.2),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::lungs::Lungs;

    #[test]
    fn trees_fill_the_lungs_with_murray_radii() {
        for seed in [1, 2, 3] {
            let p = Params::sample(seed);
            let lungs = Lungs::new(&p);
            let heart = Heart::new(&p);
            let free = |q: DVec3, side: f64| lungs.side_of(q) == Some(side);
            let aw = Airways::new(&p, &heart, &free);
            for tree in [&aw.tree, &aw.veins] {
                assert!(tree.len() > 1500, "seed {seed}: {} segments", tree.len());
                let mut children: Vec<Vec<usize>> = vec![Vec::new(); tree.len()];
                for (i, sg) in tree.iter().enumerate() {
                    assert!(sg.ra >= 0.55 - 1e-9);
                    if let Some(parent) = sg.parent {
                        assert!(free(sg.b, sg.side), "seed {seed}: segment ends outside");
                        assert!(sg.a.distance(tree[parent].b) < 1e-9);
                        children[parent].push(i);
                    }
                }
                // r³ = Σ rᵢ³ at every complete bifurcation.
                for (i, c) in children.iter().enumerate() {
                    if c.len() == 2 {
                        let sum: f64 = c.iter().map(|&k| tree[k].ra.powi(3)).sum();
                        assert!((sum - tree[i].ra.powi(3)).abs() < 1e-6 * sum);
                    }
                }
                // Both lungs are served.
                assert!(tree.iter().any(|s| s.b.x > 60.0) && tree.iter().any(|s| s.b.x < -60.0));
            }
            assert_eq!(aw.arteries.len(), aw.tree.len());
            assert_eq!(aw.artery_roots(-1.0).len(), 3);
            assert_eq!(aw.artery_roots(1.0).len(), 3);
        }
    }
}
