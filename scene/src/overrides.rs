//! Overrides of a scene's real detector physics by name — what `tomograf project` and
//! `tomograf dataset` take as flags, and what the studies' data sets are made of — as plain
//! data: a preset, a tube voltage, an exposure, a detector model, a scatter model.

use crate::Scene;
use crate::physics::{acquisition, scatter_model};
use anyhow::{Result, bail};
use tomograf_physics::acquisition::{Acquisition, SpectrumSpec};

/// Named physics settings that override a scene's (every field optional; `None` keeps the
/// scene's value). Names as in docs/physics.md, docs/detector.md and docs/scatter.md.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PhysicsOverrides {
    /// Acquisition preset: ideal-drr, kv-flat-panel-120kvp or cbct-100kvp.
    pub preset: Option<String>,
    /// Tungsten-anode tube voltage, kVp (40–150); a preset keeps its filtration and mA·s.
    pub kvp: Option<f64>,
    /// Exposure per view, mA·s.
    pub mas: Option<f64>,
    /// Energy bins of the rebinned spectrum.
    pub energy_bins: Option<usize>,
    /// Seed of the detector noise.
    pub noise_seed: Option<u64>,
    /// What the detector images hold: raw, flat-field or log-line-integral.
    pub signal: Option<String>,
    /// Detector model by name, replacing the preset's.
    pub detector_model: Option<String>,
    /// Scattered radiation: none, estimate or monte-carlo.
    pub scatter: Option<String>,
    /// Photon histories per view of the scatter model.
    pub scatter_photons: Option<u64>,
}

impl PhysicsOverrides {
    /// Writes the overrides into the scene (they win over its fields).
    pub fn merge_into(&self, s: &mut Scene) -> Result<()> {
        if self.preset.is_some() {
            s.acquisition.preset = self.preset.clone();
        }
        if self.noise_seed.is_some() {
            s.acquisition.seed = self.noise_seed;
        }
        if self.signal.is_some() {
            s.acquisition.signal = self.signal.clone();
        }
        if self.detector_model.is_some() {
            s.detector.model = self.detector_model.clone();
        }
        if let Some(model) = scatter_model(self.scatter.as_deref(), self.scatter_photons)? {
            // The scene's images and anti-scatter grid stay; the flags choose the model.
            s.scatter.get_or_insert_with(Default::default).model = model;
        }
        if let Some(kvp) = self.kvp {
            // A preset's beam keeps its filtration and exposure at the new voltage.
            let old = match (s.spectrum.take(), s.acquisition.preset.as_deref()) {
                (Some(old), _) => Some(old),
                (None, Some(p)) if p != "ideal-drr" => Some(Acquisition::preset(p)?.spectrum),
                (None, _) => None,
            };
            s.spectrum = Some(SpectrumSpec {
                kvp: Some(kvp),
                energy_kev: None,
                photons_per_mas_mm2: None,
                file: None,
                fluence_unit: None,
                ..old.unwrap_or_else(|| SpectrumSpec::tungsten(kvp, &[], 1.0))
            });
        }
        if self.mas.is_some() || self.energy_bins.is_some() {
            let spec = match (s.spectrum.as_mut(), s.acquisition.preset.as_deref()) {
                (Some(spec), _) => spec,
                (None, Some(p)) if p != "ideal-drr" => {
                    s.spectrum = Some(Acquisition::preset(p)?.spectrum);
                    s.spectrum.as_mut().expect("just set")
                }
                _ => bail!(
                    "mas and energy_bins (--mas, --energy-bins) need a spectrum: give [spectrum] \
                     (--kvp) or [acquisition] preset (--preset)"
                ),
            };
            if let Some(m) = self.mas {
                spec.mas = m;
            }
            if let Some(b) = self.energy_bins {
                spec.bins = Some(b);
            }
        }
        Ok(())
    }

    /// The acquisition these overrides alone ask for (on a default scene), with its noise
    /// seed; `None` for the ideal DRR.
    pub fn acquisition(&self) -> Result<Option<(Acquisition, u64)>> {
        let mut scene = Scene::default();
        self.merge_into(&mut scene)?;
        acquisition(&scene)
    }
}
