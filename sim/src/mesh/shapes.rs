//! Parametric closed meshes generated in code, centred on the origin of their own frame
//! (mm), counter-clockwise seen from outside. Place them with [`super::Placement`].

use super::{MeshError, Result, TriMesh};
use glam::DVec3;
use std::collections::HashMap;

/// Turns `m` outward if it came out inside out (every generator ends with this).
fn outward(m: TriMesh) -> TriMesh {
    if m.signed_volume() < 0.0 {
        m.flipped()
    } else {
        m
    }
}

fn positive(what: &str, v: f64) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(MeshError::OutOfRange(format!(
            "{what} is {v}; it must be finite and > 0"
        )))
    }
}

/// An axis-aligned box of edge lengths `size` (mm): 8 vertices, 12 triangles.
pub fn cuboid(size: DVec3) -> Result<TriMesh> {
    for (a, s) in size.to_array().into_iter().enumerate() {
        positive(&format!("box size along axis {a}"), s)?;
    }
    let h = size * 0.5;
    let vertices = (0..8)
        .map(|i| {
            DVec3::new(
                if i & 1 == 0 { -h.x } else { h.x },
                if i & 2 == 0 { -h.y } else { h.y },
                if i & 4 == 0 { -h.z } else { h.z },
            )
        })
        .collect();
    let quads = [
        [0, 2, 3, 1], // z−
        [4, 5, 7, 6], // z+
        [0, 1, 5, 4], // y−
        [2, 6, 7, 3], // y+
        [0, 4, 6, 2], // x−
        [1, 3, 7, 5], // x+
    ];
    let triangles = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    Ok(outward(TriMesh {
        vertices,
        triangles,
    }))
}

/// An icosphere of `radius` (mm): an icosahedron whose faces are split in four
/// `subdivisions` times (20·4ⁿ triangles), vertices on the sphere. Inscribed in the sphere.
pub fn icosphere(radius: f64, subdivisions: u32) -> Result<TriMesh> {
    positive("sphere radius", radius)?;
    if subdivisions > 8 {
        return Err(MeshError::OutOfRange(format!(
            "icosphere subdivisions = {subdivisions}; at most 8 (1.3 M triangles)"
        )));
    }
    let p = (1.0 + 5f64.sqrt()) / 2.0;
    let mut vertices: Vec<DVec3> = [
        [-1.0, p, 0.0],
        [1.0, p, 0.0],
        [-1.0, -p, 0.0],
        [1.0, -p, 0.0],
        [0.0, -1.0, p],
        [0.0, 1.0, p],
        [0.0, -1.0, -p],
        [0.0, 1.0, -p],
        [p, 0.0, -1.0],
        [p, 0.0, 1.0],
        [-p, 0.0, -1.0],
        [-p, 0.0, 1.0],
    ]
    .iter()
    .map(|v| DVec3::from(*v).normalize())
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, v: &mut Vec<DVec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                v.push(((v[a as usize] + v[b as usize]) * 0.5).normalize());
                (v.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(triangles.len() * 4);
        for [a, b, c] in triangles {
            let ab = midpoint(a, b, &mut vertices);
            let bc = midpoint(b, c, &mut vertices);
            let ca = midpoint(c, a, &mut vertices);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = next;
    }
    for v in &mut vertices {
        *v *= radius;
    }
    Ok(outward(TriMesh {
        vertices,
        triangles,
    }))
}

/// A UV sphere of `radius` (mm) with `segments` around the z axis (≥ 3) and `rings`
/// from pole to pole (≥ 2); vertices on the sphere.
pub fn uv_sphere(radius: f64, segments: u32, rings: u32) -> Result<TriMesh> {
    positive("sphere radius", radius)?;
    if segments < 3 || rings < 2 {
        return Err(MeshError::OutOfRange(format!(
            "UV sphere needs ≥ 3 segments and ≥ 2 rings, got {segments} and {rings}"
        )));
    }
    let mut vertices = vec![DVec3::new(0.0, 0.0, -radius)];
    for r in 1..rings {
        let th = std::f64::consts::PI * r as f64 / rings as f64;
        for s in 0..segments {
            let ph = std::f64::consts::TAU * s as f64 / segments as f64;
            vertices.push(radius * DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), -th.cos()));
        }
    }
    vertices.push(DVec3::new(0.0, 0.0, radius));
    let triangles = uv_triangles(vertices.len(), segments, rings);
    Ok(outward(TriMesh {
        vertices,
        triangles,
    }))
}

