//! An X-ray acquisition: everything between the traced paths and the recorded image — the
//! beam's spectrum and exposure, what the voxels are made of, and the detector.
//!
//! Data flow of one view: CT (HU) → [`tomograf_sim::tissue`] composition (once per volume) →
//! per-material mass thickness ([`tomograf_sim::render::Renderer::mass_thickness`], one trace)
//! → [`crate::polychromatic`] expected signal per detector channel → [`crate::detector`]
//! (noise, blur, readout, flat/dark correction, −log) → images.
//!
//! A scene asks only for what it needs: the `ideal-drr` preset is not an acquisition at
//! all but the monochromatic projector itself (see the CLI), and materials that do not
//! occur in the volume are dropped before tracing.

use crate::detector::{DetectorModel, ExpectedImage, FlatField, Output};
use crate::polychromatic::SpectralIntegrator;
use crate::scatter::orbit::OrbitScatter;
use crate::scatter::{
    AntiScatterGrid, ScatterEngine, ScatterImages, ScatterModel, estimator, transport,
};
use crate::spectrum::{Filter, FluenceUnit, Spectrum};
use serde::{Deserialize, Serialize};
use std::sync::{Arc, Mutex};
use tomograf_sim::composition::Composition;
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::geometry::View;
use tomograf_sim::material::{self, Material};
use tomograf_sim::mesh::MeshScene;
use tomograf_sim::render::{ColumnCopy, MassThickness, Projection, Projector, Renderer, Tracer};
use tomograf_sim::seed::frame_seed;
use tomograf_sim::tissue::TissueModel;
use tomograf_sim::volume::Volume;

/// Where the beam's spectrum comes from (a scene's `[spectrum]` table).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub struct SpectrumSpec {
    /// Tube voltage of a tungsten-anode spectrum (kVp, 40–150). Exclusive with
    /// `energy-kev` and `file`.
    #[serde(default)]
    pub kvp: Option<f64>,
    /// A monoenergetic beam at this energy (keV).
    #[serde(default)]
    pub energy_kev: Option<f64>,
    /// The monoenergetic beam's fluence, photons per mAs per mm² at 1 m (default
    /// [`MONOENERGETIC_FLUENCE`], a clinical tube's order of magnitude, so that a 1 mAs view
    /// does not run out of photons behind bone).
    #[serde(default)]
    pub photons_per_mas_mm2: Option<f64>,
    /// A user spectrum file (keV and the fluence of each bin; see
    /// [`Spectrum::from_file_in`] for the formats read).
    #[serde(default)]
    pub file: Option<std::path::PathBuf>,
    /// The unit of the file's fluence column: per-mm2 (photons per mAs per mm² at 1 m per
    /// bin, the default), per-cm2, per-mm2-per-kev or per-cm2-per-kev.
    #[serde(default)]
    pub fluence_unit: Option<FluenceUnit>,
    /// Added filtration, applied in order.
    #[serde(default)]
    pub filtration: Vec<FilterSpec>,
    /// Rebin to this many energy bins (fewer bins: faster, less exact; see
    /// docs/physics.md for the trade). Default: the table's 1 keV bins.
    #[serde(default)]
    pub bins: Option<usize>,
    /// Tube current–time product (mA·s) per view.
    #[serde(default = "default_mas")]
    pub mas: f64,
}

fn default_mas() -> f64 {
    1.0
}

/// The default fluence of a monoenergetic `[spectrum]` beam: 10⁶ photons per mAs per mm² at
/// 1 m — the order of the 120 kVp tungsten beam of the `kv-flat-panel-120kvp` preset (a test
/// keeps it within a factor of 3 of that beam's photon count), where the old default of 1
/// left a few photons per pixel and clipped −log behind bone.
pub const MONOENERGETIC_FLUENCE: f64 = 1e6;

/// One added filter: a material name and its thickness (mm).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub struct FilterSpec {
    /// Material name ([`material::by_name`]), e.g. "al", "cu".
    pub material: String,
    /// Thickness, mm.
    pub thickness_mm: f64,
}

