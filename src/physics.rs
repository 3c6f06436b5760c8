//! Real detector physics on the command line: the scene's `[acquisition]`, `[spectrum]`,
//! `[materials]` and detector-model fields (and their flags) resolved into a
//! [`tomograf_sim::acquisition::Acquisition`]. A scene that asks for none of it renders the
//! ideal DRR with the monochromatic projector and pays for nothing else.

use crate::scene::Scene;
use anyhow::{Result, bail};
use clap::Args;
use tomograf_sim::acquisition::{Acquisition, PRESETS, SpectrumSpec};
use tomograf_sim::detector::{DetectorModel, Output};
use tomograf_sim::scatter::ScatterModel;
use tomograf_sim::tissue::TissueModel;

/// Flags of `tomograf project` and `tomograf dataset` for real detector physics.
#[derive(Debug, Args, Clone, Default)]
pub struct PhysicsArgs {
    /// Acquisition preset: ideal-drr (the default: monochromatic DRR), kv-flat-panel-120kvp
    /// or cbct-100kvp. See docs/physics.md.
    #[arg(long)]
    pub preset: Option<String>,
    /// Tungsten-anode tube voltage, kVp (40–150); replaces the preset's (which keeps its
    /// filtration and mA·s).
    #[arg(long)]
    pub kvp: Option<f64>,
    /// Exposure per view, mA·s.
    #[arg(long)]
    pub mas: Option<f64>,
    /// Rebin the spectrum to this many energy bins [default: 1 keV bins].
    #[arg(long)]
    pub energy_bins: Option<usize>,
    /// Seed of the detector noise [default: 0].
    #[arg(long)]
    pub noise_seed: Option<u64>,
    /// What the detector images hold: raw, flat-field or log-line-integral
    /// [default: log-line-integral].
    #[arg(long)]
    pub signal: Option<String>,
    /// Detector model: perfect-absorber (alias ideal: η = 1, no noise, no blur),
    /// noiseless-csi (the flat panel's 0.6 mm CsI energy response, no noise, no blur),
    /// kv-flat-panel, cbct or photon-counting; replaces the preset's detector (e.g.
    /// `--preset kv-flat-panel-120kvp --detector-model noiseless-csi`: the polychromatic
    /// beam and the panel's energy response without noise or blur). See docs/detector.md.
    #[arg(long)]
    pub detector_model: Option<String>,
    /// Scattered radiation: none (default), estimate (fast: coarse Monte Carlo, smoothed)
    /// or monte-carlo (forced detection). See docs/scatter.md.
    #[arg(long)]
    pub scatter: Option<String>,
    /// Photon histories per view of the scatter model [default: 5000 for estimate,
    /// 100000 for monte-carlo].
    #[arg(long)]
    pub scatter_photons: Option<u64>,
}

impl PhysicsArgs {
    /// Writes the flags into the scene (flags win).
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
                _ => bail!("--mas and --energy-bins need a spectrum: give --kvp or --preset"),
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
}

/// The scatter model `--scatter NAME` and `--scatter-photons N` ask for; `None` when
/// neither is given or the name is `none` (the default: primary only). The other settings
/// take sim's defaults for the model (those of a scene's `[scatter]` table).
pub fn scatter_model(name: Option<&str>, photons: Option<u64>) -> Result<Option<ScatterModel>> {
    let name = match (name, photons) {
        (None, None) | (Some("none"), None) => return Ok(None),
        (None | Some("none"), Some(_)) => {
            bail!("--scatter-photons needs --scatter estimate or --scatter monte-carlo")
        }
        (Some(n @ ("estimate" | "monte-carlo")), _) => n,
        (Some(other), _) => {
            bail!("unknown --scatter '{other}': use none, estimate or monte-carlo")
        }
    };
    let mut model: ScatterModel = toml::from_str(&format!("model = \"{name}\""))?;
    if let Some(n) = photons {
        match &mut model {
            ScatterModel::Estimate { photons, .. } | ScatterModel::MonteCarlo { photons, .. } => {
                *photons = n
            }
            _ => {}
        }
    }
    model.validate()?;
    Ok(Some(model))
}

/// The acquisition the flags alone ask for (no scene file), with its noise seed.
pub fn from_args(args: &PhysicsArgs) -> Result<Option<(Acquisition, u64)>> {
    let mut scene = Scene::default();
    args.merge_into(&mut scene)?;
    acquisition(&scene)
}

