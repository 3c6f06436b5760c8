//! Energy response: how many signal units each photon reaching a pixel contributes, per
//! output channel and energy bin.
//!
//! A photon of energy E reaching the pixel is absorbed in the scintillator (or sensor) with
//! probability η(E) (the absorption efficiency, [`absorption_efficiency`]). An absorbed
//! photon contributes a signal s_c(E) to channel c:
//!
//! * **energy integrating**: s(E) = G·E, G the conversion gain in signal units (ADU) per keV
//!   absorbed; one channel;
//! * **photon counting**: s_c(E) = 1 when T_c ≤ E < T_c+1 (the last channel is open-ended),
//!   else 0; one channel per threshold. No charge sharing, pile-up or threshold dispersion
//!   is modelled: each absorbed photon is counted once, at its full energy.
//!
//! With N_b Poisson-distributed photons in bin b, the channel signal is a compound Poisson
//! sum with mean Σ_b N_b·η_b·s_c(E_b) and variance (its second moment per photon)
//! Σ_b N_b·η_b·s_c(E_b)²/I, where I ∈ (0, 1] is the Swank factor (the spread of the signal
//! per absorbed photon; 1 for photon counting and for an ideal energy integrator).
//! Note the variance weight is η·s², not (η·s)²: a photon that is not absorbed contributes
//! zero, so E[X²] = η·s² per incident photon. [`ChannelWeights`] holds both weights.

use serde::{Deserialize, Serialize};
use tomograf_sim::error::{Result, SimError};

/// How the detector turns absorbed photons into a signal.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(
    tag = "kind",
    rename_all = "kebab-case",
    rename_all_fields = "snake_case",
    deny_unknown_fields
)]
pub enum Mode {
    /// A scintillator + photodiode (or direct converter) integrating the absorbed energy:
    /// one channel, in signal units (ADU).
    EnergyIntegrating {
        /// Signal units (ADU, before gain non-uniformity) per keV absorbed; > 0.
        conversion_gain_adu_per_kev: f64,
        /// Swank factor I ∈ (0, 1]: variance of the signal per absorbed photon is
        /// (G·E)²/I. 1 = no gain fluctuation.
        #[serde(default = "one")]
        swank_factor: f64,
    },
    /// A counting detector with energy thresholds, keV: one channel (counts) per
    /// threshold, channel c counting T_c ≤ E < T_c+1, the last open-ended.
    PhotonCounting {
        /// Strictly increasing, finite, ≥ 0 keV; at least one.
        thresholds_kev: Vec<f64>,
    },
}

fn one() -> f64 {
    1.0
}

impl Mode {
    /// Ideal energy integration: 1 ADU per keV, no gain fluctuation.
    pub fn energy_integrating(conversion_gain_adu_per_kev: f64) -> Self {
        Self::EnergyIntegrating {
            conversion_gain_adu_per_kev,
            swank_factor: 1.0,
        }
    }

    /// Number of output channels (1 for energy integration, one per threshold otherwise).
    pub fn channels(&self) -> usize {
        match self {
            Self::EnergyIntegrating { .. } => 1,
            Self::PhotonCounting { thresholds_kev } => thresholds_kev.len(),
        }
    }

    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        match self {
            Self::EnergyIntegrating {
                conversion_gain_adu_per_kev: g,
                swank_factor: s,
            } => {
                if !(g.is_finite() && *g > 0.0) {
                    return Err(bad(format!(
                        "detector conversion gain is {g} ADU/keV; it must be finite and > 0"
                    )));
                }
                if !(s.is_finite() && *s > 0.0 && *s <= 1.0) {
                    return Err(bad(format!(
                        "detector Swank factor is {s}; it must be in (0, 1]"
                    )));
                }
            }
            Self::PhotonCounting { thresholds_kev: t } => {
                if t.is_empty() {
                    return Err(bad(
                        "photon-counting detector needs at least one energy threshold".into(),
                    ));
                }
                if let Some(x) = t.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
                    return Err(bad(format!(
                        "photon-counting threshold {x} keV; thresholds must be finite and ≥ 0"
                    )));
                }
                if let Some(w) = t.windows(2).find(|w| w[1] <= w[0]) {
                    return Err(bad(format!(
                        "photon-counting thresholds must be strictly increasing; {} keV is \
                         followed by {} keV",
                        w[0], w[1]
                    )));
                }
            }
        }
        Ok(())
    }
}

/// Per channel c and energy bin b, the first and second moment of the signal one photon
/// of energy E_b reaching the pixel contributes: mean signal of channel c =
/// Σ_b N_b·`mean[c][b]`, quantum-noise variance = Σ_b N_b·`second_moment[c][b]`.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelWeights {
    /// E[X] per incident photon, signal units (ADU or counts); `[channel][bin]`.
    pub mean: Vec<Vec<f64>>,
    /// E[X²] per incident photon, signal units²; `[channel][bin]`.
    pub second_moment: Vec<Vec<f64>>,
}

/// Fraction of photons absorbed in a layer of linear attenuation `mu_per_mm` (mm⁻¹) and
/// thickness `thickness_mm` (mm) at normal incidence: 1 − exp(−μt). Uses `exp_m1` so thin
/// layers keep full precision.
pub fn absorption_efficiency(mu_per_mm: f64, thickness_mm: f64) -> f64 {
    -(-mu_per_mm * thickness_mm).exp_m1()
}

/// The detector's converter layer. Its attenuation comes from the materials data, so the
/// caller turns μ(E) into η(E) with [`Scintillator::absorption`] and passes η to
/// [`channel_weights`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub struct Scintillator {
    /// Material name as the materials tables know it (e.g. "CsI", "Gd2O2S").
    pub material: String,
    /// Layer thickness, mm; > 0.
    pub thickness_mm: f64,
}