impl SpectrumSpec {
    /// A tungsten spectrum at `kvp` with added filtration (material, mm).
    pub fn tungsten(kvp: f64, filtration: &[(&str, f64)], mas: f64) -> Self {
        Self {
            kvp: Some(kvp),
            energy_kev: None,
            photons_per_mas_mm2: None,
            file: None,
            fluence_unit: None,
            filtration: filtration
                .iter()
                .map(|(m, t)| FilterSpec {
                    material: m.to_string(),
                    thickness_mm: *t,
                })
                .collect(),
            bins: None,
            mas,
        }
    }

    /// The spectrum this describes (photons per bin per mAs per mm² at 1 m).
    pub fn spectrum(&self) -> Result<Spectrum> {
        if self.photons_per_mas_mm2.is_some() && self.energy_kev.is_none() {
            return Err(SimError::OutOfRange(
                "[spectrum] photons_per_mas_mm2 is the fluence of a monoenergetic beam \
                 (energy_kev); a tube or file spectrum carries its own (scale it with mas)"
                    .into(),
            ));
        }
        if self.fluence_unit.is_some() && self.file.is_none() {
            return Err(SimError::OutOfRange(
                "[spectrum] fluence_unit is the unit of a spectrum file's column; give file".into(),
            ));
        }
        let base = match (self.kvp, self.energy_kev, &self.file) {
            (Some(kvp), None, None) => Spectrum::tungsten(kvp, &[])?,
            (None, Some(e), None) => {
                let fluence = self.photons_per_mas_mm2.unwrap_or(MONOENERGETIC_FLUENCE);
                if !(fluence.is_finite() && fluence > 0.0) {
                    return Err(SimError::OutOfRange(format!(
                        "[spectrum] photons_per_mas_mm2 = {fluence}; it must be finite and > 0"
                    )));
                }
                Spectrum::monoenergetic(e, fluence)?
            }
            (None, None, Some(path)) => {
                Spectrum::from_file_in(path, self.fluence_unit.unwrap_or_default())?
            }
            _ => {
                return Err(SimError::OutOfRange(
                    "[spectrum] needs exactly one of kvp, energy_kev or file".into(),
                ));
            }
        };
        let mut s = base;
        for f in &self.filtration {
            s = s.filtered(&Filter::named(&f.material, f.thickness_mm)?)?;
        }
        if let Some(n) = self.bins {
            if n == 0 {
                return Err(SimError::OutOfRange("[spectrum] bins = 0; give ≥ 1".into()));
            }
            s = s.rebinned(n);
        }
        if !(self.mas.is_finite() && self.mas > 0.0) {
            return Err(SimError::OutOfRange(format!(
                "[spectrum] mas = {}; it must be finite and > 0",
                self.mas
            )));
        }
        Ok(s)
    }
}

/// A complete acquisition: spectrum, tissue model, detector and what to output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub struct Acquisition {
    /// The beam.
    pub spectrum: SpectrumSpec,
    /// HU → materials.
    pub materials: TissueModel,
    /// The detector.
    pub detector: DetectorModel,
    /// What the image holds: raw signal, flat-field-corrected transmission, or −log.
    #[serde(default)]
    pub output: Output,
    /// Scattered radiation (default none: primary only, at no cost).
    #[serde(default)]
    pub scatter: ScatterModel,
    /// An anti-scatter grid in front of the detector (default none): it attenuates the
    /// primary by Tp(E) and each scattered photon by its direction ([`crate::scatter::
    /// anti_scatter_grid`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub anti_scatter_grid: Option<AntiScatterGrid>,
}

/// Names of the acquisition presets ([`Acquisition::preset`]); `ideal-drr` is the
/// monochromatic projector and has no acquisition.
pub const PRESETS: &[&str] = &["ideal-drr", "kv-flat-panel-120kvp", "cbct-100kvp"];

