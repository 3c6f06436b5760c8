//! Is a mesh a closed, consistently oriented surface — and repairing what can be repaired.
//!
//! A mesh bounds a volume when every edge is shared by exactly two triangles that run
//! along it in opposite directions, no triangle is degenerate, and the signed volume is
//! positive (normals face out). [`check`] reports each violation with its count;
//! [`repair`] merges vertices closer than ε, drops degenerate and duplicate triangles,
//! re-orients triangles consistently per connected component and turns inside-out
//! components outward. It cannot close holes, split edges shared by more than two
//! triangles, or remove self-intersections: those remain errors.

use super::{MeshError, Result, TriMesh};
use glam::DVec3;
use std::collections::{HashMap, VecDeque};

/// Counts of what keeps a mesh from being closed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Defects {
    /// Edges used by one triangle only (holes).
    pub boundary: usize,
    /// Edges used by three or more triangles.
    pub non_manifold: usize,
    /// Edges used twice in the same direction (inconsistent orientation).
    pub inconsistent: usize,
    /// Triangles with a repeated vertex or zero area.
    pub degenerate: usize,
}

impl Defects {
    /// Whether there is nothing to report.
    pub fn is_clean(&self) -> bool {
        *self == Self::default()
    }
}

fn is_degenerate(m: &TriMesh, t: usize) -> bool {
    let [i, j, k] = m.triangles[t];
    if i == j || j == k || k == i {
        return true;
    }
    let [a, b, c] = m.corners(t);
    (b - a).cross(c - a) == DVec3::ZERO
}

/// Directed edge uses: for each undirected edge `(lo, hi)`, how many triangles run along
/// it `lo → hi` and `hi → lo`.
fn edge_uses(m: &TriMesh) -> HashMap<(u32, u32), [u32; 2]> {
    let mut uses: HashMap<(u32, u32), [u32; 2]> = HashMap::with_capacity(m.triangles.len() * 2);
    for t in &m.triangles {
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            if a == b {
                continue;
            }
            let key = (a.min(b), a.max(b));
            uses.entry(key).or_default()[usize::from(a > b)] += 1;
        }
    }
    uses
}

/// Counts the defects of `m` (indices must be valid: [`TriMesh::validate`]).
pub fn defects(m: &TriMesh) -> Defects {
    let mut d = Defects {
        degenerate: (0..m.triangles.len())
            .filter(|&t| is_degenerate(m, t))
            .count(),
        ..Defects::default()
    };
    for [fwd, bwd] in edge_uses(m).into_values() {
        match fwd + bwd {
            1 => d.boundary += 1,
            2 if fwd != 1 => d.inconsistent += 1,
            2 => {}
            _ => d.non_manifold += 1,
        }
    }
    d
}

/// Checks that `m` is valid, closed, consistently oriented and outward facing.
pub fn check(m: &TriMesh) -> Result<()> {
    m.validate()?;
    let d = defects(m);
    if !d.is_clean() {
        let repairable = d.boundary == 0 && d.non_manifold == 0;
        return Err(MeshError::NotClosed {
            boundary: d.boundary,
            non_manifold: d.non_manifold,
            inconsistent: d.inconsistent,
            degenerate: d.degenerate,
            hint: if repairable {
                "; repair can fix orientation and degenerate triangles".into()
            } else {
                "; holes and edges shared by more than two triangles cannot be repaired \
                 automatically (if the holes come from duplicated vertices, repair merges \
                 vertices closer than its ε)"
                    .into()
            },
        });
    }
    let volume = m.signed_volume();
    if volume <= 0.0 {
        return Err(MeshError::InsideOut { volume_mm3: volume });
    }
    Ok(())
}

/// What [`repair`] changed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RepairReport {
    /// Vertices merged into another one.
    pub merged_vertices: usize,
    /// Degenerate or duplicate triangles removed.
    pub removed_triangles: usize,
    /// Triangles whose orientation was reversed.
    pub flipped_triangles: usize,
}

