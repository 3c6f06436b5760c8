//! A placed, checked mesh with its BVH and material, and a scene of several.
//!
//! Per ray the BVH (`obvhs`, f32 boxes grown by a margin) proposes candidate triangles;
//! each is intersected exactly in f64 with the watertight test ([`super::intersect`]);
//! hits are sorted by `t` and a winding count (+1 entering, −1 leaving) gives the
//! intervals inside the mesh. The whole line through the mesh's bounding box is traced,
//! so a ray that starts inside a mesh is handled; intervals are then clipped to the ray's
//! `[t_min, t_max]`.

use super::intersect::{Hit, ShearedRay};
use super::{MeshError, Placement, Result, TriMesh, topology};
use crate::accel::intervals::Interval;
use crate::ray::Ray;
use crate::solid::{PlacedSolid, Solid};
use glam::{DVec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::builder::build_bvh2;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh;
use obvhs::ploc::PlocSearchDistance;
use std::time::Duration;

/// A closed mesh or an analytic solid in the world with its material.
#[derive(Clone)]
pub struct MeshObject {
    /// Name (for messages and per-mesh outputs).
    pub name: String,
    /// Material name (resolved to attenuation by the materials module).
    pub material: String,
    /// Linear attenuation inside the mesh, mm⁻¹, when given explicitly (monochromatic
    /// scenes).
    pub mu_per_mm: Option<f64>,
    /// Density inside the mesh, g/cm³ (polychromatic scenes: the mass thickness of
    /// `material` is density × path length). Set from the material library's nominal
    /// density when `material` is a known name ([`crate::material::by_name`]); override
    /// with [`MeshObject::with_density`].
    pub density_g_cm3: Option<f64>,
    /// Where its surface is.
    surface: Surface,
    lo: DVec3,
    hi: DVec3,
    volume_mm3: f64,
}

/// A mesh object's surface: triangles with their BVHs, or an analytic solid.
#[derive(Clone)]
enum Surface {
    Triangles(Box<Triangles>),
    Analytic(PlacedSolid),
}

/// Triangles (world mm) and the BVHs that find them.
#[derive(Clone)]
struct Triangles {
    /// Triangles (world mm), in the ray BVH's primitive order.
    tris: Vec<[DVec3; 3]>,
    /// The 8-wide compressed BVH rays traverse (about 2× faster than the binary one,
    /// measured by `tomograf bench --accel-only --section meshes`).
    rays: CwBvh,
}

impl std::fmt::Debug for MeshObject {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut d = f.debug_struct("MeshObject");
        d.field("name", &self.name)
            .field("material", &self.material)
            .field("mu_per_mm", &self.mu_per_mm)
            .field("density_g_cm3", &self.density_g_cm3);
        match &self.surface {
            Surface::Triangles(t) => d.field("triangles", &t.tris.len()),
            Surface::Analytic(p) => d.field("primitive", &p.solid),
        };
        d.finish()
    }
}

/// Most triangles in a BVH leaf.
const LEAF_TRIANGLES: u32 = 1;

/// How much the f32 triangle boxes are grown: f32 rounding of coordinates up to a few
/// metres is ~1e-4 mm; 1e-2 mm plus 1e-5 of the coordinate leaves a wide margin.
fn margin(v: f32) -> f32 {
    1e-2 + 1e-5 * v.abs()
}

/// The largest |coordinate| of a placed mesh vertex, mm (1 km): larger meshes are refused,
/// as no imaging scene needs them and the f32 BVH loses them to overflow.
pub const MAX_COORD_MM: f64 = 1e6;