impl Acquisition {
    /// A named preset:
    /// * `kv-flat-panel-120kvp` — chest radiography: 120 kVp, 2.5 mm Al + 0.1 mm Cu added,
    ///   1 mAs, Schneider tissues, indirect CsI flat panel, −log output;
    /// * `cbct-100kvp` — a linac/C-arm CBCT projection: 100 kVp, 2.5 mm Al + 0.2 mm Cu
    ///   (bow-tie not modelled), 0.4 mAs, Schneider tissues, CBCT panel, −log output.
    pub fn preset(name: &str) -> Result<Self> {
        match name {
            "kv-flat-panel-120kvp" => Ok(Self {
                spectrum: SpectrumSpec::tungsten(120.0, &[("al", 2.5), ("cu", 0.1)], 1.0),
                materials: TissueModel::schneider(),
                detector: DetectorModel::kv_flat_panel(),
                output: Output::LogLineIntegral,
                scatter: ScatterModel::None,
                anti_scatter_grid: None,
            }),
            "cbct-100kvp" => Ok(Self {
                spectrum: SpectrumSpec::tungsten(100.0, &[("al", 2.5), ("cu", 0.2)], 0.4),
                materials: TissueModel::schneider(),
                detector: DetectorModel::cbct(),
                output: Output::LogLineIntegral,
                scatter: ScatterModel::None,
                anti_scatter_grid: None,
            }),
            "ideal-drr" => Err(SimError::OutOfRange(
                "'ideal-drr' is the monochromatic projector itself, not an acquisition".into(),
            )),
            _ => Err(SimError::OutOfRange(format!(
                "unknown acquisition preset '{name}'; presets are {}",
                PRESETS.join(", ")
            ))),
        }
    }

    /// Resolves the spectrum, materials and detector for a CT volume (HU): classifies the
    /// voxels (once) and tabulates every present material's attenuation and the
    /// detector's response at the spectrum's energies. `seed` seeds the detector noise:
    /// view `i`'s frame and the calibration frames each get a stream derived from it.
    pub fn prepare(&self, hu: &Volume, seed: u64) -> Result<Prepared> {
        self.prepare_with_meshes(hu, seed, None)
    }

    /// The absorbed dose `views` deliver to the CT `hu` (HU) with this acquisition's
    /// spectrum, exposure (mAs per view) and tissues: `photons` Monte Carlo histories per
    /// view, each view's source collimated to its detector (docs/scatter.md, "Dose").
    /// Seeded; the bytes do not depend on the thread count.
    pub fn dose(
        &self,
        hu: &Volume,
        views: &[View],
        photons: u64,
        seed: u64,
    ) -> Result<crate::scatter::dose::Dose> {
        let spectrum = self.spectrum.spectrum()?;
        let (composition, materials) = self.materials.composition(hu)?;
        let e_max = spectrum.energies_kev().iter().copied().fold(1.0, f64::max);
        let medium = transport::Medium::new(&composition, &materials, e_max)?;
        crate::scatter::dose::acquisition_dose(
            &medium,
            &spectrum,
            self.spectrum.mas,
            views,
            photons,
            seed,
        )
    }

