//! Closed triangle-mesh objects (implants, devices, the patient table) in the same rays as
//! the voxel volume.
//!
//! * [`TriMesh`] — vertices and triangles in the mesh's own frame; [`Placement`] puts it in
//!   the world (LPS, mm).
//! * [`topology`] — the watertightness check made on load (every edge shared by exactly two
//!   triangles with opposite orientation, outward normals) and [`topology::repair`].
//! * analytic solids — box, ellipsoid (sphere) and cylinder with closed-form ray intervals
//!   ([`crate::solid`]), placed like meshes and used wherever a mesh is
//!   ([`MeshObject::analytic`]).
//! * [`shapes`] — parametric meshes generated in code (box, spheres, cylinder, pacemaker
//!   can with leads, table top).
//! * [`io`] — OBJ, PLY and STL files.
//! * [`intersect`] — the watertight ray–triangle test (Woop, Benthin & Wald 2013) with a
//!   tie-break that counts a ray through an edge or vertex exactly once.
//! * [`object`] — a placed mesh with its BVH (`obvhs`) and material, per-ray path lengths,
//!   and [`object::MeshScene`]: several meshes, their per-ray intervals and how they
//!   displace the voxels.

pub mod intersect;
pub mod io;
pub mod object;
pub mod self_intersection;
pub mod shapes;
pub mod topology;

pub use crate::solid::Solid;
pub use object::{MeshInterval, MeshObject, MeshScene, Scratch};

use glam::{DMat3, DMat4, DVec3};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// What can go wrong with a mesh. Messages name the mesh's problem and its size.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MeshError {
    /// The file could not be read or parsed.
    #[error("cannot read mesh {path}: {reason}")]
    Read {
        /// The file.
        path: String,
        /// What failed.
        reason: String,
    },
    /// The mesh has no triangles, an index out of range or a non-finite coordinate.
    #[error("invalid mesh: {0}")]
    Invalid(String),
    /// The mesh does not bound a volume.
    #[error(
        "mesh is not closed: {boundary} boundary edges (holes), {non_manifold} edges shared by \
         more than two triangles, {inconsistent} edges whose two triangles disagree in \
         orientation, {degenerate} degenerate triangles{hint}"
    )]
    NotClosed {
        /// Edges used by one triangle only.
        boundary: usize,
        /// Edges used by three or more triangles.
        non_manifold: usize,
        /// Edges used twice in the same direction.
        inconsistent: usize,
        /// Triangles with repeated vertices or zero area.
        degenerate: usize,
        /// What to try.
        hint: String,
    },
    /// The triangles face inwards (the enclosed volume is negative).
    #[error(
        "mesh is inside out: its signed volume is {volume_mm3:.6e} mm³ (normals point inwards); use repair"
    )]
    InsideOut {
        /// Signed volume, mm³.
        volume_mm3: f64,
    },
    /// Triangles cross each other.
    #[error("mesh intersects itself: {pairs} pairs of triangles cross (e.g. triangles {first:?})")]
    SelfIntersecting {
        /// Crossing pairs found.
        pairs: usize,
        /// One crossing pair.
        first: (usize, usize),
    },
    /// A placement or parameter is unusable.
    #[error("out of range: {0}")]
    OutOfRange(String),
}

/// Result alias for meshes.
pub type Result<T> = std::result::Result<T, MeshError>;

