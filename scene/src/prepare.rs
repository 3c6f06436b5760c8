//! A scene made ready to render: the volume loaded (mu for the ideal DRR, HU for real
//! detector physics), geometry and views resolved, the physics the scene asks for chosen
//! once — and nothing it did not ask for — then rendered view by view.
//!
//! ```no_run
//! # fn main() -> anyhow::Result<()> {
//! let scene = tomograf_scene::Scene::load(std::path::Path::new("scene.toml"))?;
//! let prepared = tomograf_scene::prepare(&scene)?;
//! for w in &prepared.warnings {
//!     eprintln!("{w}");
//! }
//! let renderer = prepared.renderer()?;
//! for (i, view) in prepared.job.views.iter().enumerate() {
//!     let frame = renderer.render(i, view)?; // one image per detector channel
//!     # let _ = frame;
//! }
//! # Ok(()) }
//! ```

use crate::job::{Job, resolve};
use crate::scene::{MeshPhysics, Scene};
use crate::volume::{DEFAULT_ENERGY_KEV, VolumeSource, load_hu, load_mu};
use anyhow::{Result, bail};
use std::sync::Arc;
use tomograf_physics::acquisition::{Acquired, Acquisition};
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::geometry::coverage::{Coverage, coverage};
use tomograf_sim::mesh::MeshScene;
use tomograf_sim::{Projection, Projector, Renderer, View, Volume};

/// A scene resolved against its volume; [`Prepared::renderer`] renders its views.
pub struct Prepared {
    /// The scene it was made from.
    pub scene: Scene,
    /// The volume: attenuation mu (mm⁻¹) for the ideal DRR, HU for real detector physics.
    pub volume: Volume,
    /// Where the volume came from, as the sidecar records it.
    pub source: VolumeSource,
    /// Geometry, views, projector and output quantity.
    pub job: Job,
    /// The detector physics and its noise seed; `None` for the ideal DRR.
    pub acquisition: Option<(Acquisition, u64)>,
    /// Legal geometry that is probably not meant (a source inside the volume, a detector
    /// cutting through it, views missing it), one sentence each.
    pub warnings: Vec<String>,
    /// Seconds spent loading the volume.
    pub load_seconds: f64,
    /// The job's estimated peak memory, bytes ([`render_peak_bytes`]).
    pub peak_bytes: u128,
}

/// One rendered view: one image per detector channel, and with real detector physics the
/// parts (primary, scatter) it was made of.
pub struct Frame {
    /// One image per detector channel (one for the ideal DRR).
    pub images: Vec<Projection>,
    /// The parts of a real detector's image; `None` for the ideal DRR.
    pub parts: Option<Acquired>,
}

pub use crate::peak::render_peak_bytes;

/// Loads and resolves `scene`: the acquisition it asks for (checked first, so a bad
/// preset fails before a large volume is read), the volume, the views (refused when none
/// meets the volume and no mesh is in the scene; the images would be all zero), and the
/// combinations the renderer does not support.
pub fn prepare(scene: &Scene) -> Result<Prepared> {
    let acquisition = crate::physics::acquisition(scene)?;
    if let Some(d) = &scene.dose {
        crate::dose::check(d, acquisition.as_ref(), !scene.mesh.is_empty())?;
    }
    let t0 = std::time::Instant::now();
    let (volume, source) = match &acquisition {
        None => load_mu(scene)?,
        Some((acq, _)) => load_hu(scene, acq.materials.calibration_kev)?,
    };
    let load_seconds = t0.elapsed().as_secs_f64();
    assemble(scene, volume, source, acquisition, load_seconds)
}