impl MeshObject {
    /// Places `mesh`, checks that it is closed and outward facing ([`topology::check`])
    /// and, when `check_self_intersection`, that no two triangles cross; builds the BVH.
    pub fn new(
        name: &str,
        mesh: &TriMesh,
        placement: &Placement,
        material: &str,
        mu_per_mm: Option<f64>,
        check_self_intersection: bool,
    ) -> Result<Self> {
        check_mu(name, mu_per_mm)?;
        let world = mesh.placed(placement)?;
        if let Some(v) = world
            .vertices
            .iter()
            .find(|v| v.abs().max_element() > MAX_COORD_MM)
        {
            // The BVH is built in f32: far beyond this its boxes overflow to infinity.
            return Err(MeshError::OutOfRange(format!(
                "mesh {name}: a vertex lies at {v} mm, beyond ±{MAX_COORD_MM:e} mm of the \
                 origin; check its size, translation and the file's units (mm)"
            )));
        }
        topology::check(&world).map_err(|e| prefix(name, e))?;
        let aabbs: Vec<Aabb> = (0..world.triangles.len())
            .map(|t| {
                let c = world.corners(t);
                let lo = c[0].min(c[1]).min(c[2]);
                let hi = c[0].max(c[1]).max(c[2]);
                let (lo, hi) = (lo.as_vec3a(), hi.as_vec3a());
                // Grown by 1–2 margins, varied per triangle: equal boxes (a fan's) make the
                // PLOC build merge one pair per pass (65 536-side cylinder: 46 s → 11 s).
                let jitter = 1.0 + super::self_intersection::jitter(t) as f32;
                Aabb::new(
                    lo - Vec3A::from(lo.to_array().map(margin)) * jitter,
                    hi + Vec3A::from(hi.to_array().map(margin)) * jitter,
                )
            })
            .collect();
        // Small leaves: a candidate costs an f64 watertight test, far more than the f32
        // box test of a node (measured: `tomograf bench --accel-only --section meshes`).
        // PLOC pairs each node with its best of one neighbour on either side (not 14): a
        // fan's overlapping boxes made the wider search the build's cost (65 536-side
        // cylinder 2.5-2.8 s → 0.45-0.65 s) while the sphere's and devices' render times
        // stayed within noise (docs/reliability.md, "The mesh self-intersection check").
        let params = BvhBuildParams {
            max_prims_per_leaf: LEAF_TRIANGLES,
            collapse_traversal_cost: 1.0,
            ploc_search_distance: PlocSearchDistance::Minimum,
            ..BvhBuildParams::medium_build()
        };
        let bvh = build_bvh2(&aabbs, params, &mut Duration::default());
        let rays = bvh2_to_cwbvh(&bvh, LEAF_TRIANGLES, true, false);
        let tris = rays
            .primitive_indices
            .iter()
            .map(|&p| world.corners(p as usize))
            .collect();
        let (lo, hi) = world.bounds();
        let object = Self {
            name: name.to_string(),
            material: material.to_string(),
            mu_per_mm,
            density_g_cm3: crate::material::by_name(material).ok().map(|m| m.density()),
            surface: Surface::Triangles(Box::new(Triangles { tris, rays })),
            lo,
            hi,
            volume_mm3: world.signed_volume(),
        };
        if check_self_intersection {
            let (pairs, first) = object.self_intersections();
            if pairs > 0 {
                return Err(prefix(name, MeshError::SelfIntersecting { pairs, first }));
            }
        }
        Ok(object)
    }

    /// An analytic solid ([`Solid`]: box, ellipsoid or sphere, cylinder) placed by
    /// `placement`, whose ray intervals are exact (closed form, no triangles); otherwise
    /// the same as a mesh of `material` (and `mu_per_mm`, mm⁻¹, for the ideal DRR).
    pub fn analytic(
        name: &str,
        primitive: Solid,
        placement: &Placement,
        material: &str,
        mu_per_mm: Option<f64>,
    ) -> Result<Self> {
        check_mu(name, mu_per_mm)?;
        let placed = PlacedSolid::new(primitive, placement.matrix()?)
            .map_err(|e| prefix(name, MeshError::OutOfRange(e)))?;
        let (lo, hi) = placed.bounds();
        Ok(Self {
            name: name.to_string(),
            material: material.to_string(),
            mu_per_mm,
            density_g_cm3: crate::material::by_name(material).ok().map(|m| m.density()),
            volume_mm3: placed.volume_mm3(),
            surface: Surface::Analytic(placed),
            lo,
            hi,
        })
    }

    /// Whether the surface is an analytic solid (exact intervals, no triangles).
    pub fn is_analytic(&self) -> bool {
        matches!(self.surface, Surface::Analytic(_))
    }

