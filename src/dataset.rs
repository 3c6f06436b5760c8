//! `tomograf dataset`: training or test sets as in the TomoGRAF paper.
//!
//! Per item (a CT file or folder, or a seeded phantom): the black-border-cropped CT resampled
//! to `size³` and normalised to [0, 1] over an HU window (`ct.nii.gz`, whose affine keeps
//! the world frame), and `views` projections every 360/`views` degrees plus AP and lateral
//! at `size²` (`projections.npy`, line integrals, shape views × rows × cols), rendered with
//! exact Siddon from the cropped full-resolution volume, with the geometry of every view in
//! `views.json`. `item.json` is written last and marks the item finished; `manifest.jsonl`
//! (one line per finished item, in item order) is rebuilt at the end of every run.
//!
//! Resumable: a re-run skips finished items; every file is written to a temporary name and
//! renamed, so a killed run leaves no half-written file. `--shard i/n` takes items
//! `i, i+n, i+2n, …`; items are independent, so shards produce the same bytes as one run.

use crate::physics::{self, PhysicsArgs};
use crate::project::load_volume_file;
use anyhow::{Context, Result, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use tomograf_datasets::anatomy::{self, AnatomySpec, Profile};
use tomograf_datasets::item::{self, AcquisitionRecord, ItemRecord};
use tomograf_datasets::preprocess::{HuWindow, crop_black_border, resample};
use tomograf_datasets::{atomic, image, nifti};
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::geometry::angles;
use tomograf_sim::{Beam, Detector, Geometry, Pose, Projector, Renderer, View};

#[derive(Debug, Args)]
pub struct DatasetArgs {
    /// CT volumes: NIfTI files or DICOM series folders (a folder of such is expanded).
    pub inputs: Vec<PathBuf>,
    /// Output folder.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Generate this many seeded thorax phantoms instead of (or after) the inputs.
    #[arg(long, default_value_t = 0)]
    pub phantoms: usize,
    /// Seed of the first phantom; phantom n uses seed + n.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Phantom population: lidc (cropped to the thorax, like LIDC-IDRI) or full-chest (arms,
    /// neck, whole chest wall, like the paper's in-house test set).
    #[arg(long, default_value = "lidc")]
    pub profile: String,
    /// Put the phantoms on a patient table.
    #[arg(long)]
    pub table: bool,
    /// Give the phantoms a pacemaker with leads.
    #[arg(long)]
    pub pacemaker: bool,
    /// Projections per full rotation (every 360/views degrees), besides AP and lateral.
    #[arg(long, default_value_t = 72)]
    pub views: usize,
    /// CT grid (size³) and detector (size²).
    #[arg(long, default_value_t = 128)]
    pub size: usize,
    /// HU window mapped to [0, 1], LOW,HIGH [default: -1024,2048].
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub hu_window: Vec<f32>,
    /// Black-border crop threshold, HU: voxels at or below it count as border.
    #[arg(long, default_value_t = -900.0, allow_hyphen_values = true)]
    pub crop_hu: f32,
    /// Effective energy for HU → mu, keV.
    #[arg(long, default_value_t = 60.0)]
    pub energy_kev: f64,
    /// Source-to-isocentre and source-to-detector distances, mm.
    #[arg(long, default_value_t = 1000.0)]
    pub sad: f64,
    #[arg(long, default_value_t = 1500.0)]
    pub sid: f64,
    /// Name of the split this set belongs to (e.g. the institution: "lidc", "in-house").
    #[arg(long, default_value = "train")]
    pub split: String,
    /// Take only items i, i+n, … of the job: I/N (0-based), for running across machines.
    #[arg(long)]
    pub shard: Option<String>,
    /// Real detector physics instead of ideal DRRs (item i's noise is seeded from the
    /// noise seed and i, so shards give the same bytes).
    #[command(flatten)]
    pub physics: PhysicsArgs,
}

/// Where an item comes from.
#[derive(Debug, Clone, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
enum Source {
    File { path: PathBuf },
    Phantom { spec: AnatomySpec },
}

/// Inputs expanded: files as given; a folder with DICOM files is one series, any other
/// folder contributes its NIfTI files and series sub-folders, sorted by path.
fn expand(inputs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for p in inputs {
        if p.is_dir()
            && !tomograf_datasets::dicom::scan_dicom_tree(p)?
                .iter()
                .any(|s| s.folder == *p)
        {
            let mut nii: Vec<PathBuf> = std::fs::read_dir(p)
                .with_context(|| format!("cannot list {}", p.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|f| {
                    let n = f.to_string_lossy().to_ascii_lowercase();
                    n.ends_with(".nii") || n.ends_with(".nii.gz")
                })
                .collect();
            nii.sort();
            out.extend(nii);
            out.extend(
                tomograf_datasets::dicom::scan_dicom_tree(p)?
                    .into_iter()
                    .map(|s| s.folder),
            );
        } else {
            out.push(p.clone());
        }
    }
    Ok(out)
}

/// SHA-256 of a file, or of a folder's files (sorted names and contents).
fn sha256_of(path: &Path) -> Result<String> {
    let mut h = Sha256::new();
    if path.is_dir() {
        let mut files: Vec<PathBuf> = std::fs::read_dir(path)?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|f| f.is_file())
            .collect();
        files.sort();
        for f in files {
            h.update(f.file_name().unwrap_or_default().as_encoded_bytes());
            h.update(std::fs::read(&f).with_context(|| format!("cannot read {}", f.display()))?);
        }
    } else {
        h.update(std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?);
    }
    Ok(format!("{:x}", h.finalize()))
}

pub fn run(args: DatasetArgs) -> Result<()> {
    let window = match args.hu_window.as_slice() {
        [] => HuWindow::CHEST,
        [lo, hi] => HuWindow::new(*lo, *hi)?,
        _ => bail!("--hu-window takes LOW,HIGH"),
    };
    if args.size < 2 || args.views == 0 {
        bail!("--size must be at least 2 and --views at least 1");
    }
    // Bad physics flags are named before any work.
    physics::from_args(&args.physics)?;
    let (shard, shards) = args
        .shard
        .as_deref()
        .map(crate::evaluate::parse_shard)
        .transpose()?
        .unwrap_or((0, 1));
    let mut sources: Vec<Source> = expand(&args.inputs)?
        .into_iter()
        .map(|path| Source::File { path })
        .collect();
    let profile = Profile::parse(&args.profile)?;
    sources.extend((0..args.phantoms).map(|n| {
        // Grids large enough for the profile's field of view, at about CT resolution.
        let (dims, spacing) = match profile {
            Profile::LidcCropped => ([200, 200, 128], [2.0, 2.0, 2.5]),
            Profile::FullChest => ([256, 256, 200], [2.2, 2.2, 2.5]),
        };
        let mut spec = AnatomySpec::new(args.seed + n as u64, profile, dims, spacing);
        spec.table = args.table;
        spec.pacemaker = args.pacemaker;
        Source::Phantom { spec }
    }));
    if sources.is_empty() {
        bail!("nothing to do: give CT inputs or --phantoms N");
    }
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("cannot create {}", args.output.display()))?;
    atomic::remove_stale_temporaries(&args.output)?;

    let mine: Vec<usize> = (0..sources.len()).filter(|i| i % shards == shard).collect();
    let bar = ProgressBar::new(mine.len() as u64).with_style(
        ProgressStyle::with_template(
            "{spinner} item {pos}/{len} [{bar:30}] {elapsed} (eta {eta}) {msg}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    let (mut made, mut skipped) = (0, 0);
    for &index in &mine {
        let dir = args.output.join(format!("{index:05}"));
        if finished(&dir) {
            skipped += 1;
        } else {
            bar.set_message(format!("{index:05}"));
            make_item(&args, window, index, &sources[index], &dir)
                .with_context(|| format!("item {index:05}"))?;
            made += 1;
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    let listed = item::write_manifest(&args.output, sources.len())?;
    eprintln!(
        "{made} item(s) made, {skipped} already finished (shard {shard}/{shards}); manifest lists {listed} of {} item(s): {}",
        sources.len(),
        args.output.join("manifest.jsonl").display()
    );
    Ok(())
}

/// An item is finished when its `item.json` exists and parses (it is written last).
fn finished(dir: &Path) -> bool {
    item::finished_record(dir).is_some()
}

fn make_item(
    args: &DatasetArgs,
    window: HuWindow,
    index: usize,
    source: &Source,
    dir: &Path,
) -> Result<()> {
    // The CT in HU, and what identifies it.
    let (hu, sha) = match source {
        Source::File { path } => (load_volume_file(path, false)?, sha256_of(path)?),
        Source::Phantom { spec } => {
            let sha = format!(
                "{:x}",
                Sha256::digest(serde_json::to_string(spec)?.as_bytes())
            );
            (anatomy::generate(spec)?, sha)
        }
    };
    let cropped = crop_black_border(&hu, args.crop_hu)?;

    // Projections from the cropped full-resolution volume.
    let acquisition = physics::from_args(&args.physics)?;
    let mu = match &acquisition {
        None => Attenuation::hounsfield_at_kev(args.energy_kev)?.to_mu(cropped.clone())?,
        Some(_) => cropped.clone(), // classified into tissues below, in HU
    };
    let mut poses = angles::arc(0.0, 360.0 / args.views as f64, args.views, 0.0)?;
    poses.extend([Pose::AP, Pose::LATERAL]);
    let mut geometry = Geometry {
        beam: Beam::Cone {
            sad_mm: args.sad,
            sid_mm: args.sid,
        },
        detector: Detector::new(args.size, args.size, 1.0),
        isocentre: mu.centre(),
    };
    let pitch = geometry.fit_pitch(&poses, &mu)?;
    geometry.detector.pitch_u_mm = pitch;
    geometry.detector.pitch_v_mm = pitch;
    let views: Vec<View> = geometry.views(&poses)?;
    let mut stack = Vec::with_capacity(views.len() * args.size * args.size);
    let quantity = match &acquisition {
        None => {
            let renderer = Renderer::new(&mu, Projector::Siddon)?;
            for v in &views {
                stack.extend(renderer.render(v)?.data);
            }
            "line integral ∫mu ds (mu at the effective energy)".to_string()
        }
        Some((acq, seed)) => {
            if acq.detector.channels() != 1 {
                bail!("data sets hold one image per view: use a one-channel detector");
            }
            let prepared = acq.prepare(&mu, physics::item_seed(*seed, index))?;
            for (i, v) in views.iter().enumerate() {
                stack.extend(prepared.acquire(Projector::Siddon, v, i)?.remove(0).data);
            }
            format!("detector signal: {:?} (see acquisition)", acq.output)
        }
    };

    // The CT on the training grid, normalised.
    let ct = window.normalize(&resample(&cropped, [args.size; 3])?)?;

    std::fs::create_dir_all(dir)?;
    nifti::write_nifti(&dir.join("ct.nii.gz"), &ct)?;
    image::write_npy(
        &dir.join("projections.npy"),
        &stack,
        &[views.len(), args.size, args.size],
    )?;
    item::write_views(dir, &geometry, &poses, &views)?;
    let record = ItemRecord {
        index,
        id: format!("{index:05}"),
        split: args.split.clone(),
        source: serde_json::to_value(source)?,
        source_sha256: sha,
        hu_window: window,
        energy_kev: args.energy_kev,
        ct: "ct.nii.gz".into(),
        ct_dims: ct.dims(),
        projections: "projections.npy".into(),
        projection_quantity: quantity,
        acquisition: acquisition
            .as_ref()
            .map(|(a, s)| {
                AcquisitionRecord {
                    settings: a.clone(),
                    noise_seed: *s,
                }
                .to_json()
            })
            .unwrap_or(serde_json::Value::Null),
        views: "views.json".into(),
        angles_deg: poses.iter().map(|p| [p.theta_deg, p.phi_deg]).collect(),
    };
    Ok(item::write_record(dir, &record)?)
}
