//! `tomograf phantom` (write the built-in or a procedural phantom:
//! [`tomograf_scene::phantom`]) and `tomograf scan`.

use super::{grid_dims, parse3};
use crate::progress::Bar;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;
use tomograf_datasets::anatomy::Profile;
use tomograf_scene::phantom::{self, PhantomFile};

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
    let p = PhantomFile {
        output: args.output,
        dicom: args.dicom,
        profile: args.profile.as_deref().map(Profile::parse).transpose()?,
        seed: args.seed,
        table: args.table,
        pacemaker: args.pacemaker,
        mesh_devices: args.mesh_devices,
        dims: args.dims.map(grid_dims).transpose()?,
        spacing: args.spacing,
    };
    phantom::write_phantom(&p, &Bar::default())
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