    /// The same mesh at density `density_g_cm3` (g/cm³, finite and > 0).
    pub fn with_density(mut self, density_g_cm3: f64) -> Result<Self> {
        if !(density_g_cm3.is_finite() && density_g_cm3 > 0.0) {
            return Err(MeshError::OutOfRange(format!(
                "mesh {}: density {density_g_cm3} g/cm³; it must be finite and > 0",
                self.name
            )));
        }
        self.density_g_cm3 = Some(density_g_cm3);
        Ok(self)
    }

    /// Number of triangles (0 for an analytic solid).
    pub fn triangle_count(&self) -> usize {
        match &self.surface {
            Surface::Triangles(t) => t.tris.len(),
            Surface::Analytic(_) => 0,
        }
    }

    /// Enclosed volume, mm³.
    pub fn volume_mm3(&self) -> f64 {
        self.volume_mm3
    }

    /// World bounding box (mm).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        (self.lo, self.hi)
    }

    /// Heap bytes (triangles and their BVH; 0 for an analytic solid).
    pub fn memory_bytes(&self) -> usize {
        let Surface::Triangles(t) = &self.surface else {
            return 0;
        };
        t.tris.capacity() * std::mem::size_of::<[DVec3; 3]>()
            + t.rays.nodes.capacity() * std::mem::size_of::<obvhs::cwbvh::node::CwBvhNode>()
            + t.rays.primitive_indices.capacity() * 4
    }

    /// The line of `ray` against the bounding box (slab test, f64): `(t0, t1)` or `None`.
    fn box_span(&self, ray: &Ray) -> Option<(f64, f64)> {
        let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
        for a in 0..3 {
            let (o, d) = (ray.origin[a], ray.direction[a]);
            if d == 0.0 {
                if o < self.lo[a] || o > self.hi[a] {
                    return None;
                }
                continue;
            }
            let (p, q) = ((self.lo[a] - o) / d, (self.hi[a] - o) / d);
            t0 = t0.max(p.min(q));
            t1 = t1.min(p.max(q));
        }
        (t1 >= t0).then_some((t0, t1))
    }

    /// All intersections of the line of `ray` with the surface, sorted by `t` (exits
    /// before entries at equal `t`).
    pub fn hits(&self, ray: &Ray, out: &mut Vec<Hit>) {
        out.clear();
        let t = match &self.surface {
            Surface::Triangles(t) => t,
            Surface::Analytic(p) => {
                if let Some((t0, t1)) = p.ray_span(ray) {
                    out.extend([Hit { t: t0, sign: 1 }, Hit { t: t1, sign: -1 }]);
                }
                return;
            }
        };
        let Some((t0, t1)) = self.box_span(ray) else {
            return;
        };
        // The f32 ray starts a little before the box so its coordinates stay small.
        let pad = 1.0 + 1e-6 * (t1 - t0);
        let start = t0 - pad;
        let origin = (ray.origin + start * ray.direction).as_vec3a();
        let len = (t1 - start + pad) as f32;
        // −0 components become +0: the 8-wide BVH picks child order from `d < 0` but
        // inverts `d` with its sign, so a −0 would cull every box.
        let d = Vec3A::from(
            ray.direction
                .as_vec3a()
                .to_array()
                .map(|c| if c == 0.0 { 0.0 } else { c }),
        );
        let r = obvhs::ray::Ray::new(origin, d, 0.0, len);
        let sheared = ShearedRay::new(ray.origin, ray.direction);
        t.rays.ray_traverse_anyhit(r, |_, id| {
            let [a, b, c] = t.tris[id];
            if let Some(h) = sheared.hit(a, b, c) {
                out.push(h);
            }
        });
        out.sort_unstable_by(|x, y| x.t.total_cmp(&y.t).then(x.sign.cmp(&y.sign)));
    }

    /// Intervals of `ray` inside the mesh, clipped to `[t_min, t_max]`, sorted.
    pub fn inside(&self, ray: &Ray, out: &mut Vec<Interval>) {
        self.inside_with(ray, &mut Vec::new(), out);
    }

    /// [`MeshObject::inside`] with a caller's buffer for the hits (reused across rays).
    fn inside_with(&self, ray: &Ray, hits: &mut Vec<Hit>, out: &mut Vec<Interval>) {
        self.hits(ray, hits);
        out.clear();
        let mut winding = 0i32;
        let mut start = 0.0;
        for h in hits.iter() {
            let before = winding;
            winding += h.sign;
            if before <= 0 && winding > 0 {
                start = h.t;
            } else if before > 0 && winding <= 0 {
                let (a, b) = (start.max(ray.t_min), h.t.min(ray.t_max));
                if b > a {
                    out.push(Interval { t0: a, t1: b });
                }
            }
        }
    }

    /// Path length of `ray` inside the mesh, mm.
    pub fn path_length(&self, ray: &Ray) -> f64 {
        let mut v = Vec::new();
        self.inside(ray, &mut v);
        v.iter().map(|i| i.t1 - i.t0).sum()
    }

    /// Pairs of triangles that cross (sharing no vertex position; coplanar overlaps are
    /// not detected; [`super::self_intersection`]): the count and the first pair (indices
    /// in the ray BVH's order; input order is lost). About n log n for n triangles, fans
    /// included. An analytic solid has none.
    pub fn self_intersections(&self) -> (usize, (usize, usize)) {
        match &self.surface {
            Surface::Triangles(t) => super::self_intersection::crossing_pairs(&t.tris),
            Surface::Analytic(_) => (0, (0, 0)),
        }
    }
}