/// [`prepare`] for a CT already in memory: `hu` (HU, mm, the patient frame) stands for the
/// scene's `[volume]`, and `acquisition` (resolved, with its noise seed; `None`: the ideal
/// DRR at `[volume] energy_kev`, default 60 keV) for its physics sections, which must be
/// absent. Geometry, views, projector and output come from the scene as in [`prepare`].
/// How data-set items and the trade-off ladder make their images: the one renderer every
/// image goes through. For real physics, [`Prepared::volume`] is `hu` itself, handed back.
pub fn prepare_in_memory(
    scene: &Scene,
    hu: Volume,
    acquisition: Option<(Acquisition, u64)>,
) -> Result<Prepared> {
    if let Some(p) = &scene.volume.path {
        bail!(
            "the scene's CT is given in memory; it names a [volume] path too ({})",
            p.display()
        );
    }
    if crate::physics::acquisition(scene)?.is_some() || scene.dose.is_some() {
        bail!(
            "the scene's physics is given with its CT in memory; its own [acquisition], \
             [spectrum], [materials], [detector] model, [scatter] and [dose] must be absent"
        );
    }
    let (volume, attenuation) = match &acquisition {
        None => {
            let a = Attenuation::hounsfield_at_kev(
                scene.volume.energy_kev.unwrap_or(DEFAULT_ENERGY_KEV),
            )?;
            (a.to_mu(hu)?, a)
        }
        Some((acq, _)) => {
            if scene.volume.energy_kev.is_some() {
                bail!(
                    "[volume] energy_kev is the monochromatic DRR's energy; with a spectrum \
                     the CT's energy is [materials] calibration_kev"
                );
            }
            (
                hu,
                Attenuation::hounsfield_at_kev(acq.materials.calibration_kev)?,
            )
        }
    };
    let source = crate::volume::record(&volume, None, None, "hu".into(), attenuation);
    assemble(scene, volume, source, acquisition, 0.0)
}

/// Resolves the scene's views against the loaded `volume` and checks what the job will hold.
fn assemble(
    scene: &Scene,
    volume: Volume,
    source: VolumeSource,
    acquisition: Option<(Acquisition, u64)>,
    load_seconds: f64,
) -> Result<Prepared> {
    let job = resolve(scene, &volume)?;
    let pixels: u128 = job
        .views
        .iter()
        .map(|v| v.rows as u128 * v.cols as u128)
        .sum();
    tomograf_sim::memory::check(
        pixels * 4,
        &format!("{} views held as f32 images", job.views.len()),
    )?;
    // The job's peak beyond the volume already read (MemAvailable no longer counts it).
    let voxels = volume.len() as u128;
    let peak = render_peak_bytes(acquisition.is_some(), voxels, pixels);
    tomograf_sim::memory::check(
        peak.saturating_sub(voxels * 4),
        &format!(
            "rendering {} views ({} pixels in all) of a {}×{}×{} volume ({}), beyond the \
             volume already read,",
            job.views.len(),
            pixels,
            volume.dims()[0],
            volume.dims()[1],
            volume.dims()[2],
            if acquisition.is_some() {
                "detector physics"
            } else {
                "ideal DRR"
            }
        ),
    )?;
    let warnings = check_geometry(&job.views, &volume, !scene.mesh.is_empty())?;
    if acquisition.is_some() {
        if job.skipping.is_some() {
            bail!(
                "[projector] empty_below_per_mm (--empty-below) is for the ideal DRR; \
                 empty-space skipping of a material composition (real detector physics) is \
                 not supported yet"
            );
        }
        if scene.output.quantity.is_some() || scene.output.i0.is_some() {
            bail!(
                "[output] quantity and i0 (--quantity, --i0) are for the ideal DRR; with \
                 real detector physics the image is the detector's signal ([acquisition] \
                 signal, --signal: raw, flat-field or log-line-integral)"
            );
        }
    }
    Ok(Prepared {
        scene: scene.clone(),
        volume,
        source,
        job,
        acquisition,
        warnings,
        load_seconds,
        peak_bytes: peak,
    })
}

/// Renders the views of a [`Prepared`] scene.
pub enum SceneRenderer<'a> {
    /// The ideal DRR: the monochromatic projector, in the job's output quantity.
    Ideal {
        renderer: Renderer<'a>,
        quantity: tomograf_sim::Quantity,
    },
    /// Real detector physics, prepared once for every view, traced with `projector`.
    Physics {
        prepared: Box<tomograf_physics::acquisition::Prepared>,
        projector: tomograf_sim::Projector,
    },
}

impl Prepared {
    /// The scene's mesh objects for `physics` (`None` when it has none).
    fn meshes(&self, physics: MeshPhysics) -> Result<Option<Arc<MeshScene>>> {
        let mut objects = Vec::new();
        for (i, m) in self.scene.mesh.iter().enumerate() {
            objects.extend(m.build(i, physics)?);
        }
        Ok((!objects.is_empty()).then(|| Arc::new(MeshScene::new(objects))))
    }