/// A rounded box: the box of half-edges `half` (mm) with every edge and corner rounded to
/// `radius` (the Minkowski sum of a box of half-edges `half − radius` and a ball). Made
/// from a UV sphere of `radius` (`segments` around z, offset half a step, an odd number of
/// `rings`, so no vertex but the poles lies on a coordinate plane) whose vertices move by
/// ±(half − radius) along each axis on their side: the flat faces are spanned by the
/// stretched triangles, vertices lie on the rounded surface.
pub fn rounded_box(half: DVec3, radius: f64, segments: u32, rings: u32) -> Result<TriMesh> {
    positive("rounded box radius", radius)?;
    if !(half.is_finite() && half.min_element() >= radius) {
        return Err(MeshError::OutOfRange(format!(
            "rounded box half-edges {half} must be finite and ≥ the radius {radius}"
        )));
    }
    if segments < 4 || rings < 3 {
        return Err(MeshError::OutOfRange(format!(
            "rounded box needs ≥ 4 segments and ≥ 3 rings, got {segments} and {rings}"
        )));
    }
    let rings = rings | 1; // odd: no ring on z = 0
    let inner = half - DVec3::splat(radius);
    let side = |x: f64| {
        if x > 0.0 {
            1.0
        } else if x < 0.0 {
            -1.0
        } else {
            0.0
        }
    };
    let mut vertices = vec![DVec3::new(0.0, 0.0, -radius)];
    for r in 1..rings {
        let th = std::f64::consts::PI * r as f64 / rings as f64;
        for s in 0..segments {
            let ph = std::f64::consts::TAU * (s as f64 + 0.5) / segments as f64;
            vertices.push(radius * DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), -th.cos()));
        }
    }
    vertices.push(DVec3::new(0.0, 0.0, radius));
    for v in &mut vertices {
        *v += DVec3::new(side(v.x), side(v.y), side(v.z)) * inner;
    }
    let triangles = uv_triangles(vertices.len(), segments, rings);
    Ok(outward(TriMesh {
        vertices,
        triangles,
    }))
}

/// A closed prism: the convex or star-shaped polygon `outline` (x, y; counter-clockwise,
/// mm) swept from z = −height/2 to +height/2, caps fanned from the centroid.
pub fn prism(outline: &[[f64; 2]], height: f64) -> Result<TriMesh> {
    positive("prism height", height)?;
    let n = outline.len() as u32;
    if n < 3 {
        return Err(MeshError::OutOfRange(format!(
            "a prism outline needs ≥ 3 points, got {n}"
        )));
    }
    let h = height / 2.0;
    let mut vertices: Vec<DVec3> = Vec::new();
    for z in [-h, h] {
        vertices.extend(outline.iter().map(|p| DVec3::new(p[0], p[1], z)));
    }
    let c = outline
        .iter()
        .fold([0.0, 0.0], |a, p| [a[0] + p[0], a[1] + p[1]]);
    let c = [c[0] / n as f64, c[1] / n as f64];
    vertices.push(DVec3::new(c[0], c[1], -h));
    vertices.push(DVec3::new(c[0], c[1], h));
    let (cb, ct) = (2 * n, 2 * n + 1);
    let mut triangles = Vec::new();
    for i in 0..n {
        let j = (i + 1) % n;
        triangles.push([cb, j, i]);
        triangles.push([ct, n + i, n + j]);
        triangles.push([i, j, n + j]);
        triangles.push([i, n + j, n + i]);
    }
    Ok(outward(TriMesh {
        vertices,
        triangles,
    }))
}