/// Refuses a non-finite or negative explicit attenuation.
fn check_mu(name: &str, mu_per_mm: Option<f64>) -> Result<()> {
    match mu_per_mm {
        Some(mu) if !(mu.is_finite() && mu >= 0.0) => Err(MeshError::OutOfRange(format!(
            "mesh {name}: mu = {mu} mm⁻¹; it must be finite and ≥ 0"
        ))),
        _ => Ok(()),
    }
}

fn prefix(name: &str, e: MeshError) -> MeshError {
    match e {
        MeshError::Invalid(s) => MeshError::Invalid(format!("mesh {name}: {s}")),
        MeshError::OutOfRange(s) => MeshError::OutOfRange(format!("mesh {name}: {s}")),
        other => MeshError::Invalid(format!("mesh {name}: {other}")),
    }
}

/// A mesh's part of one ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshInterval {
    /// Start, mm.
    pub t0: f64,
    /// End, mm.
    pub t1: f64,
    /// Index of the mesh in its [`MeshScene`].
    pub mesh: usize,
}

/// Buffers [`MeshScene::append_intervals`] reuses from ray to ray.
#[derive(Debug, Default)]
pub struct Scratch {
    hits: Vec<Hit>,
    inside: Vec<Interval>,
    all: Vec<MeshInterval>,
    cuts: Vec<f64>,
}

/// Several meshes. Where meshes overlap, the one listed **later** holds the ray (as if
/// painted over the earlier ones); inside any mesh its material replaces the voxels'.
#[derive(Debug, Clone, Default)]
pub struct MeshScene {
    /// The meshes, in priority order (last wins).
    pub objects: Vec<MeshObject>,
}

impl MeshScene {
    /// A scene of `objects`.
    pub fn new(objects: Vec<MeshObject>) -> Self {
        Self { objects }
    }

    /// Whether there are no meshes.
    pub fn is_empty(&self) -> bool {
        self.objects.is_empty()
    }

    /// Checks that every mesh has an explicit `mu_per_mm` (needed by the monochromatic
    /// line integral until materials are resolved by name).
    pub fn require_mu(&self) -> Result<()> {
        match self.objects.iter().find(|o| o.mu_per_mm.is_none()) {
            Some(o) => Err(MeshError::OutOfRange(format!(
                "mesh {} (material {}) has no mu_per_mm; give one to render it",
                o.name, o.material
            ))),
            None => Ok(()),
        }
    }

    /// The distinct material names of the meshes, in order of first appearance, and for
    /// each mesh the index of its material in that list. Per-material tracing gives each
    /// of these names its own mass-thickness column (after the voxel materials), even when
    /// a voxel material has the same name.
    pub fn materials(&self) -> (Vec<String>, Vec<usize>) {
        let mut names: Vec<String> = Vec::new();
        let index = self
            .objects
            .iter()
            .map(|o| match names.iter().position(|n| *n == o.material) {
                Some(i) => i,
                None => {
                    names.push(o.material.clone());
                    names.len() - 1
                }
            })
            .collect();
        (names, index)
    }

