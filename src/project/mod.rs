//! `tomograf project` (render views of a volume), with the commands that share its
//! volume handling: `tomograf phantom` and `tomograf scan`. The scene, its volume, views
//! and physics are `tomograf_scene`'s; this module merges the flags into a scene, shows
//! progress and writes the files.
//!
//! * [`phantom`] — the `phantom` and `scan` commands.

mod phantom;

pub use phantom::{PhantomArgs, ScanArgs, scan, write_phantom};
pub use tomograf_scene::job::resolve;
pub use tomograf_scene::volume::{load_hu, load_mu};

use crate::output;
use crate::output::{Format, Outputs};
use crate::physics::PhysicsArgs;
use crate::scatter_images::ScatterWriters;
use anyhow::{Result, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::time::Instant;
use tomograf_datasets::sidecar::{self, PixelQuantity};
use tomograf_scene::scene::Scene;
use tomograf_sim::Projection;

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
    let outputs = Outputs::from_scene(&scene)?;
    let prepared = tomograf_scene::prepare(&scene)?;
    for w in &prepared.warnings {
        eprintln!("{w}");
    }
    let renderer = prepared.renderer()?;
    let (job, acquisition) = (&prepared.job, &prepared.acquisition);
    outputs.prepare()?;
    let mut separate = ScatterWriters::new(
        &outputs,
        scene.scatter.as_ref().map_or(&[][..], |s| &s.images[..]),
    );

    let bar = ProgressBar::new(job.views.len() as u64).with_style(
        ProgressStyle::with_template(
            "{spinner} rendering view {pos}/{len} [{bar:30}] {elapsed} (eta {eta})",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    if job.views.len() < 2 {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let mut render_time = std::time::Duration::ZERO;
    let mut clipping = tomograf_sim::detector::Clipping::default();
    let mut channels: Vec<Vec<Projection>> = Vec::new();
    let mut channel_outputs: Vec<Outputs> = Vec::new();
    for (i, view) in job.views.iter().enumerate() {
        let t = Instant::now();
        let tomograf_scene::Frame { images, parts } = renderer.render(i, view)?;
        render_time += t.elapsed();
        if let Some(parts) = &parts {
            separate.write_view(i, parts)?;
            clipping.add(
                parts.clipped,
                parts.saturated,
                images.iter().map(|p| p.data.len()).sum(),
            );
        }
        if channel_outputs.is_empty() {
            channel_outputs = (0..images.len())
                .map(|c| outputs.for_channel(c, images.len()))
                .collect();
            channels = vec![Vec::with_capacity(job.views.len()); images.len()];
        }
        for ((img, out), stack) in images.into_iter().zip(&channel_outputs).zip(&mut channels) {
            out.write_view(i, &img)?;
            stack.push(img);
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    let mut sidecar = output::sidecar(&prepared.source, job);
    if let Some((acq, seed)) = acquisition {
        sidecar.quantity = PixelQuantity::Described("detector signal (see acquisition)".into());
        sidecar.acquisition = Some(sidecar::acquisition_record(acq, *seed)?);
        sidecar.clipped_pixels = Some(clipping.clipped as u64);
        sidecar.saturated_pixels = Some(clipping.saturated as u64);
        if let Some(w) = clipping.warning(acq.spectrum.mas, "[spectrum] mas or --mas") {
            eprintln!("{w}");
        }
    }
    let mut files = 0;
    for (c, (out, images)) in channel_outputs.iter().zip(&channels).enumerate() {
        let mut sc = sidecar.clone();
        if channel_outputs.len() > 1 {
            sc.channel = Some(c);
        }
        files += out.finish(images, sc)?;
    }
    if !separate.is_empty() {
        files += separate.finish(&sidecar)?;
    }
    if let Some(d) = &scene.dose {
        files += crate::dose::write(
            d,
            acquisition.as_ref(),
            &prepared.volume,
            &job.views,
            &outputs,
        )?;
    }
    eprintln!(
        "rendered {} view(s) of {}×{} in {:.1} ms ({:.1} ms per view; loading {:.0} ms); wrote {} file(s) to {}",
        job.views.len(),
        job.views.first().map_or(0, |v| v.rows),
        job.views.first().map_or(0, |v| v.cols),
        render_time.as_secs_f64() * 1e3,
        render_time.as_secs_f64() * 1e3 / job.views.len().max(1) as f64,
        prepared.load_seconds * 1e3,
        files,
        outputs.dir.display()
    );
    Ok(())
}

/// Formats named on the command line.
pub fn parse_formats(names: &[String]) -> Result<Vec<Format>> {
    names.iter().map(|n| Format::parse(n)).collect()
}
