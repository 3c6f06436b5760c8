//! Whether a closed triangle mesh crosses itself: pairs of triangles that share no vertex
//! and of which an edge of one passes through the interior of the other.
//!
//! Candidates come from box queries, and two triangles that share a vertex are never a
//! crossing pair. A box query alone is quadratic on a **fan** — the cap of a cylinder or
//! cone exported as n triangles around one centre vertex: every triangle's box holds the
//! centre, so every box meets every other (measured before this module: 16 384 sides
//! 14.7 s, 32 768 over a minute). So the triangles around each vertex of high valence form
//! a group with its own BVH; a triangle never queries a group whose vertex it holds (all
//! of that group shares a vertex with it), and a node is entered only when its box meets
//! the query triangle's box and plane, so the pairs tested are about those that are near.
//! (The BVH builds themselves are still superlinear on fans: docs/reliability.md.)
//!
//! Positions are compared exactly (f64 bits, −0 = +0): two corners at the same position
//! are one vertex.

use glam::{DVec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::builder::build_bvh2;
use obvhs::ploc::PlocSearchDistance;
use rayon::prelude::*;
use std::collections::HashMap;
use std::time::Duration;

/// A vertex shared by at least this many triangles gets its own group.
const FAN_VALENCE: usize = 32;

/// At most this many groups (the vertices of highest valence); the rest of the triangles
/// are queried as ordinary ones.
const MAX_FANS: usize = 64;

/// Tolerance of the box and plane tests, mm: the f32 boxes are grown by this plus 1e-5 of
/// the coordinate (f32 rounding of coordinates up to a few metres is ~1e-4 mm).
const SLACK_MM: f64 = 1e-2;

/// The box of `lo..hi` grown by the slack times `1 + jitter` (`jitter` in [0, 1), from the
/// triangle's index: equal boxes make obvhs's PLOC build merge one pair per pass, so a fan's
/// build is quadratic without it).
fn grown(lo: DVec3, hi: DVec3, jitter: f64) -> Aabb {
    let g = |v: DVec3, s: f64| {
        Vec3A::from(
            v.to_array()
                .map(|x| (x + s * (1.0 + jitter) * (SLACK_MM + 1e-5 * x.abs())) as f32),
        )
    };
    Aabb::new(g(lo, -1.0), g(hi, 1.0))
}

/// A number in [0, 1) from `i` (Fibonacci hashing).
pub(super) fn jitter(i: usize) -> f64 {
    f64::from((i as u32).wrapping_mul(0x9E37_79B9)) / 4_294_967_296.0
}

/// One group: its triangles (indices into the mesh) and their BVH.
struct Group {
    /// The vertex every triangle of the group holds (`None`: the ordinary triangles).
    vertex: Option<u32>,
    members: Vec<u32>,
    bvh: Bvh2,
}

/// Counts the crossing pairs of `tris` (world mm) and returns one of them, the smallest
/// `(i, j)` with `i < j` (indices into `tris`); `(0, (0, 0))` when none cross. The result does
/// not depend on the thread count.
pub fn crossing_pairs(tris: &[[DVec3; 3]]) -> (usize, (usize, usize)) {
    let ids = vertex_ids(tris);
    let mut valence: HashMap<u32, usize> = HashMap::new();
    for t in &ids {
        for &v in t {
            *valence.entry(v).or_default() += 1;
        }
    }
    let mut fans: Vec<(usize, u32)> = valence
        .iter()
        .filter(|&(_, &n)| n >= FAN_VALENCE)
        .map(|(&v, &n)| (n, v))
        .collect();
    fans.sort_unstable_by(|a, b| b.cmp(a));
    fans.truncate(MAX_FANS);
    // Group of each triangle: the first fan (highest valence) it holds; ordinary last.
    let ordinary = fans.len();
    let group_of: Vec<usize> = ids
        .iter()
        .map(|t| {
            fans.iter()
                .position(|(_, v)| t.contains(v))
                .unwrap_or(ordinary)
        })
        .collect();
    let mut members = vec![Vec::new(); fans.len() + 1];
    for (i, &g) in group_of.iter().enumerate() {
        members[g].push(i as u32);
    }
    let groups: Vec<Group> = members
        .into_iter()
        .enumerate()
        .map(|(g, members)| {
            let boxes: Vec<Aabb> = members
                .iter()
                .map(|&i| {
                    let t = &tris[i as usize];
                    grown(
                        t[0].min(t[1]).min(t[2]),
                        t[0].max(t[1]).max(t[2]),
                        jitter(i as usize),
                    )
                })
                .collect();
            let bvh = if boxes.is_empty() {
                Bvh2::default()
            } else {
                // One neighbour each side in PLOC's search: a fan's boxes all overlap, and
                // the wider search was most of the build (65 536 sides: check 2.1 → 1.4 s).
                build_bvh2(
                    &boxes,
                    BvhBuildParams {
                        ploc_search_distance: PlocSearchDistance::Minimum,
                        ..BvhBuildParams::fast_build()
                    },
                    &mut Duration::default(),
                )
            };
            Group {
                vertex: fans.get(g).map(|&(_, v)| v),
                members,
                bvh,
            }
        })
        .collect();

    let found: Vec<(usize, Option<(usize, usize)>)> = (0..tris.len())
        .into_par_iter()
        .map(|i| {
            let mut count = 0;
            let mut first: Option<(usize, usize)> = None;
            let own = group_of[i];
            // Groups after one's own (each pair of groups is visited from one side); within
            // the ordinary group, partners after oneself. A group whose vertex the triangle
            // holds shares it with all its members: skipped.
            for (g, group) in groups.iter().enumerate().skip(own) {
                if g == own && g != ordinary {
                    continue;
                }
                if group.vertex.is_some_and(|v| ids[i].contains(&v)) {
                    continue;
                }
                query(&group.bvh, &tris[i], |prim| {
                    let j = group.members[prim] as usize;
                    if (own == ordinary && j <= i) || !triangles_cross(&tris[i], &tris[j]) {
                        return;
                    }
                    count += 1;
                    let pair = (i.min(j), i.max(j));
                    first = Some(first.map_or(pair, |f| f.min(pair)));
                });
            }
            (count, first)
        })
        .collect();
    let count = found.iter().map(|f| f.0).sum();
    let first = found.iter().filter_map(|f| f.1).min().unwrap_or((0, 0));
    (count, first)
}

/// Vertex ids of each triangle's corners (equal positions, equal ids).
fn vertex_ids(tris: &[[DVec3; 3]]) -> Vec<[u32; 3]> {
    let mut index: HashMap<[u64; 3], u32> = HashMap::new();
    tris.iter()
        .map(|t| {
            t.map(|p| {
                let key = p.to_array().map(|x| (x + 0.0).to_bits());
                let next = index.len() as u32;
                *index.entry(key).or_insert(next)
            })
        })
        .collect()
}

/// Calls `leaf(primitive)` for every primitive of `bvh` whose node boxes meet the box and
/// the plane of `tri` (within [`SLACK_MM`]).
fn query(bvh: &Bvh2, tri: &[DVec3; 3], mut leaf: impl FnMut(usize)) {
    if bvh.nodes.is_empty() {
        return;
    }
    let lo = tri[0].min(tri[1]).min(tri[2]);
    let hi = tri[0].max(tri[1]).max(tri[2]);
    let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
    let d = n.dot(tri[0]);
    let meets = |b: &Aabb| {
        let (bl, bh) = (b.min.as_dvec3(), b.max.as_dvec3());
        let slack = 2.0 * (SLACK_MM + 1e-5 * lo.abs().max(hi.abs()).max_element());
        if (bl - hi).max_element() > slack || (lo - bh).max_element() > slack {
            return false;
        }
        // Plane against box: the box's extent along n covers the plane's offset.
        let (c, e) = ((bl + bh) * 0.5, (bh - bl) * 0.5);
        (n.dot(c) - d).abs() <= e.dot(n.abs()) + slack * n.length() * 2.0
    };
    let mut stack = vec![0u32];
    while let Some(index) = stack.pop() {
        let node = &bvh.nodes[index as usize];
        if !meets(&node.aabb) {
            continue;
        }
        if node.is_leaf() {
            for k in node.first_index..node.first_index + node.prim_count {
                leaf(bvh.primitive_indices[k as usize] as usize);
            }
        } else {
            stack.extend([node.first_index, node.first_index + 1]);
        }
    }
}

/// Whether two triangles that share no vertex cross: an edge of one passes through the
/// interior of the other (f64; touching at a single point counts as crossing only when
/// strictly inside).
fn triangles_cross(p: &[DVec3; 3], q: &[DVec3; 3]) -> bool {
    if p.iter().any(|a| q.contains(a)) {
        return false;
    }
    let edge_hits = |s: &[DVec3; 3], t: &[DVec3; 3]| {
        (0..3).any(|e| segment_hits_triangle(s[e], s[(e + 1) % 3], t))
    };
    edge_hits(p, q) || edge_hits(q, p)
}

fn segment_hits_triangle(a: DVec3, b: DVec3, t: &[DVec3; 3]) -> bool {
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    let (da, db) = (n.dot(a - t[0]), n.dot(b - t[0]));
    if da * db >= 0.0 {
        return false; // both on one side, or touching/coplanar
    }
    let p = a + (b - a) * (da / (da - db));
    (0..3).all(|e| {
        let (u, v) = (t[e], t[(e + 1) % 3]);
        n.dot((v - u).cross(p - u)) > 0.0
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes;
    use crate::mesh::{Placement, TriMesh};

    fn triangles(m: &TriMesh) -> Vec<[DVec3; 3]> {
        (0..m.triangles.len()).map(|t| m.corners(t)).collect()
    }

    /// Every pair, no boxes, no groups.
    fn every_pair(tris: &[[DVec3; 3]]) -> (usize, (usize, usize)) {
        let mut found = (0, None);
        for i in 0..tris.len() {
            for j in i + 1..tris.len() {
                if triangles_cross(&tris[i], &tris[j]) {
                    found.0 += 1;
                    found.1.get_or_insert((i, j));
                }
            }
        }
        (found.0, found.1.unwrap_or((0, 0)))
    }

    fn placed(m: &TriMesh, rotation_deg: [f64; 3], t: [f64; 3]) -> TriMesh {
        m.placed(&Placement::Pose {
            rotation_deg,
            scale: [1.0; 3],
            translation_mm: t,
        })
        .unwrap()
    }

    #[test]
    fn fans_find_what_every_pair_finds() {
        // Cylinders (two fans each, 96 sides: groups of 96) crossing each other and a
        // cube, side through cap, cap through cap; and one apart from the others.
        let cyl = shapes::cylinder(10.0, 30.0, 96).unwrap();
        let cube = shapes::cuboid(DVec3::splat(8.0)).unwrap();
        let cases: Vec<Vec<TriMesh>> = vec![
            vec![
                cyl.clone(),
                placed(&cyl, [90.0, 0.0, 0.0], [0.0, 0.0, 12.0]),
            ],
            vec![cyl.clone(), placed(&cyl, [0.0, 0.0, 7.0], [4.0, 3.0, 20.0])],
            vec![
                cyl.clone(),
                placed(&cube, [10.0, 20.0, 30.0], [0.0, 9.0, 15.0]),
            ],
            vec![cyl.clone(), placed(&cyl, [0.0, 0.0, 0.0], [25.0, 0.0, 0.0])],
        ];
        let mut crossing = 0;
        for (k, parts) in cases.iter().enumerate() {
            let mut m = parts[0].clone();
            for p in &parts[1..] {
                m.append(p);
            }
            let tris = triangles(&m);
            let expected = every_pair(&tris);
            assert_eq!(crossing_pairs(&tris), expected, "case {k}");
            crossing += usize::from(expected.0 > 0);
        }
        assert_eq!(crossing, 3, "three of the four cases cross");
    }

    #[test]
    fn a_cylinders_fans_do_not_cross() {
        // 4096 sides: two caps of 4096 triangles around one vertex each; every pair of a cap
        // shares its centre, and no pair of the cylinder crosses.
        let m = shapes::cylinder(50.0, 20.0, 4096).unwrap();
        assert_eq!(crossing_pairs(&triangles(&m)), (0, (0, 0)));
    }
}