/// Most sides of a generated cylinder (4 M triangles).
pub const MAX_SEGMENTS: u32 = 1 << 20;

/// A cylinder of `radius` and `height` (mm) along z with `segments` sides (3 to
/// [`MAX_SEGMENTS`]), vertices on the circle (inscribed polygon).
pub fn cylinder(radius: f64, height: f64, segments: u32) -> Result<TriMesh> {
    positive("cylinder radius", radius)?;
    if !(3..=MAX_SEGMENTS).contains(&segments) {
        return Err(MeshError::OutOfRange(format!(
            "cylinder needs 3 to {MAX_SEGMENTS} segments, got {segments} (an exact \
             cylinder needs none: kind = \"cylinder\" without resolution)"
        )));
    }
    let outline: Vec<[f64; 2]> = (0..segments)
        .map(|s| {
            let a = std::f64::consts::TAU * s as f64 / segments as f64;
            [radius * a.cos(), radius * a.sin()]
        })
        .collect();
    prism(&outline, height)
}

/// A closed tube of `radius` (mm, `segments` sides) along the polyline `path` (mm), with
/// flat end caps. Bends must be gentle compared with the radius (no self-overlap).
pub fn tube(path: &[DVec3], radius: f64, segments: u32) -> Result<TriMesh> {
    positive("tube radius", radius)?;
    if path.len() < 2 || segments < 3 {
        return Err(MeshError::OutOfRange(format!(
            "a tube needs ≥ 2 path points and ≥ 3 segments, got {} and {segments}",
            path.len()
        )));
    }
    let n = path.len();
    let tangent = |i: usize| {
        let d = if i == 0 {
            path[1] - path[0]
        } else if i == n - 1 {
            path[n - 1] - path[n - 2]
        } else {
            (path[i + 1] - path[i]).normalize_or_zero()
                + (path[i] - path[i - 1]).normalize_or_zero()
        };
        d.normalize_or_zero()
    };
    let t0 = tangent(0);
    if t0 == DVec3::ZERO {
        return Err(MeshError::OutOfRange(
            "tube path has repeated points".into(),
        ));
    }
    // Parallel-transported frame.
    let mut normal = t0.any_orthonormal_vector();
    let mut vertices = Vec::new();
    for (i, &centre) in path.iter().enumerate() {
        let t = tangent(i);
        if t == DVec3::ZERO {
            return Err(MeshError::OutOfRange(
                "tube path has repeated points".into(),
            ));
        }
        normal = (normal - t * normal.dot(t)).normalize();
        let binormal = t.cross(normal);
        for s in 0..segments {
            let a = std::f64::consts::TAU * s as f64 / segments as f64;
            vertices.push(centre + radius * (a.cos() * normal + a.sin() * binormal));
        }
    }
    let at = |i: u32, s: u32| i * segments + s % segments;
    let mut triangles = Vec::new();
    for i in 0..n as u32 - 1 {
        for s in 0..segments {
            let (a, b, c, d) = (at(i, s), at(i, s + 1), at(i + 1, s + 1), at(i + 1, s));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    vertices.push(path[0]);
    vertices.push(path[n - 1]);
    let (c0, c1) = (vertices.len() as u32 - 2, vertices.len() as u32 - 1);
    let last = n as u32 - 1;
    for s in 0..segments {
        triangles.push([c0, at(0, s + 1), at(0, s)]);
        triangles.push([c1, at(last, s), at(last, s + 1)]);
    }
    Ok(outward(TriMesh {
        vertices,
        triangles,
    }))
}

/// A pacemaker as it lies under the skin of the chest (LPS frame): the can, a rounded
/// slab 50 × 8 × 45 mm (x, y, z; thin front to back), and two leads (tubes of 1 mm radius)
/// leaving its header at +z (towards the head), looping and running 12 cm posterior (+y)
/// into the chest. Returned as `(name, mesh)` pairs, centred on the can.
pub fn pacemaker(segments: u32) -> Result<Vec<(String, TriMesh)>> {
    if segments > MAX_SEGMENTS {
        return Err(MeshError::OutOfRange(format!(
            "pacemaker resolution {segments}; at most {MAX_SEGMENTS}"
        )));
    }
    let segments = segments.max(8);
    // Can outline: a stadium (two half-discs joined by straight sides).
    let (half_w, r) = (25.0, 22.5);
    let mut outline = Vec::new();
    for s in 0..=segments {
        let a = -std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * s as f64 / segments as f64;
        outline.push([half_w - r + r * a.cos(), r * a.sin()]);
    }
    for s in 0..=segments {
        let a = std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * s as f64 / segments as f64;
        outline.push([-(half_w - r) + r * a.cos(), r * a.sin()]);
    }
    // Built flat in x–y with the header at +y, then turned by +90° about x: (x, y, z) →
    // (x, −z, y).
    let turn = |m: TriMesh| {
        outward(TriMesh {
            vertices: m
                .vertices
                .iter()
                .map(|v| DVec3::new(v.x, -v.z, v.y))
                .collect(),
            triangles: m.triangles,
        })
    };
    let can = prism(&outline, 8.0)?;
    let mut out = vec![("pacemaker-can".to_string(), turn(can))];
    for (k, dx) in [(1, -6.0), (2, 6.0)] {
        let path: Vec<DVec3> = (0..=24)
            .map(|i| {
                let s = i as f64 / 24.0;
                let a = std::f64::consts::PI * s; // half loop from +y over to −y
                DVec3::new(dx + 10.0 * s, 23.0 + 12.0 * a.sin(), -3.0 - 120.0 * s * s)
                    + DVec3::new(0.0, -30.0 * (1.0 - a.cos()) * 0.5, 0.0)
            })
            .collect();
        out.push((
            format!("pacemaker-lead-{k}"),
            turn(tube(&path, 1.0, segments.min(16))?),
        ));
    }
    Ok(out)
}

/// A patient table top: a `width` × `length` (x, z; mm) slab `thickness` mm thick (y),
/// its top face slightly curved (sagging 10 % of the thickness at the centre line).
pub fn table_top(width: f64, length: f64, thickness: f64) -> Result<TriMesh> {
    positive("table width", width)?;
    positive("table thickness", thickness)?;
    positive("table length", length)?;
    let n = 16;
    let mut outline = Vec::new();
    for i in 0..=n {
        let x = -width / 2.0 + width * i as f64 / n as f64;
        let sag = 0.1 * thickness * (1.0 - (2.0 * x / width).powi(2));
        outline.push([x, -thickness / 2.0 + sag]); // top face (−y is anterior: up)
    }
    outline.push([width / 2.0, thickness / 2.0]);
    outline.push([-width / 2.0, thickness / 2.0]);
    outline.reverse(); // counter-clockwise in (x, y)
    let slab = prism(&outline, length)?;
    // prism extrudes along z: the table's length runs head–feet (z).
    Ok(slab)
}

/// The triangles of a UV-sphere vertex layout of `n` vertices: the bottom pole (vertex 0),
/// `rings − 1` rings of `segments` vertices, the top pole (the last vertex).
fn uv_triangles(n: usize, segments: u32, rings: u32) -> Vec<[u32; 3]> {
    let top = (n - 1) as u32;
    let ring = |r: u32, s: u32| 1 + (r - 1) * segments + s % segments;
    let mut triangles = Vec::new();
    for s in 0..segments {
        triangles.push([0, ring(1, s + 1), ring(1, s)]);
        triangles.push([top, ring(rings - 1, s), ring(rings - 1, s + 1)]);
        for r in 1..rings - 1 {
            let (a, b, c, d) = (
                ring(r, s),
                ring(r, s + 1),
                ring(r + 1, s + 1),
                ring(r + 1, s),
            );
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    triangles
}