    /// Builds the renderer: the projector over the volume (and meshes) for the ideal DRR,
    /// or the acquisition's material decomposition for real detector physics.
    pub fn renderer(&self) -> Result<SceneRenderer<'_>> {
        self.renderer_with(self.job.projector, self.acquisition.as_ref())
    }

    /// [`Prepared::renderer`] with another `projector` and, for real physics, another
    /// `acquisition` (its spectrum bins, scatter or detector changed): the same volume,
    /// views, tracer and meshes. How `tomograf tradeoff` renders each setting it measures.
    /// The physics must be of the kind the scene was prepared for (the volume holds mu
    /// for the ideal DRR, HU for real physics).
    pub fn renderer_with(
        &self,
        projector: Projector,
        acquisition: Option<&(Acquisition, u64)>,
    ) -> Result<SceneRenderer<'_>> {
        if acquisition.is_some() != self.acquisition.is_some() {
            bail!(
                "the scene was prepared for {}: its volume holds {}",
                if self.acquisition.is_some() {
                    "real detector physics"
                } else {
                    "the ideal DRR"
                },
                if self.acquisition.is_some() {
                    "HU"
                } else {
                    "mu"
                }
            );
        }
        Ok(match acquisition {
            None => {
                let mut r = Renderer::new(&self.volume, projector)?;
                if self.job.skipping.is_some() {
                    r = r.with_skipping(self.job.skipping)?;
                }
                // The HU → mu energy, at which a mesh's material gives its mu.
                let energy_kev = matches!(self.source.attenuation, Attenuation::Hounsfield { .. })
                    .then(|| self.scene.volume.energy_kev.unwrap_or(DEFAULT_ENERGY_KEV));
                if let Some(m) = self.meshes(MeshPhysics::Monochromatic { energy_kev })? {
                    r = r.with_meshes(m)?;
                }
                r = r.with_tracer(self.job.tracer).for_views(&self.job.views);
                SceneRenderer::Ideal {
                    renderer: r,
                    quantity: self.job.quantity,
                }
            }
            Some((acq, seed)) => SceneRenderer::Physics {
                prepared: Box::new(
                    acq.prepare_with_meshes(
                        &self.volume,
                        *seed,
                        self.meshes(MeshPhysics::Polychromatic)?,
                    )?
                    .with_tracer(self.job.tracer)
                    .for_views(projector, &self.job.views)?,
                ),
                projector,
            },
        })
    }
}

impl SceneRenderer<'_> {
    /// Renders `view`, the scene's view number `index` (which seeds its detector noise).
    pub fn render(&self, index: usize, view: &View) -> Result<Frame> {
        Ok(match self {
            Self::Ideal { renderer, quantity } => Frame {
                images: vec![renderer.render(view)?.to_quantity(*quantity)],
                parts: None,
            },
            Self::Physics {
                prepared,
                projector,
            } => {
                let mut parts = prepared.acquire_with_parts(*projector, view, index)?;
                Frame {
                    images: std::mem::take(&mut parts.images),
                    parts: Some(parts),
                }
            }
        })
    }
}

/// Geometry that is legal but almost certainly not meant: a warning where the source or
/// the detector sits inside the volume, or where some views miss it; an error where every
/// view misses it and no mesh is in the scene (the images would be all zero).
fn check_geometry(views: &[View], vol: &Volume, meshes: bool) -> Result<Vec<String>> {
    let c: Vec<Coverage> = views.iter().map(|v| coverage(v, vol)).collect();
    let list = |f: &dyn Fn(&Coverage) -> bool| {
        let hits: Vec<String> = c
            .iter()
            .enumerate()
            .filter(|(_, c)| f(c))
            .map(|(i, _)| i.to_string())
            .take(8)
            .collect();
        (!hits.is_empty()).then(|| hits.join(", "))
    };
    let mut warnings = Vec::new();
    if let Some(v) = list(&|c| c.source_inside) {
        warnings.push(format!(
            "warning: the source lies inside the volume (views {v}): only the part of the \
             volume in front of the source is integrated; raise [geometry] sad_mm (--sad) if this is not meant"
        ));
    }
    if let Some(v) = list(&|c| c.detector_inside) {
        warnings.push(format!(
            "warning: the detector cuts through the volume (views {v}): rays end at the \
             detector, so the line integrals are truncated; raise [geometry] sid_mm (--sid; it is at or \
             just above sad_mm)"
        ));
    }
    if c.iter().all(|c| c.rays_hitting == 0) {
        let msg = "no ray of any view meets the volume, so every image would hold zeros: \
                   check --isocentre (default: the volume's centre), --offset, --sad and the \
                   detector size";
        if !meshes {
            bail!("{msg}");
        }
        warnings.push(format!("warning: {msg} (only the meshes are in the beam)"));
    } else if let Some(v) = list(&|c| c.rays_hitting == 0) {
        warnings.push(format!(
            "warning: views {v} miss the volume entirely (images of zeros)"
        ));
    }
    Ok(warnings)
}
