//! Real detector physics on the command line: the scene's `[acquisition]`, `[spectrum]`,
//! `[materials]` and detector-model fields (and their flags) resolved into a
//! [`tomograf_physics::acquisition::Acquisition`]. A scene that asks for none of it renders the
//! ideal DRR with the monochromatic projector and pays for nothing else.

use anyhow::Result;
use clap::Args;
use tomograf_physics::acquisition::Acquisition;
use tomograf_scene::Scene;
pub use tomograf_scene::overrides::PhysicsOverrides;

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
    /// The flags as plain data.
    pub fn overrides(&self) -> PhysicsOverrides {
        PhysicsOverrides {
            preset: self.preset.clone(),
            kvp: self.kvp,
            mas: self.mas,
            energy_bins: self.energy_bins,
            noise_seed: self.noise_seed,
            signal: self.signal.clone(),
            detector_model: self.detector_model.clone(),
            scatter: self.scatter.clone(),
            scatter_photons: self.scatter_photons,
        }
    }

    /// Writes the flags into the scene (flags win).
    pub fn merge_into(&self, s: &mut Scene) -> Result<()> {
        self.overrides().merge_into(s)
    }
}

/// The acquisition the flags alone ask for (no scene file), with its noise seed.
pub fn from_args(args: &PhysicsArgs) -> Result<Option<(Acquisition, u64)>> {
    args.overrides().acquisition()
}

#[cfg(test)]
mod tests {
    use super::*;
    use tomograf_physics::acquisition::Acquisition;
    use tomograf_physics::detector::DetectorModel;

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
