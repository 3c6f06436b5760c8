//! `tomograf project`: resolve a scene (file + flags), render every view, write outputs.

use crate::output::{self, Format, Outputs};
use crate::physics::{self, PhysicsArgs};
use crate::scatter_images::ScatterWriters;
use crate::scene::{ExplicitView, MeshPhysics, Scene};
use anyhow::{Context, Result, bail};
use clap::Args;
use glam::DVec3;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;
use tomograf_datasets::anatomy::{self, AnatomySpec, Profile};
use tomograf_sim::accel::SkipOptions;
use tomograf_sim::acquisition::Acquired;
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::geometry::angles;
use tomograf_sim::mesh::MeshScene;
use tomograf_sim::phantom::Phantom;
use tomograf_sim::{
    Beam, Detector, Geometry, Pose, Projection, Projector, Quantity, Renderer, View, ViewBeam,
    Volume,
};

/// Default grid of the built-in phantom when rendered directly: 256 × 256 × 133 voxels of
/// 1.4 × 1.4 × 2.5 mm (a chest CT's field of view at half its in-plane resolution).
pub const PHANTOM_DIMS: [usize; 3] = [256, 256, 133];
/// See [`PHANTOM_DIMS`].
pub const PHANTOM_SPACING: [f64; 3] = [1.4, 1.4, 2.5];

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