impl Scintillator {
    /// Checks the thickness.
    pub fn validate(&self) -> Result<()> {
        if !(self.thickness_mm.is_finite() && self.thickness_mm > 0.0) {
            return Err(bad(format!(
                "scintillator thickness is {} mm; it must be finite and > 0",
                self.thickness_mm
            )));
        }
        Ok(())
    }

    /// η(E) at `energies_kev` (keV), from the layer's material in the material library
    /// ([`tomograf_sim::material::by_name`]): its mass attenuation (cm²/g) times its density
    /// (g/cm³) is μ in cm⁻¹, a tenth of that in mm⁻¹ ([`Scintillator::absorption`]).
    pub fn absorption_at(&self, energies_kev: &[f64]) -> Result<Vec<f64>> {
        let m = tomograf_sim::material::by_name(&self.material)?;
        let mu = energies_kev
            .iter()
            .map(|&e| Ok(m.mass_attenuation(e)? * m.density() / 10.0))
            .collect::<Result<Vec<f64>>>()?;
        self.absorption(&mu)
    }

    /// η(E) for the layer's linear attenuation `mu_per_mm` (mm⁻¹, one per energy bin, as
    /// the materials data give it for this material and density).
    pub fn absorption(&self, mu_per_mm: &[f64]) -> Result<Vec<f64>> {
        self.validate()?;
        mu_per_mm
            .iter()
            .map(|&mu| {
                if mu.is_finite() && mu >= 0.0 {
                    Ok(absorption_efficiency(mu, self.thickness_mm))
                } else {
                    Err(bad(format!(
                        "scintillator attenuation {mu} mm⁻¹; it must be finite and ≥ 0"
                    )))
                }
            })
            .collect()
    }
}

/// The weights for `mode` at bin energies `energies_kev` (keV, > 0) with absorption
/// efficiencies `absorption` (η ∈ [0, 1], one per bin). See the module docs.
pub fn channel_weights(
    mode: &Mode,
    energies_kev: &[f64],
    absorption: &[f64],
) -> Result<ChannelWeights> {
    mode.validate()?;
    if energies_kev.is_empty() {
        return Err(bad("no energy bins given for the detector response".into()));
    }
    if energies_kev.len() != absorption.len() {
        return Err(bad(format!(
            "{} energies but {} absorption efficiencies; give one per energy bin",
            energies_kev.len(),
            absorption.len()
        )));
    }
    if let Some(e) = energies_kev.iter().find(|e| !(e.is_finite() && **e > 0.0)) {
        return Err(bad(format!(
            "energy bin at {e} keV; energies must be finite and > 0"
        )));
    }
    if let Some(a) = absorption
        .iter()
        .find(|a| !(a.is_finite() && (0.0..=1.0).contains(*a)))
    {
        return Err(bad(format!(
            "absorption efficiency {a}; it must be in [0, 1]"
        )));
    }
    let per_channel = |signal: &dyn Fn(f64) -> f64, swank: f64| {
        let mean = energies_kev
            .iter()
            .zip(absorption)
            .map(|(&e, &eta)| eta * signal(e))
            .collect();
        let m2 = energies_kev
            .iter()
            .zip(absorption)
            .map(|(&e, &eta)| eta * signal(e).powi(2) / swank)
            .collect();
        (mean, m2)
    };
    let (mean, second_moment) = match mode {
        Mode::EnergyIntegrating {
            conversion_gain_adu_per_kev: g,
            swank_factor: s,
        } => {
            let (m, m2) = per_channel(&|e| g * e, *s);
            (vec![m], vec![m2])
        }
        Mode::PhotonCounting { thresholds_kev: t } => (0..t.len())
            .map(|c| {
                let lo = t[c];
                let hi = t.get(c + 1).copied().unwrap_or(f64::INFINITY);
                per_channel(&|e| if lo <= e && e < hi { 1.0 } else { 0.0 }, 1.0)
            })
            .unzip(),
    };
    Ok(ChannelWeights {
        mean,
        second_moment,
    })
}

fn bad(msg: String) -> SimError {
    SimError::OutOfRange(msg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thin_layer_absorption_is_mu_t() {
        // 1 − e^(−x) = x − x²/2 + …: for x = 1e-9 the relative error of x is 5e-10.
        let eta = absorption_efficiency(1e-6, 1e-3);
        assert!((eta - 1e-9).abs() < 1e-18, "{eta}");
        assert!((absorption_efficiency(2.0, 0.5) - (1.0 - (-1.0f64).exp())).abs() < 1e-15);
    }

    #[test]
    fn bad_modes_are_refused() {
        for m in [
            Mode::PhotonCounting {
                thresholds_kev: vec![],
            },
            Mode::PhotonCounting {
                thresholds_kev: vec![30.0, 20.0],
            },
            Mode::PhotonCounting {
                thresholds_kev: vec![f64::NAN],
            },
            Mode::energy_integrating(-1.0),
            Mode::EnergyIntegrating {
                conversion_gain_adu_per_kev: 1.0,
                swank_factor: 1.5,
            },
        ] {
            assert!(m.validate().is_err(), "{m:?}");
        }
    }

    #[test]
    fn mismatched_inputs_are_refused() {
        let m = Mode::energy_integrating(1.0);
        assert!(channel_weights(&m, &[50.0], &[]).is_err());
        assert!(channel_weights(&m, &[], &[]).is_err());
        assert!(channel_weights(&m, &[50.0], &[1.2]).is_err());
        assert!(channel_weights(&m, &[-5.0], &[1.0]).is_err());
    }
}