/// The acquisition a scene asks for, with its noise seed; `None` for the ideal DRR.
pub fn acquisition(scene: &Scene) -> Result<Option<(Acquisition, u64)>> {
    let d = &scene.detector;
    let a = &scene.acquisition;
    let asks = scene.spectrum.is_some()
        || scene.materials.is_some()
        || d.model.is_some()
        || d.response.is_some()
        || d.thresholds_kev.is_some()
        || a.signal.is_some()
        || a.seed.is_some()
        || scene.scatter.is_some();
    let mut acq = match a.preset.as_deref() {
        None | Some("ideal-drr") if !asks => return Ok(None),
        Some("ideal-drr") => bail!(
            "preset ideal-drr is the monochromatic projector: it takes no spectrum, materials, \
             detector model, signal or seed (choose one of {})",
            PRESETS.join(", ")
        ),
        Some(p) => Acquisition::preset(p)?,
        None => {
            let Some(spectrum) = scene.spectrum.clone() else {
                bail!(
                    "real detector physics needs a beam: give [spectrum] (or --kvp) or a preset \
                     ({})",
                    PRESETS.join(", ")
                );
            };
            Acquisition {
                spectrum,
                materials: TissueModel::schneider(),
                detector: DetectorModel::ideal(),
                output: Output::LogLineIntegral,
                scatter: Default::default(),
                anti_scatter_grid: None,
            }
        }
    };
    if let Some(s) = &scene.spectrum {
        acq.spectrum = s.clone();
    }
    if let Some(m) = &scene.materials {
        let mut model = match m.model.as_deref() {
            None | Some("schneider") => TissueModel::schneider(),
            Some("five-tissue") => TissueModel::five_tissue(),
            Some("water") => TissueModel::water(70.0),
            Some(other) => {
                bail!("unknown materials model '{other}': use schneider, five-tissue or water")
            }
        };
        if let Some(bins) = &m.bins {
            model.bins = bins.clone();
        }
        if let Some(e) = m.calibration_kev {
            model.calibration_kev = e;
        }
        if let Some(w) = m.blend_hu {
            model.blend_hu = w;
        }
        model.validate()?;
        acq.materials = model;
    }
    if let Some(r) = &d.response {
        if d.model.is_some() || d.thresholds_kev.is_some() {
            bail!("[detector] response replaces model and thresholds_kev: give one or the other");
        }
        acq.detector = r.clone();
    } else if let Some(m) = &d.model {
        acq.detector = DetectorModel::by_name(m, d.thresholds_kev.clone())?;
    } else if d.thresholds_kev.is_some() {
        bail!("thresholds_kev applies to the photon-counting detector model only");
    }
    if let Some(s) = &a.signal {
        acq.output = Output::from_name(s)?;
    }
    if let Some(s) = &scene.scatter {
        s.validate()?;
        acq.scatter = s.model.clone();
        acq.anti_scatter_grid = s.anti_scatter_grid.clone();
    }
    acq.detector.validate()?;
    Ok(Some((acq, a.seed.unwrap_or(0))))
}

/// The noise seed of data-set item `index` from the run's noise seed.
pub fn item_seed(seed: u64, index: usize) -> u64 {
    tomograf_sim::seed::frame_seed(seed ^ 0xD47A_5E7D_A7A5_E7D0, index as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scatter_flags_pick_the_model_and_keep_sims_defaults() {
        assert_eq!(scatter_model(None, None).unwrap(), None);
        assert_eq!(scatter_model(Some("none"), None).unwrap(), None);
        // The defaults are those of a scene's `[scatter] model = "estimate"` table.
        let scene: ScatterModel = toml::from_str("model = \"estimate\"").unwrap();
        assert_eq!(scatter_model(Some("estimate"), None).unwrap(), Some(scene));
        match scatter_model(Some("monte-carlo"), Some(123)).unwrap() {
            Some(ScatterModel::MonteCarlo { photons, .. }) => assert_eq!(photons, 123),
            other => panic!("{other:?}"),
        }
        let e = scatter_model(Some("estimate"), Some(0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("photons = 0"), "{e}");
        let e = scatter_model(Some("fog"), None).unwrap_err().to_string();
        assert!(e.contains("unknown --scatter 'fog'"), "{e}");
    }

    #[test]
    fn kvp_on_a_preset_keeps_its_filtration_and_exposure() {
        let args = PhysicsArgs {
            preset: Some("kv-flat-panel-120kvp".into()),
            kvp: Some(80.0),
            detector_model: Some("ideal".into()),
            ..PhysicsArgs::default()
        };
        let (acq, _) = from_args(&args).unwrap().unwrap();
        let preset = Acquisition::preset("kv-flat-panel-120kvp").unwrap();
        assert_eq!(acq.spectrum.kvp, Some(80.0));
        assert_eq!(acq.spectrum.filtration, preset.spectrum.filtration);
        assert_eq!(acq.spectrum.mas, preset.spectrum.mas);
        assert_eq!(acq.detector, DetectorModel::ideal());
    }
}