    /// [`Acquisition::prepare`] with mesh objects in the same rays: each mesh names a
    /// material of the library ([`material::by_name`]) and has a density
    /// ([`tomograf_sim::mesh::MeshObject::density_g_cm3`]); inside a mesh its material replaces
    /// the voxels', and its mass thickness enters the polychromatic integration as one
    /// more material (one per distinct mesh material name). Scatter is not modelled with
    /// meshes (the Monte Carlo medium is the voxel composition): asking for both is an
    /// error.
    pub fn prepare_with_meshes(
        &self,
        hu: &Volume,
        seed: u64,
        meshes: Option<Arc<MeshScene>>,
    ) -> Result<Prepared> {
        self.detector.validate()?;
        let meshes = meshes.filter(|m| !m.is_empty());
        if meshes.is_some() && !self.scatter.is_none() {
            return Err(SimError::OutOfRange(
                "scatter with mesh objects is not modelled (the Monte Carlo medium is the voxel \
                 composition): drop [scatter] or the meshes"
                    .into(),
            ));
        }
        let spectrum = self.spectrum.spectrum()?;
        let (composition, materials) = self.materials.composition(hu)?;
        let energies = spectrum.energies_kev().to_vec();
        let table = |m: &Material| {
            energies
                .iter()
                .map(|&e| m.mass_attenuation(e))
                .collect::<Result<Vec<f64>>>()
        };
        let mut attenuation = materials
            .iter()
            .map(|m| Ok((m.name().to_string(), table(m)?)))
            .collect::<Result<Vec<_>>>()?;
        let mut columns = composition.materials().to_vec();
        if let Some(m) = &meshes {
            for name in m.materials().0 {
                let material = material::by_name(&name).map_err(|e| match e {
                    SimError::UnknownMaterial(msg) => {
                        SimError::UnknownMaterial(format!("{msg} (named by a mesh)"))
                    }
                    other => other,
                })?;
                attenuation.push((name.clone(), table(&material)?));
                columns.push(name);
            }
        }
        let mut absorption = match &self.detector.scintillator {
            Some(s) => s.absorption_at(&energies)?,
            None => vec![1.0; energies.len()],
        };
        let e_top = energies.iter().copied().fold(1.0, f64::max);
        if let Some(g) = &self.anti_scatter_grid {
            // The primary crosses the grid along the focus: a binomial thinning by Tp(E).
            let t = g.tabulate(e_top)?;
            for (a, &e) in absorption.iter_mut().zip(&energies) {
                *a *= t.primary(e);
            }
        }
        let weights = self.detector.channel_weights(&energies, &absorption)?;
        let scatter = if self.scatter.is_none() {
            None
        } else {
            self.scatter.validate()?;
            let e_max = energies.iter().copied().fold(1.0, f64::max);
            let medium = transport::Medium::new(&composition, &materials, e_max)?;
            // The detector's response on the medium's 1 keV grid (scattered energies).
            let grid: Vec<f64> = (0..=e_max.ceil() as usize)
                .map(|k| k as f64 + 1.0)
                .collect();
            let absorption = match &self.detector.scintillator {
                Some(s) => {
                    let clamped: Vec<f64> = grid.iter().map(|&e| e.min(500.0)).collect();
                    s.absorption_at(&clamped)?
                }
                None => vec![1.0; grid.len()],
            };
            let w = self.detector.channel_weights(&grid, &absorption)?;
            let response = estimator::Response {
                mean: w.mean,
                second_moment: w.second_moment,
            };
            let engine = ScatterEngine::new(
                medium,
                response,
                energies.clone(),
                spectrum.fluence(),
                self.spectrum.mas,
            )?;
            let engine = engine.with_anti_scatter_grid(self.anti_scatter_grid.as_ref())?;
            Some((self.scatter.clone(), engine))
        };
        let integrator =
            SpectralIntegrator::new(energies, spectrum.fluence(), attenuation, &weights)?;
        Ok(Prepared {
            composition,
            meshes,
            columns,
            integrator,
            detector: self.detector.clone(),
            output: self.output,
            mas: self.spectrum.mas,
            seed,
            flat: Mutex::new(None),
            scatter,
            column_copy: None,
            tracer: Tracer::Auto,
            orbit: None,
        })
    }
}

/// An acquisition resolved for one volume: render views with [`Prepared::acquire`].
#[derive(Debug)]
pub struct Prepared {
    composition: Composition,
    /// Mesh objects in the same rays (`None`: voxels only).
    meshes: Option<Arc<MeshScene>>,
    /// Mass-thickness columns: the composition's materials, then the mesh materials.
    columns: Vec<String>,
    integrator: SpectralIntegrator,
    detector: DetectorModel,
    output: Output,
    mas: f64,
    seed: u64,
    /// The last flat/dark calibration and the open field it was made for: views whose
    /// open field is the same (every view of a circular orbit) share one calibration, as
    /// on a real system.
    flat: Mutex<Option<(Vec<f64>, FlatField)>>,
    /// The scatter model and its engine, when scatter is modelled.
    scatter: Option<(ScatterModel, ScatterEngine)>,
    /// The composition stored k-fastest, for tracing detector columns as ray sheets, made
    /// once for a job's views ([`Prepared::for_views`]) and shared by every view's renderer.
    column_copy: Option<ColumnCopy>,
    /// The exact Siddon tracer of every view's renderer ([`Prepared::with_tracer`]).
    tracer: Tracer,
    /// The job's views, when the scatter model fits each view's scatter with its
    /// neighbours' in angle ([`crate::scatter::orbit`]; set by [`Prepared::for_views`]).
    orbit: Option<Arc<OrbitScatter>>,
}

impl Prepared {
    /// Renders every view with `tracer` ([`Renderer::with_tracer`]; default
    /// [`Tracer::Auto`]). Set it before [`Prepared::for_views`].
    pub fn with_tracer(mut self, tracer: Tracer) -> Self {
        self.tracer = tracer;
        self
    }

