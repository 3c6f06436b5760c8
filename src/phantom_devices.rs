//! `tomograf phantom --mesh-devices DIR`: the procedural patient's pacemaker and table as
//! closed meshes (OBJ files, world mm) and a scene file that places them over the phantom
//! with their materials, so that `tomograf project --scene DIR/scene.toml` traces them
//! exactly instead of as voxels.

use anyhow::{Context, Result};
use std::path::{Path, PathBuf};
use tomograf_datasets::anatomy::DeviceMesh;
use tomograf_scene::scene::{MeshEntry, VolumeSection};
use tomograf_sim::mesh::io;

/// Writes `DIR/<device>.obj` for each device and `DIR/scene.toml` (a complete scene: the
/// phantom at `phantom` in HU, and one `[[mesh]]` per device with identity placement,
/// its material and density). Every file is written atomically. Returns the scene path.
pub fn write(dir: &Path, phantom: &Path, devices: &[DeviceMesh]) -> Result<PathBuf> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let phantom =
        std::path::absolute(phantom).with_context(|| format!("resolving {}", phantom.display()))?;
    /// The sections of a scene this writes.
    #[derive(serde::Serialize)]
    struct Fragment {
        volume: VolumeSection,
        mesh: Vec<MeshEntry>,
    }
    let mut scene = Fragment {
        volume: VolumeSection {
            path: Some(phantom),
            units: Some("hu".into()),
            ..Default::default()
        },
        mesh: Vec::new(),
    };
    for d in devices {
        let file = format!("{}.obj", d.name);
        io::write_obj(&dir.join(&file), &d.mesh)?;
        scene.mesh.push(MeshEntry {
            name: Some(d.name.clone()),
            path: Some(PathBuf::from(file)),
            material: Some(d.material.clone()),
            density_g_cm3: Some(d.density_g_cm3),
            ..Default::default()
        });
    }
    let text = format!(
        "# The phantom's devices as meshes (world LPS mm, identity placement), written by\n\
         # `tomograf phantom --mesh-devices`. Inside a mesh its material replaces the voxels;\n\
         # later meshes win where meshes overlap. Add [views], [detector], [spectrum], ... as\n\
         # for any scene (docs/meshes.md).\n\n{}",
        toml::to_string(&scene).context("serialising the scene")?
    );
    let path = dir.join("scene.toml");
    let tmp = dir.join("scene.toml.partial");
    std::fs::write(&tmp, text)
        .and_then(|_| std::fs::rename(&tmp, &path))
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(path)
}
