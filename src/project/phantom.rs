//! `tomograf phantom` (write the built-in or a procedural phantom) and `tomograf scan`.

use super::{grid_dims, parse3};
use tomograf_scene::volume::{PHANTOM_DIMS, PHANTOM_SPACING, phantom_volume};

use anyhow::{Context, Result, bail};
use clap::Args;
use std::path::PathBuf;
use tomograf_datasets::anatomy::{self, AnatomySpec, Profile};

#[derive(Debug, Args)]
pub struct PhantomArgs {
    /// Output NIfTI file (.nii or .nii.gz), or with --dicom a folder for a DICOM CT series.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Write a DICOM CT series (one int16 slice per file, HU rounded) instead of NIfTI.
    #[arg(long)]
    pub dicom: bool,
    /// A procedural patient instead of the analytic thorax: lidc (cropped to the thorax,
    /// like LIDC-IDRI) or full-chest (arms, neck, whole chest wall).
    #[arg(long)]
    pub profile: Option<String>,
    /// Seed of the procedural patient.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Add a patient table under the procedural patient.
    #[arg(long)]
    pub table: bool,
    /// Add a pacemaker with leads to the procedural patient.
    #[arg(long)]
    pub pacemaker: bool,
    /// Write the pacemaker and table as mesh files (OBJ) in this folder, with a scene
    /// (DIR/scene.toml) that places them over the phantom, instead of painting them into
    /// the voxels.
    #[arg(long, value_name = "DIR")]
    pub mesh_devices: Option<PathBuf>,
    /// Grid NX,NY,NZ [default: 256,256,133].
    #[arg(long, value_parser = parse3)]
    pub dims: Option<[f64; 3]>,
    /// Voxel size, mm [default: 1.4,1.4,2.5].
    #[arg(long, value_parser = parse3)]
    pub spacing: Option<[f64; 3]>,
}

pub fn write_phantom(args: PhantomArgs) -> Result<()> {
    let dims = args
        .dims
        .map(grid_dims)
        .transpose()?
        .unwrap_or(PHANTOM_DIMS);
    let spacing = args.spacing.unwrap_or(PHANTOM_SPACING);
    let mut devices = Vec::new();
    let vol = match &args.profile {
        Some(profile) => {
            let mut spec = AnatomySpec::new(args.seed, Profile::parse(profile)?, dims, spacing);
            spec.table = args.table;
            spec.pacemaker = args.pacemaker;
            match &args.mesh_devices {
                None => anatomy::generate(&spec)?,
                Some(_) if !(args.table || args.pacemaker) => {
                    bail!("--mesh-devices needs --pacemaker or --table (the devices it writes)")
                }
                Some(_) => {
                    let (vol, meshes) = anatomy::generate_with_device_meshes(&spec)?;
                    devices = meshes;
                    vol
                }
            }
        }
        None => {
            if args.table || args.pacemaker || args.mesh_devices.is_some() {
                bail!(
                    "--table, --pacemaker and --mesh-devices need a procedural patient: give --profile lidc or full-chest"
                );
            }
            phantom_volume(dims, spacing)?
        }
    };
    if args.dicom {
        // A fixed UID under the "2.25" (UUID-derived) root: the phantom is the same every time.
        tomograf_datasets::dicom::write_dicom_series(
            &args.output,
            &vol,
            "2.25.3141592653589793238462643383279",
        )?;
    } else {
        tomograf_datasets::nifti::write_nifti(&args.output, &vol)
            .with_context(|| format!("writing {}", args.output.display()))?;
    }
    eprintln!(
        "wrote {} ({}×{}×{} voxels, HU)",
        args.output.display(),
        dims[0],
        dims[1],
        dims[2]
    );
    if let Some(dir) = &args.mesh_devices {
        let scene = crate::phantom_devices::write(dir, &args.output, &devices)?;
        eprintln!(
            "wrote {} device mesh(es) and {}",
            devices.len(),
            scene.display()
        );
    }
    Ok(())
}

#[derive(Debug, Args)]
pub struct ScanArgs {
    /// Root of a folder tree of DICOM series (e.g. LIDC-IDRI's patient/study/series layout).
    pub root: PathBuf,
}

/// Lists the DICOM series under a folder tree, one per line.
pub fn scan(args: ScanArgs) -> Result<()> {
    let (series, skipped) = tomograf_datasets::dicom::scan_dicom_tree_reporting(&args.root)?;
    for (path, why) in &skipped {
        eprintln!("skipped {}: {why}", path.display());
    }
    if !skipped.is_empty() {
        eprintln!(
            "warning: skipped {} DICOM file(s) that could not be read (listed above)",
            skipped.len()
        );
    }
    println!("modality\tfiles\trows×cols\tseries UID\tdescription\tfolder");
    for s in &series {
        println!(
            "{}\t{}\t{}×{}\t{}\t{}\t{}",
            s.modality,
            s.files,
            s.rows,
            s.cols,
            s.series_uid,
            s.description,
            s.folder.display()
        );
    }
    eprintln!("{} series under {}", series.len(), args.root.display());
    Ok(())
}
