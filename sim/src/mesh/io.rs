//! Mesh files: Wavefront OBJ (`tobj`), PLY ASCII/binary (`ply-rs-bw`) and STL ASCII/binary
//! (`stl_io`), chosen by extension. Only positions and triangle (or polygon, fanned)
//! indices are read; units are the file's (scale them with [`super::Placement`]).

use super::{MeshError, Result, TriMesh};
use glam::DVec3;
use std::path::Path;

fn read_err(path: &Path, reason: impl ToString) -> MeshError {
    MeshError::Read {
        path: path.display().to_string(),
        reason: reason.to_string(),
    }
}

/// Reads `path` (`.obj`, `.ply` or `.stl`, any case). Checks indices and coordinates, not
/// topology (see [`super::topology`]).
pub fn load(path: &Path) -> Result<TriMesh> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let mesh = match ext.as_str() {
        "obj" => load_obj(path)?,
        "ply" => load_ply(path)?,
        "stl" => load_stl(path)?,
        _ => {
            return Err(read_err(
                path,
                format!("unknown extension '{ext}'; expected .obj, .ply or .stl"),
            ));
        }
    };
    mesh.validate().map_err(|e| read_err(path, e.to_string()))?;
    Ok(mesh)
}

/// Writes `mesh` as a Wavefront OBJ file (positions with every digit, triangles; 1-based
/// indices), atomically: to a temporary file in the same folder, then renamed.
pub fn write_obj(path: &Path, mesh: &TriMesh) -> Result<()> {
    use std::fmt::Write as _;
    mesh.validate().map_err(|e| read_err(path, e.to_string()))?;
    let mut text = String::with_capacity(48 * (mesh.vertices.len() + mesh.triangles.len()));
    for v in &mesh.vertices {
        let _ = writeln!(text, "v {} {} {}", v.x, v.y, v.z);
    }
    for t in &mesh.triangles {
        let _ = writeln!(text, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    let tmp = path.with_extension("obj.partial");
    std::fs::write(&tmp, text)
        .and_then(|_| std::fs::rename(&tmp, path))
        .map_err(|e| MeshError::Read {
            path: path.display().to_string(),
            reason: format!("cannot write: {e}"),
        })
}

fn load_obj(path: &Path) -> Result<TriMesh> {
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _) = tobj::load_obj(path, &opts).map_err(|e| read_err(path, e))?;
    let mut mesh = TriMesh::default();
    for m in models {
        let part = TriMesh {
            vertices: m
                .mesh
                .positions
                .chunks_exact(3)
                .map(|p| DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
                .collect(),
            triangles: m
                .mesh
                .indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect(),
        };
        mesh.append(&part);
    }
    Ok(mesh)
}

fn load_stl(path: &Path) -> Result<TriMesh> {
    let mut f = std::fs::File::open(path).map_err(|e| read_err(path, e))?;
    let m = stl_io::read_stl(&mut f).map_err(|e| {
        let ends_early = e.kind() == std::io::ErrorKind::UnexpectedEof;
        read_err(
            path,
            if ends_early {
                format!("the STL file ends early (truncated): {e}")
            } else {
                e.to_string()
            },
        )
    })?;
    Ok(TriMesh {
        vertices: m
            .vertices
            .iter()
            .map(|v| DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2])))
            .collect(),
        triangles: m
            .faces
            .iter()
            .map(|f| f.vertices.map(|i| i as u32))
            .collect(),
    })
}

fn load_ply(path: &Path) -> Result<TriMesh> {
    use ply_rs_bw::parser::Parser;
    use ply_rs_bw::ply::{DefaultElement, Property};
    let f = std::fs::File::open(path).map_err(|e| read_err(path, e))?;
    let mut r = std::io::BufReader::new(f);
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut r)
        .map_err(|e| read_err(path, e))?;
    let scalar = |p: Option<&Property>| -> Option<f64> {
        Some(match p? {
            Property::Float(v) => f64::from(*v),
            Property::Double(v) => *v,
            Property::Int(v) => f64::from(*v),
            Property::UInt(v) => f64::from(*v),
            Property::Short(v) => f64::from(*v),
            Property::UShort(v) => f64::from(*v),
            Property::Char(v) => f64::from(*v),
            Property::UChar(v) => f64::from(*v),
            _ => return None,
        })
    };
    let empty = Vec::new();
    let verts = ply.payload.get("vertex").unwrap_or(&empty);
    let mut mesh = TriMesh::default();
    for (i, v) in verts.iter().enumerate() {
        let c = ["x", "y", "z"].map(|k| scalar(v.get(k)));
        let [Some(x), Some(y), Some(z)] = c else {
            return Err(read_err(
                path,
                format!("vertex {i} lacks a numeric x, y or z"),
            ));
        };
        mesh.vertices.push(DVec3::new(x, y, z));
    }
    let faces = ply.payload.get("face").unwrap_or(&empty);
    for (i, f) in faces.iter().enumerate() {
        let list = f.get("vertex_indices").or_else(|| f.get("vertex_index"));
        let idx: Vec<i64> = match list {
            Some(Property::ListInt(v)) => v.iter().map(|&x| i64::from(x)).collect(),
            Some(Property::ListUInt(v)) => v.iter().map(|&x| i64::from(x)).collect(),
            Some(Property::ListShort(v)) => v.iter().map(|&x| i64::from(x)).collect(),
            Some(Property::ListUShort(v)) => v.iter().map(|&x| i64::from(x)).collect(),
            Some(Property::ListChar(v)) => v.iter().map(|&x| i64::from(x)).collect(),
            Some(Property::ListUChar(v)) => v.iter().map(|&x| i64::from(x)).collect(),
            _ => {
                return Err(read_err(
                    path,
                    format!("face {i} has no integer vertex_indices list"),
                ));
            }
        };
        if idx.len() < 3 || idx.iter().any(|&x| x < 0 || x > i64::from(u32::MAX)) {
            return Err(read_err(path, format!("face {i} has indices {idx:?}")));
        }
        for k in 1..idx.len() - 1 {
            mesh.triangles
                .push([idx[0] as u32, idx[k] as u32, idx[k + 1] as u32]);
        }
    }
    Ok(mesh)
}
