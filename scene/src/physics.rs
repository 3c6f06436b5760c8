//! Real detector physics of a scene: its `[acquisition]`, `[spectrum]`, `[materials]`,
//! `[scatter]` and detector-model fields resolved into a
//! [`tomograf_physics::acquisition::Acquisition`]. A scene that asks for none of it renders the
//! ideal DRR with the monochromatic projector and pays for nothing else.

use crate::Scene;
use anyhow::{Result, bail};
use tomograf_physics::acquisition::{Acquisition, PRESETS};
use tomograf_physics::detector::{DetectorModel, Output};
use tomograf_physics::scatter::ScatterModel;
use tomograf_sim::tissue::TissueModel;

/// The scatter model `--scatter NAME` and `--scatter-photons N` ask for; `None` when
/// neither is given or the name is `none` (the default: primary only). The other settings
/// take sim's defaults for the model (those of a scene's `[scatter]` table).
pub fn scatter_model(name: Option<&str>, photons: Option<u64>) -> Result<Option<ScatterModel>> {
    let name = match (name, photons) {
        (None, None) | (Some("none"), None) => return Ok(None),
        (None | Some("none"), Some(_)) => {
            bail!(
                "[scatter] photons (--scatter-photons) needs model = \"estimate\" or \"monte-carlo\" (--scatter)"
            )
        }
        (Some(n @ ("estimate" | "monte-carlo")), _) => n,
        (Some(other), _) => {
            bail!(
                "unknown [scatter] model (--scatter) '{other}': use none, estimate or monte-carlo"
            )
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
        assert!(e.contains("(--scatter) 'fog'"), "{e}");
    }
}
