//! `tomograf project` (render views of a volume), with the commands that share its
//! volume handling: `tomograf phantom` and `tomograf scan`. The scene, its volume, views
//! and physics are `tomograf_scene`'s; this module merges the flags into a scene and
//! hands it to [`tomograf_scene::project()`], which renders and writes the files.
//!
//! * [`phantom`] — the `phantom` and `scan` commands.

mod phantom;

pub use phantom::{PhantomArgs, ScanArgs, scan, write_phantom};

use crate::physics::PhysicsArgs;
use crate::progress::Bar;
use anyhow::{Result, bail};
use clap::Args;
use std::path::PathBuf;
use tomograf_scene::scene::Scene;

#[derive(Debug, Args)]
pub struct ProjectArgs {
    /// CT volume: a NIfTI file (.nii, .nii.gz) or a folder holding one DICOM series.
    /// Omit to render the built-in thorax phantom.
    pub input: Option<PathBuf>,
    /// Accept DICOM series whose modality is not CT.
    #[arg(long)]
    pub allow_non_ct: bool,
    /// TOML scene file; flags given here override its fields.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Voxel units of the input: hu (Hounsfield) or mu (linear attenuation, mm⁻¹).
    #[arg(long)]
    pub units: Option<String>,
    /// Effective photon energy for HU → mu, keV [default: 60].
    #[arg(long)]
    pub energy_kev: Option<f64>,
    /// Beam: cone or parallel [default: cone].
    #[arg(long)]
    pub beam: Option<String>,
    /// Source-to-isocentre distance, mm [default: 1000].
    #[arg(long)]
    pub sad: Option<f64>,
    /// Source-to-detector distance, mm [default: 1500].
    #[arg(long)]
    pub sid: Option<f64>,
    /// Isocentre X,Y,Z in world LPS mm [default: the volume's centre].
    #[arg(long, value_parser = parse3, allow_hyphen_values = true)]
    pub isocentre: Option<[f64; 3]>,
    /// Detector rows [default: 256].
    #[arg(long)]
    pub rows: Option<usize>,
    /// Detector columns [default: 256].
    #[arg(long)]
    pub cols: Option<usize>,
    /// Pixel pitch in mm: one value, or COLUMN,ROW [default: fit the volume on the panel].
    #[arg(long, value_parser = parse2)]
    pub pitch: Option<[f64; 2]>,
    /// Detector offset in mm along columns,rows [default: 0,0].
    #[arg(long, value_parser = parse2, allow_hyphen_values = true)]
    pub offset: Option<[f64; 2]>,
    /// A view: ap, pa, lateral, right-lateral, or θ[,φ] in degrees; repeatable [default: ap].
    #[arg(long = "view", allow_hyphen_values = true)]
    pub views: Vec<String>,
    /// An arc of views START:STEP:COUNT in degrees, e.g. 0:5:72.
    #[arg(long, allow_hyphen_values = true)]
    pub arc: Option<String>,
    /// Projector: siddon (exact) or trilinear [default: siddon].
    #[arg(long)]
    pub projector: Option<String>,
    /// Trilinear sample spacing in voxels [default: 0.5].
    #[arg(long)]
    pub step: Option<f64>,
    /// Exact Siddon tracer: auto (the measured best), scalar, packets, sheets or columns
    /// [default: auto]. Images agree to rounding; see docs/projector.md, "Which tracer".
    #[arg(long)]
    pub tracer: Option<String>,
    /// Skip empty space: voxels with |mu| at or below this (mm⁻¹) count as empty, e.g.
    /// 1e-4 for a CT whose air is noise rather than exact zeros. Each line integral then
    /// loses at most this × its length in skipped space. Ideal DRR only.
    #[arg(long)]
    pub empty_below: Option<f32>,
    /// What pixels hold: line-integral, transmission or intensity [default: line-integral].
    #[arg(long)]
    pub quantity: Option<String>,
    /// Unattenuated intensity for --quantity intensity [default: 1].
    #[arg(long)]
    pub i0: Option<f64>,
    /// Output folder [default: out].
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// File name prefix [default: drr].
    #[arg(long)]
    pub prefix: Option<String>,
    /// Output formats, comma-separated: exr, tiff, npy, png [default: exr,npy,png].
    #[arg(long, value_delimiter = ',')]
    pub format: Vec<String>,
    /// PNG preview window LOW,HIGH in the output quantity [default: each image's range].
    #[arg(long, value_parser = parse2, allow_hyphen_values = true)]
    pub window: Option<[f64; 2]>,
    /// Grid of the built-in phantom, NX,NY,NZ [default: 256,256,133].
    #[arg(long, value_parser = parse3)]
    pub phantom_dims: Option<[f64; 3]>,
    /// Voxel size of the built-in phantom, mm [default: 1.4,1.4,2.5].
    #[arg(long, value_parser = parse3)]
    pub phantom_spacing: Option<[f64; 3]>,
    #[command(flatten)]
    pub physics: PhysicsArgs,
}