/// Repairs what can be repaired (see the module doc), then [`check`]s the result.
/// `epsilon` (mesh units, ≥ 0) is the distance below which vertices are merged.
pub fn repair(m: &TriMesh, epsilon: f64) -> Result<(TriMesh, RepairReport)> {
    m.validate()?;
    if !(epsilon.is_finite() && epsilon >= 0.0) {
        return Err(MeshError::OutOfRange(format!(
            "vertex merge ε is {epsilon}; it must be finite and ≥ 0"
        )));
    }
    let mut report = RepairReport::default();
    let (mut out, merged) = merge_vertices(m, epsilon);
    report.merged_vertices = merged;
    let before = out.triangles.len();
    let mut seen = std::collections::HashSet::new();
    let mut kept = Vec::with_capacity(before);
    for t in 0..out.triangles.len() {
        let mut key = out.triangles[t];
        key.sort_unstable();
        if !is_degenerate(&out, t) && seen.insert(key) {
            kept.push(out.triangles[t]);
        }
    }
    out.triangles = kept;
    report.removed_triangles = before - out.triangles.len();
    report.flipped_triangles = orient(&mut out);
    check(&out)?;
    Ok((out, report))
}

/// Merges vertices closer than `eps` (a hash grid of cell `eps`); returns the re-indexed
/// mesh (unused vertices dropped) and how many were merged.
fn merge_vertices(m: &TriMesh, eps: f64) -> (TriMesh, usize) {
    let cell = if eps > 0.0 { eps } else { 1.0 };
    let key = |v: DVec3| {
        let q = (v / cell).floor();
        (q.x as i64, q.y as i64, q.z as i64)
    };
    let mut grid: HashMap<(i64, i64, i64), Vec<u32>> = HashMap::new();
    let mut remap = vec![0u32; m.vertices.len()];
    let mut vertices: Vec<DVec3> = Vec::new();
    let mut merged = 0;
    for (i, &v) in m.vertices.iter().enumerate() {
        let (x, y, z) = key(v);
        let mut found = None;
        'search: for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(list) = grid.get(&(x + dx, y + dy, z + dz)) {
                        for &j in list {
                            if vertices[j as usize].distance(v) <= eps {
                                found = Some(j);
                                break 'search;
                            }
                        }
                    }
                }
            }
        }
        remap[i] = match found {
            Some(j) => {
                merged += 1;
                j
            }
            None => {
                vertices.push(v);
                let j = (vertices.len() - 1) as u32;
                grid.entry((x, y, z)).or_default().push(j);
                j
            }
        };
    }
    let triangles = m
        .triangles
        .iter()
        .map(|t| t.map(|i| remap[i as usize]))
        .collect();
    (
        TriMesh {
            vertices,
            triangles,
        },
        merged,
    )
}

/// Orients triangles consistently within each edge-connected component (breadth-first
/// from one triangle), then turns components with negative volume outward. Returns the
/// number of triangles flipped.
fn orient(m: &mut TriMesh) -> usize {
    let n = m.triangles.len();
    let mut by_edge: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (t, tri) in m.triangles.iter().enumerate() {
        for e in 0..3 {
            let (a, b) = (tri[e], tri[(e + 1) % 3]);
            by_edge.entry((a.min(b), a.max(b))).or_default().push(t);
        }
    }
    let runs_forward =
        |tri: [u32; 3], a: u32, b: u32| (0..3).any(|e| tri[e] == a && tri[(e + 1) % 3] == b);
    let mut flip = vec![false; n];
    let mut done = vec![false; n];
    let mut flipped = 0;
    for start in 0..n {
        if done[start] {
            continue;
        }
        let mut component = vec![start];
        done[start] = true;
        let mut queue = VecDeque::from([start]);
        while let Some(t) = queue.pop_front() {
            let mut tri = m.triangles[t];
            if flip[t] {
                tri.swap(1, 2);
            }
            for e in 0..3 {
                let (a, b) = (tri[e], tri[(e + 1) % 3]);
                let Some(list) = by_edge.get(&(a.min(b), a.max(b))) else {
                    continue;
                };
                if list.len() != 2 {
                    continue; // non-manifold or boundary: left to check
                }
                for &u in list {
                    if u != t && !done[u] {
                        done[u] = true;
                        // The neighbour must run b → a.
                        flip[u] = runs_forward(m.triangles[u], a, b);
                        component.push(u);
                        queue.push_back(u);
                    }
                }
            }
        }
        let volume: f64 = component
            .iter()
            .map(|&t| {
                let [a, b, c] = m.corners(t);
                let v = a.dot(b.cross(c));
                if flip[t] { -v } else { v }
            })
            .sum();
        if volume < 0.0 {
            for &t in &component {
                flip[t] = !flip[t];
            }
        }
    }
    for (t, f) in flip.into_iter().enumerate() {
        if f {
            m.triangles[t].swap(1, 2);
            flipped += 1;
        }
    }
    flipped
}