fn parse_list<const N: usize>(s: &str) -> Result<[f64; N], String> {
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
fn parse2(s: &str) -> Result<[f64; 2], String> {
    parse_list::<2>(s)
}
fn parse3(s: &str) -> Result<[f64; 3], String> {
    parse_list::<3>(s)
}

fn grid_dims(d: [f64; 3]) -> Result<[usize; 3]> {
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

/// The built-in thorax phantom on a grid centred at the world origin, in HU.
pub fn phantom_volume(dims: [usize; 3], spacing: [f64; 3]) -> Result<Volume> {
    Ok(Phantom::thorax().voxelize(dims, DVec3::from(spacing), DVec3::ZERO)?)
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

/// Where the volume came from, for the sidecar.
#[derive(Debug, Clone, serde::Serialize)]
pub struct VolumeSource {
    pub path: Option<PathBuf>,
    pub phantom: Option<&'static str>,
    pub units: String,
    pub attenuation: Attenuation,
    pub dims: [usize; 3],
    pub spacing_mm: [f64; 3],
    pub origin_mm: [f64; 3],
    pub direction: [[f64; 3]; 3],
}

/// Effective energy (keV) of the HU → mu conversion of the ideal DRR when none is given.
const DEFAULT_ENERGY_KEV: f64 = 60.0;

/// Loads the input volume (or phantom) and converts it to mu (mm⁻¹).
pub fn load_mu(scene: &Scene) -> Result<(Volume, VolumeSource)> {
    load(scene, None)
}

/// Loads the input volume (or phantom) in HU, for real detector physics whose tissue
/// model is calibrated at `calibration_kev` (recorded as the volume's HU → mu energy).
pub fn load_hu(scene: &Scene, calibration_kev: f64) -> Result<(Volume, VolumeSource)> {
    load(scene, Some(calibration_kev))
}

/// Loads the input; converts HU to mu unless `keep_hu` (the calibration energy) is given.
fn load(scene: &Scene, keep_hu: Option<f64>) -> Result<(Volume, VolumeSource)> {
    let v = &scene.volume;
    let units = v
        .units
        .clone()
        .unwrap_or_else(|| "hu".into())
        .to_ascii_lowercase();
    let (vol, phantom) = match &v.path {
        Some(p) => (load_volume_file(p, v.allow_non_ct.unwrap_or(false))?, None),
        None => (
            phantom_volume(
                v.phantom_dims.unwrap_or(PHANTOM_DIMS),
                v.phantom_spacing_mm.unwrap_or(PHANTOM_SPACING),
            )?,
            Some("thorax"),
        ),
    };
    let attenuation = match (units.as_str(), keep_hu) {
        ("hu", Some(e)) => {
            if v.energy_kev.is_some() {
                bail!(
                    "--energy-kev is the monochromatic DRR's energy; with a spectrum the CT's \
                     energy is [materials] calibration_kev"
                );
            }
            Attenuation::hounsfield_at_kev(e)?
        }
        (_, Some(_)) => bail!(
            "real detector physics classifies tissues by CT number: the input must be in HU \
             (--units hu)"
        ),
        ("hu", None) => Attenuation::hounsfield_at_kev(v.energy_kev.unwrap_or(DEFAULT_ENERGY_KEV))?,
        ("mu", None) => {
            if v.energy_kev.is_some() {
                bail!("--energy-kev only applies to HU input (--units hu)");
            }
            Attenuation::LinearPerMm
        }
        (other, None) => bail!("unknown units '{other}': use hu (Hounsfield) or mu (mm⁻¹)"),
    };
    let mu = match keep_hu {
        Some(_) => vol,
        None => attenuation.to_mu(vol)?,
    };
    let d = mu.direction();
    let source = VolumeSource {
        path: v.path.clone(),
        phantom,
        units,
        attenuation,
        dims: mu.dims(),
        spacing_mm: mu.spacing().to_array(),
        origin_mm: mu.origin().to_array(),
        direction: [
            d.x_axis.to_array(),
            d.y_axis.to_array(),
            d.z_axis.to_array(),
        ],
    };
    Ok((mu, source))
}

/// Reads a CT volume: a NIfTI file or a folder holding one DICOM series.
pub fn load_volume_file(path: &std::path::Path, allow_non_ct: bool) -> Result<Volume> {
    let name = path.to_string_lossy().to_ascii_lowercase();
    if path.is_dir() {
        Ok(tomograf_datasets::dicom::read_dicom_series(
            path,
            allow_non_ct,
        )?)
    } else if name.ends_with(".nii") || name.ends_with(".nii.gz") {
        Ok(tomograf_datasets::nifti::read_nifti(path)?)
    } else {
        bail!(
            "cannot read {}: give a NIfTI volume (.nii, .nii.gz) or a folder holding one DICOM series",
            path.display()
        )
    }
}

#[derive(Debug, Args)]
pub struct ScanArgs {
    /// Root of a folder tree of DICOM series (e.g. LIDC-IDRI's patient/study/series layout).
    pub root: PathBuf,
}

/// Lists the DICOM series under a folder tree, one per line.
pub fn scan(args: ScanArgs) -> Result<()> {
    let series = tomograf_datasets::dicom::scan_dicom_tree(&args.root)?;
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

/// Merges command-line flags into the scene (flags win).
fn merge(args: &ProjectArgs) -> Result<Scene> {
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

/// Everything needed to render, resolved from a scene.
pub struct Job {
    pub geometry: Option<Geometry>,
    pub poses: Vec<Pose>,
    pub views: Vec<View>,
    pub projector: Projector,
    /// Empty-space skipping (`--empty-below`).
    pub skipping: Option<SkipOptions>,
    pub quantity: Quantity,
}

/// Resolves geometry, views, projector and quantity against the (mu) volume.
pub fn resolve(scene: &Scene, mu: &Volume) -> Result<Job> {
    let g = &scene.geometry;
    let beam = match g.beam.as_deref().unwrap_or("cone") {
        "cone" => Beam::Cone {
            sad_mm: g.sad_mm.unwrap_or(1000.0),
            sid_mm: g.sid_mm.unwrap_or(1500.0),
        },
        "parallel" => {
            if g.sad_mm.is_some() || g.sid_mm.is_some() {
                bail!("SAD and SID do not apply to a parallel beam");
            }
            Beam::Parallel
        }
        other => bail!("unknown beam '{other}': use cone or parallel"),
    };
    let mut poses = Vec::new();
    for p in scene.views.poses.iter().flatten() {
        poses.push(angles::parse_pose(p)?);
    }
    if let Some(a) = &scene.views.arc {
        poses.extend(angles::parse_arc(a)?);
    }
    let explicit: Vec<View> = scene
        .views
        .explicit
        .iter()
        .map(explicit_view)
        .collect::<Result<_>>()?;
    if poses.is_empty() && explicit.is_empty() {
        poses.push(Pose::AP);
    }
    let d = &scene.detector;
    let offset = d.offset_mm.unwrap_or([0.0, 0.0]);
    let mut geometry = Geometry {
        beam,
        detector: Detector {
            rows: d.rows.unwrap_or(256),
            cols: d.cols.unwrap_or(256),
            pitch_u_mm: 1.0,
            pitch_v_mm: 1.0,
            offset_u_mm: offset[0],
            offset_v_mm: offset[1],
        },
        isocentre: g
            .isocentre_mm
            .map(DVec3::from)
            .unwrap_or_else(|| mu.centre()),
    };
    let pitch = match d.pitch_mm {
        Some(p) => p,
        None => {
            let p = geometry.fit_pitch(&poses, mu)?;
            [p, p]
        }
    };
    geometry.detector.pitch_u_mm = pitch[0];
    geometry.detector.pitch_v_mm = pitch[1];
    let mut views = geometry.views(&poses)?;
    views.extend(explicit);

    let p = &scene.projector;
    let projector = match p.kind.as_deref().unwrap_or("siddon") {
        "siddon" => {
            if p.step_voxels.is_some() {
                bail!("--step applies to the trilinear projector only");
            }
            Projector::Siddon
        }
        "trilinear" => Projector::Trilinear {
            step_voxels: p.step_voxels.unwrap_or(0.5),
        },
        other => bail!("unknown projector '{other}': use siddon or trilinear"),
    };
    let skipping = p.empty_below_per_mm.map(|threshold| SkipOptions {
        threshold,
        ..SkipOptions::default()
    });
    let o = &scene.output;
    let quantity = match o.quantity.as_deref().unwrap_or("line-integral") {
        "line-integral" => Quantity::LineIntegral,
        "transmission" => Quantity::Transmission,
        "intensity" => Quantity::Intensity {
            i0: o.i0.unwrap_or(1.0),
        },
        other => bail!("unknown quantity '{other}': use line-integral, transmission or intensity"),
    };
    if o.i0.is_some() && !matches!(quantity, Quantity::Intensity { .. }) {
        bail!("--i0 applies to --quantity intensity only");
    }
    quantity.validate()?;
    Ok(Job {
        geometry: (!poses.is_empty()).then_some(geometry),
        poses,
        views,
        projector,
        skipping,
        quantity,
    })
}

fn explicit_view(e: &ExplicitView) -> Result<View> {
    let beam = match (e.source_mm, e.direction) {
        (Some(s), None) => ViewBeam::Cone {
            source: DVec3::from(s),
        },
        (None, Some(d)) => {
            let d = DVec3::from(d);
            if !d.is_finite() || d.length() == 0.0 {
                bail!("explicit view direction {d} is zero");
            }
            ViewBeam::Parallel {
                direction: d.normalize(),
            }
        }
        _ => {
            bail!("an explicit view needs exactly one of source_mm (cone) or direction (parallel)")
        }
    };
    let v = View {
        beam,
        detector_origin: DVec3::from(e.detector_origin_mm),
        u: DVec3::from(e.u_mm),
        v: DVec3::from(e.v_mm),
        rows: e.rows,
        cols: e.cols,
    };
    v.validate()?;
    Ok(v)
}

/// Renders view number `i`: one image per detector channel, and with real detector physics
/// the parts (primary, scatter) it was made of.
type RenderView<'a> = dyn Fn(usize, &View) -> Result<(Vec<Projection>, Option<Acquired>)> + 'a;

pub fn run(args: ProjectArgs) -> Result<()> {
    let t0 = Instant::now();
    let scene = merge(&args)?;
    let outputs = Outputs::from_scene(&scene)?;
    let acquisition = physics::acquisition(&scene)?;
    let (vol, source) = match &acquisition {
        None => load_mu(&scene)?,
        Some((acq, _)) => load_hu(&scene, acq.materials.calibration_kev)?,
    };
    let t_load = t0.elapsed();
    let job = resolve(&scene, &vol)?;
    // One view → one image per detector channel.
    let prepared;
    let renderer;
    let meshes = |physics| -> Result<Option<Arc<MeshScene>>> {
        let mut objects = Vec::new();
        for (i, m) in scene.mesh.iter().enumerate() {
            objects.extend(m.build(i, physics)?);
        }
        Ok((!objects.is_empty()).then(|| Arc::new(MeshScene::new(objects))))
    };
    let render: Box<RenderView> = match &acquisition {
        None => {
            let mut r = Renderer::new(&vol, job.projector)?;
            if job.skipping.is_some() {
                r = r.with_skipping(job.skipping)?;
            }
            // The HU → mu energy, at which a mesh's material gives its mu.
            let energy_kev = matches!(source.attenuation, Attenuation::Hounsfield { .. })
                .then(|| scene.volume.energy_kev.unwrap_or(DEFAULT_ENERGY_KEV));
            if let Some(m) = meshes(MeshPhysics::Monochromatic { energy_kev })? {
                r = r.with_meshes(m)?;
            }
            renderer = r;
            Box::new(|_, view| Ok((vec![renderer.render(view)?.to_quantity(job.quantity)], None)))
        }
        Some((acq, seed)) => {
            if job.skipping.is_some() {
                bail!(
                    "--empty-below is for the ideal DRR; empty-space skipping of a material \
                     composition (real detector physics) is not supported yet"
                );
            }
            if scene.output.quantity.is_some() || scene.output.i0.is_some() {
                bail!(
                    "--quantity and --i0 are for the ideal DRR; with real detector physics the \
                     image is the detector's --signal (raw, flat-field or log-line-integral)"
                );
            }
            prepared = acq.prepare_with_meshes(&vol, *seed, meshes(MeshPhysics::Polychromatic)?)?;
            Box::new(|i, view| {
                let mut parts = prepared.acquire_with_parts(job.projector, view, i)?;
                Ok((std::mem::take(&mut parts.images), Some(parts)))
            })
        }
    };
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
    let mut channels: Vec<Vec<Projection>> = Vec::new();
    let mut channel_outputs: Vec<Outputs> = Vec::new();
    for (i, view) in job.views.iter().enumerate() {
        let t = Instant::now();
        let (images, parts) = render(i, view)?;
        render_time += t.elapsed();
        if let Some(parts) = &parts {
            separate.write_view(i, parts)?;
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
    let mut sidecar = serde_json::to_value(output::Sidecar::new(&source, &job))?;
    if let Some((acq, seed)) = &acquisition {
        sidecar["quantity"] = serde_json::json!("detector signal (see acquisition)");
        sidecar["acquisition"] = serde_json::to_value(acq)?;
        sidecar["acquisition"]["seed"] = serde_json::json!(seed);
        sidecar["acquisition"]["frame_seeds"] = serde_json::json!(
            "view i: SplitMix64(seed ^ (i+1)·0x9E3779B97F4A7C15); calibration: frame 0"
        );
    }
    let mut files = 0;
    for (c, (out, images)) in channel_outputs.iter().zip(&channels).enumerate() {
        let mut sc = sidecar.clone();
        if channel_outputs.len() > 1 {
            sc["channel"] = serde_json::json!(c);
        }
        files += out.finish(images, sc)?;
    }
    if !separate.is_empty() {
        files += separate.finish(&sidecar)?;
    }
    eprintln!(
        "rendered {} view(s) of {}×{} in {:.1} ms ({:.1} ms per view; loading {:.0} ms); wrote {} file(s) to {}",
        job.views.len(),
        job.views.first().map_or(0, |v| v.rows),
        job.views.first().map_or(0, |v| v.cols),
        render_time.as_secs_f64() * 1e3,
        render_time.as_secs_f64() * 1e3 / job.views.len().max(1) as f64,
        t_load.as_secs_f64() * 1e3,
        files,
        outputs.dir.display()
    );
    Ok(())
}

/// Formats named on the command line.
pub fn parse_formats(names: &[String]) -> Result<Vec<Format>> {
    names.iter().map(|n| Format::parse(n)).collect()
}