    /// The volume's material composition.
    pub fn composition(&self) -> &Composition {
        &self.composition
    }

    /// The spectral model.
    pub fn integrator(&self) -> &SpectralIntegrator {
        &self.integrator
    }

    /// Prepares for rendering `views` with `projector`: where enough of them would trace
    /// their detector columns as ray sheets ([`Renderer::for_views`]), the renderers of
    /// every view share one k-fastest copy of the composition, made here (about as long to
    /// make as one view takes; docs/projector.md, "Column sheets"). Images are unchanged.
    pub fn for_views(mut self, projector: Projector, views: &[View]) -> Result<Self> {
        if let Some((model, _)) = &self.scatter
            && model.angular_window_deg() > 0.0
        {
            self.orbit = Some(Arc::new(OrbitScatter::new(
                views.to_vec(),
                model.angular_window_deg(),
            )));
        }
        if self.meshes.is_none() {
            self.column_copy = Renderer::for_composition(&self.composition, projector)?
                .with_tracer(self.tracer)
                .for_views(views)
                .column_copy();
        }
        Ok(self)
    }

    /// Whether the views' renderers take a shared k-fastest copy ([`Prepared::for_views`]).
    pub fn shares_column_copy(&self) -> bool {
        self.column_copy.is_some()
            && Renderer::for_composition(&self.composition, Projector::Siddon).is_ok_and(|r| {
                r.with_column_copy(self.column_copy.as_ref())
                    .column_copy()
                    .is_some()
            })
    }

    /// Per-material mass thickness of one view.
    pub fn mass_thickness(&self, projector: Projector, view: &View) -> Result<MassThickness> {
        let mut r = Renderer::for_composition(&self.composition, projector)?
            .with_column_copy(self.column_copy.as_ref());
        if let Some(m) = &self.meshes {
            r = r.with_meshes(m.clone())?;
        }
        // After the shared copy: `columns` takes it instead of making its own.
        r.with_tracer(self.tracer)
            .mass_thickness(view, &self.columns)
    }

    /// The expected (noiseless) primary signal of a view (through the anti-scatter grid, if
    /// any), without scatter.
    pub fn primary(&self, projector: Projector, view: &View) -> Result<ExpectedImage> {
        let t = self.mass_thickness(projector, view)?;
        self.integrator.expected(&t, view, self.mas)
    }

    /// The expected (noiseless) signal of a view, and of the same view without the object
    /// (for flat fields).
    pub fn expected(
        &self,
        projector: Projector,
        view: &View,
    ) -> Result<(ExpectedImage, ExpectedImage)> {
        let t = self.mass_thickness(projector, view)?;
        let mut object = self.integrator.expected(&t, view, self.mas)?;
        self.add_scatter(&mut object, view, 0)?;
        let open = self.integrator.open(view, self.mas)?;
        Ok((object, open))
    }

    /// The same acquisition with its scatter transport tracked with majorants per brick of
    /// `size³` voxels (`Some`; the default, 16³) or one for the whole volume (`None`), for
    /// ablations (`physics/examples/scatter_tracking.rs`). No effect without scatter.
    pub fn with_majorant_bricks(mut self, size: Option<usize>) -> Result<Self> {
        if let Some((model, engine)) = self.scatter.take() {
            self.scatter = Some((model, engine.with_majorant_bricks(size)?));
        }
        Ok(self)
    }

    /// The scatter engine, when scatter is modelled.
    pub fn scatter_engine(&self) -> Option<&ScatterEngine> {
        self.scatter.as_ref().map(|(_, engine)| engine)
    }

    /// The scatter images of view number `index` (`None` when scatter is not modelled).
    /// Their random streams derive from the seed and `index` alone — and, when the model
    /// fits views in angle and `view` is the job's view `index` ([`Prepared::for_views`]),
    /// from those of its neighbours, which are then made too ([`crate::scatter::orbit`]).
    pub fn scatter(&self, view: &View, index: usize) -> Result<Option<ScatterImages>> {
        match &self.orbit {
            Some(orbit) if orbit.holds(index, view) => {
                orbit.images(index, |j| self.raw_scatter(&orbit.view(j), j))
            }
            _ => self.raw_scatter(view, index),
        }
    }