/// A triangle mesh: vertex positions and counter-clockwise (seen from outside) triangles.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TriMesh {
    /// Vertex positions (mesh frame; mm once placed).
    pub vertices: Vec<DVec3>,
    /// Vertex indices per triangle, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    /// Checks indices and coordinates (not topology: see [`topology::check`]).
    pub fn validate(&self) -> Result<()> {
        if self.triangles.is_empty() {
            return Err(MeshError::Invalid("it has no triangles".into()));
        }
        if let Some(i) = self.vertices.iter().position(|v| !v.is_finite()) {
            return Err(MeshError::Invalid(format!(
                "vertex {i} has a non-finite coordinate {}",
                self.vertices[i]
            )));
        }
        let n = self.vertices.len();
        if let Some(t) = self
            .triangles
            .iter()
            .position(|t| t.iter().any(|&i| i as usize >= n))
        {
            return Err(MeshError::Invalid(format!(
                "triangle {t} uses vertex index {:?} but there are {n} vertices",
                self.triangles[t]
            )));
        }
        Ok(())
    }

    /// The three corners of triangle `t`.
    #[inline]
    pub fn corners(&self, t: usize) -> [DVec3; 3] {
        self.triangles[t].map(|i| self.vertices[i as usize])
    }

    /// Signed enclosed volume (mm³ for a placed mesh): positive when normals face out.
    pub fn signed_volume(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| {
                let [a, b, c] = self.corners(t);
                a.dot(b.cross(c))
            })
            .sum::<f64>()
            / 6.0
    }

    /// The mesh with every triangle's orientation reversed.
    pub fn flipped(mut self) -> Self {
        for t in &mut self.triangles {
            t.swap(1, 2);
        }
        self
    }

    /// Appends `other` (a second closed component).
    pub fn append(&mut self, other: &TriMesh) {
        let base = self.vertices.len() as u32;
        self.vertices.extend_from_slice(&other.vertices);
        self.triangles
            .extend(other.triangles.iter().map(|t| t.map(|i| i + base)));
    }

    /// The mesh moved by `placement` (orientation kept outward for mirroring placements).
    pub fn placed(&self, placement: &Placement) -> Result<TriMesh> {
        let m = placement.matrix()?;
        let mut out = TriMesh {
            vertices: self
                .vertices
                .iter()
                .map(|&v| m.transform_point3(v))
                .collect(),
            triangles: self.triangles.clone(),
        };
        if DMat3::from_mat4(m).determinant() < 0.0 {
            out = out.flipped();
        }
        Ok(out)
    }

    /// Smallest and largest corner of the vertices' bounding box.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        self.vertices.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), &v| (lo.min(v), hi.max(v)),
        )
    }
}

/// Where a mesh sits in the world (LPS, mm): `world = rotation · (scale ⊙ p) + translation`,
/// or a general affine matrix.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Placement {
    /// Rotation (Euler angles about x, then y, then z, degrees), per-axis scale (mesh
    /// units → mm) and translation (mm).
    Pose {
        /// Rotation about world x, y, z (applied in that order), degrees.
        #[serde(default)]
        rotation_deg: [f64; 3],
        /// Scale per mesh axis (e.g. 1000 for a mesh in metres).
        #[serde(default = "unit_scale")]
        scale: [f64; 3],
        /// Translation, mm.
        #[serde(default)]
        translation_mm: [f64; 3],
    },
    /// A 4×4 affine matrix, row-major, last row `[0, 0, 0, 1]`, acting on column vectors.
    Matrix {
        /// Rows of the matrix.
        matrix: [[f64; 4]; 4],
    },
}

fn unit_scale() -> [f64; 3] {
    [1.0; 3]
}

impl Default for Placement {
    fn default() -> Self {
        Self::Pose {
            rotation_deg: [0.0; 3],
            scale: [1.0; 3],
            translation_mm: [0.0; 3],
        }
    }
}

impl Placement {
    /// A translation only.
    pub fn translation(t: DVec3) -> Self {
        Self::Pose {
            rotation_deg: [0.0; 3],
            scale: [1.0; 3],
            translation_mm: t.to_array(),
        }
    }

    /// The affine matrix; refuses non-finite, singular or non-affine ones.
    pub fn matrix(&self) -> Result<DMat4> {
        let m = match *self {
            Self::Pose {
                rotation_deg: r,
                scale: s,
                translation_mm: t,
            } => {
                let rot = DMat3::from_rotation_z(r[2].to_radians())
                    * DMat3::from_rotation_y(r[1].to_radians())
                    * DMat3::from_rotation_x(r[0].to_radians());
                DMat4::from_mat3_translation(
                    rot * DMat3::from_diagonal(DVec3::from(s)),
                    DVec3::from(t),
                )
            }
            Self::Matrix { matrix } => DMat4::from_cols_array_2d(&matrix).transpose(),
        };
        if !m.is_finite() {
            return Err(MeshError::OutOfRange(format!(
                "placement {m} is not finite"
            )));
        }
        if m.row(3) != glam::DVec4::new(0.0, 0.0, 0.0, 1.0) {
            return Err(MeshError::OutOfRange(format!(
                "placement's last row is {}; an affine matrix has [0, 0, 0, 1]",
                m.row(3)
            )));
        }
        let det = DMat3::from_mat4(m).determinant();
        if det.abs() < 1e-12 {
            return Err(MeshError::OutOfRange(format!(
                "placement is singular (determinant {det:e}): a scale is 0"
            )));
        }
        Ok(m)
    }
}