pub(super) fn parse_list<const N: usize>(s: &str) -> Result<[f64; N], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| {
            x.trim()
                .parse::<f64>()
                .map_err(|_| format!("'{x}' is not a number"))
        })
        .collect::<Result<_, _>>()?;
    if v.iter().any(|x| !x.is_finite()) {
        return Err(format!("'{s}' holds a non-finite number"));
    }
    match v.len() {
        1 => Ok([v[0]; N]),
        n if n == N => Ok(std::array::from_fn(|i| v[i])),
        n => Err(format!(
            "expected 1 or {N} comma-separated numbers, got {n}"
        )),
    }
}
pub(super) fn parse2(s: &str) -> Result<[f64; 2], String> {
    parse_list::<2>(s)
}
pub(super) fn parse3(s: &str) -> Result<[f64; 3], String> {
    parse_list::<3>(s)
}

pub(super) fn grid_dims(d: [f64; 3]) -> Result<[usize; 3]> {
    d.iter()
        .try_fold(Vec::new(), |mut acc, &x| {
            if x < 1.0 || x.fract() != 0.0 {
                bail!("grid dimensions must be positive integers, got {x}");
            }
            acc.push(x as usize);
            Ok(acc)
        })
        .map(|v| [v[0], v[1], v[2]])
}

/// Merges command-line flags into the scene (flags win).
pub(crate) fn merge(args: &ProjectArgs) -> Result<Scene> {
    let mut s = match &args.scene {
        Some(p) => Scene::load(p)?,
        None => Scene::default(),
    };
    macro_rules! set {
        ($dst:expr, $src:expr) => {
            if let Some(x) = $src.clone() {
                $dst = Some(x);
            }
        };
    }
    set!(s.volume.path, args.input);
    set!(s.volume.units, args.units);
    if args.allow_non_ct {
        s.volume.allow_non_ct = Some(true);
    }
    set!(s.volume.energy_kev, args.energy_kev);
    if let Some(d) = args.phantom_dims {
        s.volume.phantom_dims = Some(grid_dims(d)?);
    }
    set!(s.volume.phantom_spacing_mm, args.phantom_spacing);
    set!(s.geometry.beam, args.beam);
    set!(s.geometry.sad_mm, args.sad);
    set!(s.geometry.sid_mm, args.sid);
    set!(s.geometry.isocentre_mm, args.isocentre);
    set!(s.detector.rows, args.rows);
    set!(s.detector.cols, args.cols);
    set!(s.detector.pitch_mm, args.pitch);
    set!(s.detector.offset_mm, args.offset);
    if !args.views.is_empty() || args.arc.is_some() {
        s.views.poses = Some(args.views.clone());
        s.views.arc = args.arc.clone();
        s.views.explicit.clear();
    }
    set!(s.projector.kind, args.projector);
    set!(s.projector.step_voxels, args.step);
    set!(s.projector.tracer, args.tracer);
    set!(s.projector.empty_below_per_mm, args.empty_below);
    set!(s.output.dir, args.output);
    set!(s.output.prefix, args.prefix);
    if !args.format.is_empty() {
        s.output.formats = Some(args.format.clone());
    }
    set!(s.output.quantity, args.quantity);
    set!(s.output.i0, args.i0);
    if let Some([lo, hi]) = args.window {
        s.output.window = Some([lo as f32, hi as f32]);
    }
    args.physics.merge_into(&mut s)?;
    Ok(s)
}

pub fn run(args: ProjectArgs) -> Result<()> {
    let scene = merge(&args)?;
    let summary = tomograf_scene::project(&scene, &Bar::default())?;
    eprintln!("{summary}");
    Ok(())
}
