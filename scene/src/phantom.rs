//! Phantom files (`tomograf phantom`): the built-in analytic thorax or a procedural
//! patient ([`tomograf_datasets::anatomy`]) written as NIfTI or a DICOM series in HU, and
//! with `mesh_devices` the patient's pacemaker and table as closed meshes (OBJ files,
//! world mm) with a scene file that places them over the phantom with their materials, so
//! that `tomograf project --scene DIR/scene.toml` traces them exactly instead of as voxels.

use crate::progress::Progress;
use crate::scene::{MeshEntry, VolumeSection};
use crate::volume::{PHANTOM_DIMS, PHANTOM_SPACING, phantom_volume};
use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};
use tomograf_datasets::anatomy::{self, AnatomySpec, DeviceMesh, Profile};
use tomograf_sim::mesh::io;

/// What phantom to write, and where.
#[derive(Debug, Clone, Default)]
pub struct PhantomFile {
    /// Output NIfTI file (.nii or .nii.gz), or with `dicom` a folder for a DICOM CT series.
    pub output: PathBuf,
    /// Write a DICOM CT series (one int16 slice per file, HU rounded) instead of NIfTI.
    pub dicom: bool,
    /// A procedural patient instead of the analytic thorax.
    pub profile: Option<Profile>,
    /// Seed of the procedural patient.
    pub seed: u64,
    /// Add a patient table / a pacemaker with leads (procedural patients only).
    pub table: bool,
    pub pacemaker: bool,
    /// Write the pacemaker and table as meshes into this folder instead of painting them
    /// into the voxels.
    pub mesh_devices: Option<PathBuf>,
    /// Grid (default [`PHANTOM_DIMS`]) and voxel size in mm (default [`PHANTOM_SPACING`]).
    pub dims: Option<[usize; 3]>,
    pub spacing: Option<[f64; 3]>,
}

/// Writes the phantom `p` asks for (and its device meshes, with `mesh_devices`).
pub fn write_phantom(p: &PhantomFile, progress: &dyn Progress) -> Result<()> {
    let dims = p.dims.unwrap_or(PHANTOM_DIMS);
    let spacing = p.spacing.unwrap_or(PHANTOM_SPACING);
    let mut devices = Vec::new();
    let vol = match p.profile {
        Some(profile) => {
            let mut spec = AnatomySpec::new(p.seed, profile, dims, spacing);
            spec.table = p.table;
            spec.pacemaker = p.pacemaker;
            match &p.mesh_devices {
                None => anatomy::generate(&spec)?,
                Some(_) if !(p.table || p.pacemaker) => {
                    bail!(
                        "mesh_devices (--mesh-devices) needs pacemaker or table (--pacemaker, \
                         --table): the devices it writes"
                    )
                }
                Some(_) => {
                    let (vol, meshes) = anatomy::generate_with_device_meshes(&spec)?;
                    devices = meshes;
                    vol
                }
            }
        }
        None => {
            if p.table || p.pacemaker || p.mesh_devices.is_some() {
                bail!(
                    "table, pacemaker and mesh_devices (--table, --pacemaker, --mesh-devices) need a \
                     procedural patient: give profile (--profile) lidc or full-chest"
                );
            }
            if p.seed != 0 {
                bail!(
                    "seed (--seed) {} needs a procedural patient (the analytic thorax has no \
                     seed): give profile (--profile) lidc or full-chest",
                    p.seed
                );
            }
            phantom_volume(dims, spacing)?
        }
    };
    if p.dicom {
        // A fixed UID under the "2.25" (UUID-derived) root: the phantom is the same every time.
        tomograf_datasets::dicom::write_dicom_series(
            &p.output,
            &vol,
            "2.25.3141592653589793238462643383279",
        )?;
    } else {
        tomograf_datasets::nifti::write_nifti(&p.output, &vol)
            .with_context(|| format!("writing {}", p.output.display()))?;
    }
    progress.note(&format!(
        "wrote {} ({}×{}×{} voxels, HU)",
        p.output.display(),
        dims[0],
        dims[1],
        dims[2]
    ));
    if let Some(dir) = &p.mesh_devices {
        let scene = write_devices(dir, &p.output, &devices)?;
        progress.note(&format!(
            "wrote {} device mesh(es) and {}",
            devices.len(),
            scene.display()
        ));
    }
    Ok(())
}

/// Writes `DIR/<device>.obj` for each device and `DIR/scene.toml` (a complete scene: the
/// phantom at `phantom` in HU, and one `[[mesh]]` per device with identity placement,
/// its material and density). Every file is written atomically. Returns the scene path.
pub fn write_devices(dir: &Path, phantom: &Path, devices: &[DeviceMesh]) -> Result<PathBuf> {
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