    /// The disjoint, sorted intervals of `ray` inside meshes, each with the mesh that
    /// holds it (overlaps resolved: later mesh wins).
    pub fn intervals(&self, ray: &Ray, out: &mut Vec<MeshInterval>) {
        out.clear();
        self.append_intervals(ray, &mut Scratch::default(), out);
    }

    /// [`MeshScene::intervals`] appended to `out`, with buffers reused across rays.
    pub fn append_intervals(&self, ray: &Ray, scratch: &mut Scratch, out: &mut Vec<MeshInterval>) {
        let Scratch {
            hits,
            inside,
            all,
            cuts,
        } = scratch;
        all.clear();
        for (m, o) in self.objects.iter().enumerate() {
            o.inside_with(ray, hits, inside);
            all.extend(inside.iter().map(|i| MeshInterval {
                t0: i.t0,
                t1: i.t1,
                mesh: m,
            }));
        }
        if all.len() <= 1 || self.objects.len() == 1 {
            out.extend_from_slice(all);
            return;
        }
        // Sweep the interval ends; each elementary piece goes to the highest mesh index
        // covering it.
        let first = out.len();
        cuts.clear();
        cuts.extend(all.iter().flat_map(|i| [i.t0, i.t1]));
        cuts.sort_unstable_by(f64::total_cmp);
        cuts.dedup();
        for w in cuts.windows(2) {
            let (a, b) = (w[0], w[1]);
            let owner = all
                .iter()
                .filter(|i| i.t0 <= a && i.t1 >= b)
                .map(|i| i.mesh)
                .max();
            if let Some(mesh) = owner {
                match out[first..].last_mut() {
                    Some(l) if l.mesh == mesh && l.t1 == a => l.t1 = b,
                    _ => out.push(MeshInterval { t0: a, t1: b, mesh }),
                }
            }
        }
    }

    /// Path length of `ray` held by each mesh (mm), after overlaps are resolved.
    pub fn path_lengths(&self, ray: &Ray) -> Vec<f64> {
        let mut v = Vec::new();
        self.intervals(ray, &mut v);
        let mut out = vec![0.0; self.objects.len()];
        for i in &v {
            out[i.mesh] += i.t1 - i.t0;
        }
        out
    }

    /// Σ mu × length over the meshes along `ray` (meshes without `mu_per_mm` add 0;
    /// see [`MeshScene::require_mu`]), and the intervals they hold.
    pub fn line_integral(&self, ray: &Ray, intervals: &mut Vec<MeshInterval>) -> f64 {
        self.intervals(ray, intervals);
        self.mu_integral(intervals)
    }

    /// Σ mu × length over given intervals (from [`MeshScene::intervals`]).
    pub fn mu_integral(&self, intervals: &[MeshInterval]) -> f64 {
        intervals
            .iter()
            .map(|i| self.objects[i.mesh].mu_per_mm.unwrap_or(0.0) * (i.t1 - i.t0))
            .sum()
    }

    /// Heap bytes of all meshes.
    pub fn memory_bytes(&self) -> usize {
        self.objects.iter().map(MeshObject::memory_bytes).sum()
    }
}

/// The parts of the sorted, disjoint `keep` intervals not covered by the sorted, disjoint
/// `remove` intervals.
pub fn subtract(keep: &[Interval], remove: &[MeshInterval], out: &mut Vec<Interval>) {
    out.clear();
    let mut r = 0;
    for k in keep {
        let mut t = k.t0;
        while r < remove.len() && remove[r].t1 <= t {
            r += 1;
        }
        let mut s = r;
        while s < remove.len() && remove[s].t0 < k.t1 {
            if remove[s].t0 > t {
                out.push(Interval {
                    t0: t,
                    t1: remove[s].t0,
                });
            }
            t = t.max(remove[s].t1);
            s += 1;
        }
        if k.t1 > t {
            out.push(Interval { t0: t, t1: k.t1 });
        }
    }
}
