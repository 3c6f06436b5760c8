//! Real detector physics on the command line: the scene's `[acquisition]`, `[spectrum]`,
//! `[materials]` and detector-model fields (and their flags) resolved into a
//! [`tomograf_sim::acquisition::Acquisition`]. A scene that asks for none of it renders the
//! ideal DRR with the monochromatic projector and pays for nothing else.

use anyhow::{Result, bail};
use clap::Args;
use tomograf_scene::Scene;
pub use tomograf_scene::physics::{acquisition, scatter_model};
use tomograf_sim::acquisition::{Acquisition, SpectrumSpec};

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

/// The acquisition the flags alone ask for (no scene file), with its noise seed.
pub fn from_args(args: &PhysicsArgs) -> Result<Option<(Acquisition, u64)>> {
    let mut scene = Scene::default();
    args.merge_into(&mut scene)?;
    acquisition(&scene)
}

#[cfg(test)]
mod tests {
    use super::*;
    use tomograf_sim::acquisition::Acquisition;
    use tomograf_sim::detector::DetectorModel;

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