    /// View `index`'s scatter images from its own histories alone.
    fn raw_scatter(&self, view: &View, index: usize) -> Result<Option<ScatterImages>> {
        match &self.scatter {
            None => Ok(None),
            Some((model, engine)) => engine.run(
                model,
                view,
                frame_seed(self.seed ^ SCATTER_STREAM, index as u64 + 1),
            ),
        }
    }

    /// Adds view `index`'s expected scatter signal (mean and second moment) to `object`.
    fn add_scatter(&self, object: &mut ExpectedImage, view: &View, index: usize) -> Result<()> {
        if let Some(s) = self.scatter(view, index)? {
            add_into(object, &s.total());
        }
        Ok(())
    }

    /// Acquired view number `index`: one image per detector channel, as the acquisition's
    /// output says. Its noise stream is derived from the seed and `index` alone, and the
    /// flat/dark calibration (when the output needs one) from the seed alone, so the bytes
    /// do not depend on the order views are acquired in or on the thread count.
    pub fn acquire(
        &self,
        projector: Projector,
        view: &View,
        index: usize,
    ) -> Result<Vec<Projection>> {
        Ok(self.acquire_with_parts(projector, view, index)?.images)
    }

    /// [`Prepared::acquire`], also returning the parts the image was made of: the expected
    /// primary signal and the scatter images (one Monte Carlo run serves both).
    pub fn acquire_with_parts(
        &self,
        projector: Projector,
        view: &View,
        index: usize,
    ) -> Result<Acquired> {
        let t = self.mass_thickness(projector, view)?;
        let primary = self.integrator.expected(&t, view, self.mas)?;
        let scatter = self.scatter(view, index)?;
        let mut object = primary.clone();
        if let Some(s) = &scatter {
            add_into(&mut object, &s.total());
        }
        let raw = self
            .detector
            .record(&object, frame_seed(self.seed, index as u64 + 1))?;
        let saturated = self
            .detector
            .saturated(&raw, object.pitch_u_mm, object.pitch_v_mm);
        let mut clipped = 0;
        let images = if self.output == Output::Raw {
            raw
        } else {
            let open = self.integrator.open(view, self.mas)?;
            let mut cache = self.flat.lock().unwrap_or_else(|e| e.into_inner());
            let fresh = !matches!(&*cache, Some((mean, _)) if *mean == open.mean);
            if fresh {
                let flat = self.detector.calibrate(&open, frame_seed(self.seed, 0))?;
                *cache = Some((open.mean, flat));
            }
            let (_, flat) = cache.as_ref().expect("calibrated above");
            if self.output == Output::LogLineIntegral {
                clipped = flat.clipped(&raw);
            }
            flat.apply(&raw, self.output)?
        };
        Ok(Acquired {
            images,
            primary,
            scatter,
            clipped,
            saturated,
        })
    }
}

/// One acquired view and the parts it was made of ([`Prepared::acquire_with_parts`]).
#[derive(Debug, Clone)]
pub struct Acquired {
    /// The recorded images, one per detector channel (the acquisition's output).
    pub images: Vec<Projection>,
    /// The expected primary signal (through the anti-scatter grid, if any).
    pub primary: ExpectedImage,
    /// The scatter images (`None` when scatter is not modelled).
    pub scatter: Option<ScatterImages>,
    /// Pixels (all channels) whose −log hit the floor for lack of signal (photon
    /// starvation: raise the mAs), 0 for other outputs ([`crate::detector::FlatField::clipped`]).
    pub clipped: usize,
    /// Pixels (all channels) at the readout's ceiling: saturation or the ADC's top code.
    pub saturated: usize,
}

/// Adds `b`'s mean and second moment to `a`'s (same layout).
pub fn add_into(a: &mut ExpectedImage, b: &ExpectedImage) {
    a.mean.iter_mut().zip(&b.mean).for_each(|(x, y)| *x += y);
    a.second_moment
        .iter_mut()
        .zip(&b.second_moment)
        .for_each(|(x, y)| *x += y);
}

/// Mixed into the acquisition seed for the scatter's random streams (distinct from noise).
const SCATTER_STREAM: u64 = 0x5CA7_7E2D_0000_0001;
