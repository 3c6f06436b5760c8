//! The speed/accuracy trade of a user's own scene: one view rendered under a ladder of
//! settings — Siddon against trilinear marching at several steps, the spectrum's energy
//! bins, the scatter model's photons, the detector's blur — each timed and compared with
//! the most accurate setting, and the cheapest combination that meets an error budget.
//!
//! Conventions:
//! * The **reference** is the most accurate setting of every knob: exact Siddon, the
//!   spectrum's own 1 keV bins, the scene's scatter model as given (the full Monte Carlo
//!   when the scene asks for the fast estimate), the detector's blur as modelled.
//! * Every rung of the ladder changes **one** knob from the reference. Scatter adds to
//!   the primary image and costs the same whatever the other knobs, so the projector,
//!   energy-bin and blur rungs are measured without scatter, against the reference without
//!   scatter (the `primary` reference); the scatter rungs against the full reference.
//! * Detector noise (quantum and electronic) is switched off in every render, reference
//!   included: noise is not an accuracy setting, and with it every error would be the
//!   noise's. Quantisation and fixed gain maps stay, as they are deterministic.
//! * Errors are in the output quantity (the ideal DRR's quantity, or the detector's
//!   signal): `rms` = RMS(a − r) / RMS(r) and `max` = max|a − r| / max|r|, r the
//!   reference image (all channels). A scatter rung's error includes the reference's own
//!   Monte Carlo noise.
//! * Time is the median wall time of rendering the view (`repeats` renders; one for a
//!   render with scatter), after the per-volume preparation (material classification,
//!   spectral tables), which a data-set job pays once per CT.

use anyhow::{Result, bail};
use std::time::Instant;
use tomograf_physics::acquisition::Acquisition;
use tomograf_physics::scatter::ScatterModel;
use tomograf_scene::Prepared;
use tomograf_sim::View;
use tomograf_sim::error::SimError;
use tomograf_sim::render::{Projection, Projector};

/// The scene's acquisition and its seed, when it has real physics.
fn physics(scene: &Prepared) -> Option<(&Acquisition, u64)> {
    scene.acquisition.as_ref().map(|(a, s)| (a, *s))
}

/// One combination of settings.
#[derive(Debug, Clone, PartialEq)]
pub struct Setting {
    /// The projector.
    pub projector: Projector,
    /// Energy bins of the spectrum; `None`: its own 1 keV bins.
    pub energy_bins: Option<usize>,
    /// The scatter model.
    pub scatter: ScatterModel,
    /// Whether the detector's blur is applied.
    pub blur: bool,
}

/// Which knob a rung turns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Knob {
    /// The reference itself.
    Reference,
    /// Siddon or trilinear at some step.
    Projector,
    /// The spectrum's energy bins.
    EnergyBins,
    /// The scatter model's photons (or model).
    Scatter,
    /// The cells forced detection traces through (the scatter's detection grid).
    ScatterCells,
    /// The detector's blur.
    Blur,
}

/// One measured setting.
#[derive(Debug, Clone)]
pub struct Rung {
    /// Which knob this rung turned (from the reference).
    pub knob: Knob,
    /// A short human label, e.g. `trilinear, step 1 voxel`.
    pub label: String,
    /// The setting.
    pub setting: Setting,
    /// Median seconds to render the view.
    pub seconds: f64,
    /// Seconds of the reference this rung is compared with (the primary reference for a
    /// rung measured without scatter).
    pub reference_seconds: f64,
    /// RMS(a − r) / RMS(r).
    pub rms: f64,
    /// max|a − r| / max|r|.
    pub max: f64,
}

/// What to try.
#[derive(Debug, Clone)]
pub struct Options {
    /// Trilinear steps, voxels.
    pub steps: Vec<f64>,
    /// Energy bin counts (only those below the spectrum's own count are tried).
    pub bins: Vec<usize>,
    /// Fractions of the reference's Monte Carlo scatter photons.
    pub scatter_fractions: Vec<f64>,
    /// Detection cells to try (mm; those coarser than the reference's).
    pub scatter_cells: Vec<f64>,
    /// Histories of the reference's Monte Carlo (`None`: the scene's own for a Monte Carlo
    /// scene, [`ESTIMATE_REFERENCE_PHOTONS`] for one that asks for the estimate).
    pub scatter_reference_photons: Option<u64>,
    /// Renders per timing (median).
    pub repeats: usize,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            steps: vec![0.25, 0.5, 1.0, 2.0],
            bins: vec![64, 32, 16, 8, 4],
            scatter_fractions: vec![0.25, 0.0625],
            scatter_cells: vec![16.0],
            scatter_reference_photons: None,
            repeats: 3,
        }
    }
}

/// Histories of the reference Monte Carlo for a scene that asks for the fast estimate (its
/// noise, about 0.3 % of the image on a chest CT, is well below the estimate's error).
pub const ESTIMATE_REFERENCE_PHOTONS: u64 = 10_000;
/// Detection cells of that reference, mm: docs/scatter.md measures the bias of 8 mm cells
/// at 0.14 % (a real chest CT) and 0.53 % (a validation phantom) of the scatter image.
pub const ESTIMATE_REFERENCE_CELL_MM: f64 = 8.0;

/// The ladder: the reference and every one-knob rung.
#[derive(Debug, Clone)]
pub struct Ladder {
    /// The reference (errors 0).
    pub reference: Rung,
    /// The reference without scatter, when the reference has scatter: what the projector,
    /// energy-bin and blur rungs are compared with.
    pub primary: Option<Rung>,
    /// One knob changed each.
    pub rungs: Vec<Rung>,
    /// The reference's image (all channels), for comparing other settings with it.
    pub reference_image: Vec<f32>,
}

/// The scene's scatter model as the reference uses it: as given (with `photons` when
/// given), or for a scene that asks for the fast estimate the Monte Carlo with
/// [`ESTIMATE_REFERENCE_PHOTONS`] (or `photons`) through cells of
/// [`ESTIMATE_REFERENCE_CELL_MM`].
fn reference_scatter(scene: &ScatterModel, photons: Option<u64>) -> ScatterModel {
    match scene {
        ScatterModel::None => ScatterModel::None,
        ScatterModel::Estimate { .. } => ScatterModel::monte_carlo_default()
            .with_photons(photons.unwrap_or(ESTIMATE_REFERENCE_PHOTONS))
            .with_detection_cell_mm(ESTIMATE_REFERENCE_CELL_MM),
        ScatterModel::MonteCarlo { .. } => {
            let own = scene.photons().unwrap_or(1);
            scene.clone().with_photons(photons.unwrap_or(own))
        }
    }
}

/// Renders `view` (index `index`) under `setting`: the images of every channel,
/// concatenated, and the median render time over `repeats`.
pub fn render(
    scene: &Prepared,
    view: &View,
    setting: &Setting,
    repeats: usize,
) -> Result<(Vec<f32>, f64)> {
    let acquisition = physics(scene).map(|(acquisition, seed)| {
        let mut acq = acquisition.clone();
        acq.spectrum.bins = setting.energy_bins;
        acq.scatter = setting.scatter.clone();
        if !setting.blur {
            acq.detector.blur = Default::default();
        }
        acq.detector.quantum_noise = false;
        acq.detector.readout.electronic_noise_adu = 0.0;
        (acq, seed)
    });
    let renderer = scene.renderer_with(setting.projector, acquisition.as_ref())?;
    // A render with scatter is timed once: its Monte Carlo is the slow part.
    let repeats = if setting.scatter == ScatterModel::None {
        repeats
    } else {
        1
    };
    let mut times = Vec::new();
    let mut image = Vec::new();
    for _ in 0..repeats.max(1) {
        let t = Instant::now();
        let frame = renderer.render(0, view)?;
        times.push(t.elapsed().as_secs_f64());
        image = frame
            .images
            .into_iter()
            .flat_map(|p: Projection| p.data)
            .collect();
    }
    times.sort_by(f64::total_cmp);
    Ok((image, times[times.len() / 2]))
}

/// `(rms, max)` of `a` against the reference `r` (see the module's conventions).
pub fn errors(a: &[f32], r: &[f32]) -> Result<(f64, f64)> {
    if a.len() != r.len() || r.is_empty() {
        bail!(SimError::OutOfRange(format!(
            "images of {} and {} values cannot be compared",
            a.len(),
            r.len()
        )));
    }
    let (mut d2, mut r2, mut dmax, mut rmax) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (&x, &y) in a.iter().zip(r) {
        let (x, y) = (f64::from(x), f64::from(y));
        if !(x.is_finite() && y.is_finite()) {
            bail!(SimError::OutOfRange(
                "a rendered image holds a non-finite value".into(),
            ));
        }
        d2 += (x - y) * (x - y);
        r2 += y * y;
        dmax = dmax.max((x - y).abs());
        rmax = rmax.max(y.abs());
    }
    if r2 == 0.0 {
        bail!(SimError::OutOfRange(
            "the reference image is all zeros (does the view see the volume?)".into(),
        ));
    }
    Ok(((d2 / r2).sqrt(), dmax / rmax))
}

fn projector_label(p: Projector) -> String {
    match p {
        Projector::Siddon => "Siddon (exact)".into(),
        Projector::Trilinear { step_voxels } => format!("trilinear, step {step_voxels} voxel"),
    }
}

/// The reference setting for `chain` (`scatter_photons`: the reference Monte Carlo's
/// histories, see [`Options::scatter_reference_photons`]).
pub fn reference(scene: &Prepared, scatter_photons: Option<u64>) -> Setting {
    Setting {
        projector: Projector::Siddon,
        energy_bins: None,
        scatter: match physics(scene) {
            None => ScatterModel::None,
            Some((acquisition, _)) => reference_scatter(&acquisition.scatter, scatter_photons),
        },
        blur: true,
    }
}

/// Measures the reference and every one-knob rung of `options` for `view`.
/// `progress(done, total)` is called after each render.
pub fn ladder(
    scene: &Prepared,
    view: &View,
    options: &Options,
    mut progress: impl FnMut(usize, usize),
) -> Result<Ladder> {
    if options.scatter_reference_photons == Some(0) {
        bail!(SimError::OutOfRange(
            "scatter reference photons = 0: give the reference Monte Carlo's histories (≥ 1)"
                .into(),
        ));
    }
    let base = reference(scene, options.scatter_reference_photons);
    // Rungs of the primary-chain knobs go without scatter.
    let primary = Setting {
        scatter: ScatterModel::None,
        ..base.clone()
    };
    let mut plan: Vec<(Knob, String, Setting)> = Vec::new();
    for &s in &options.steps {
        if !(s.is_finite() && s > 0.0) {
            bail!(SimError::OutOfRange(format!(
                "trilinear step {s} voxels: it must be finite and > 0"
            )));
        }
        let projector = Projector::Trilinear { step_voxels: s };
        plan.push((
            Knob::Projector,
            projector_label(projector),
            Setting {
                projector,
                ..primary.clone()
            },
        ));
    }
    if let Some((acquisition, _)) = physics(scene) {
        let mut own_bins = acquisition.spectrum.clone();
        own_bins.bins = None;
        let native = own_bins.spectrum()?.energies_kev().len();
        for &b in options.bins.iter().filter(|&&b| b >= 1 && b < native) {
            plan.push((
                Knob::EnergyBins,
                format!("{b} energy bins (of {native})"),
                Setting {
                    energy_bins: Some(b),
                    ..primary.clone()
                },
            ));
        }
        let blur = &acquisition.detector.blur;
        if blur.sigma_mm > 0.0 || blur.tail_fraction > 0.0 {
            plan.push((
                Knob::Blur,
                "detector blur off".into(),
                Setting {
                    blur: false,
                    ..primary.clone()
                },
            ));
        }
        let scene = &acquisition.scatter;
        if let Some(n) = base.scatter.photons() {
            let own_cell = base.scatter.detection_cell_mm();
            for &f in &options.scatter_fractions {
                if !(f > 0.0 && f < 1.0) {
                    bail!(SimError::OutOfRange(format!(
                        "scatter photon fraction {f}: give fractions in (0, 1)"
                    )));
                }
                let k = ((n as f64 * f).round() as u64).max(1);
                plan.push((
                    Knob::Scatter,
                    format!("scatter Monte Carlo, {k} photons"),
                    Setting {
                        scatter: base.scatter.clone().with_photons(k),
                        ..base.clone()
                    },
                ));
            }
            for &c in &options.scatter_cells {
                if !(c.is_finite() && c > 0.0) {
                    bail!(SimError::OutOfRange(format!(
                        "scatter detection cell {c} mm: give cell sizes > 0"
                    )));
                }
                if own_cell > 0.0 && c <= own_cell {
                    continue;
                }
                plan.push((
                    Knob::ScatterCells,
                    format!("scatter forced detection through {c} mm cells"),
                    Setting {
                        scatter: base.scatter.clone().with_detection_cell_mm(c),
                        ..base.clone()
                    },
                ));
            }
            let estimate = match scene {
                ScatterModel::Estimate { .. } => scene.clone(),
                _ => ScatterModel::estimate_default(),
            };
            plan.push((
                Knob::Scatter,
                format!(
                    "scatter estimate, {} photons{}",
                    estimate.photons().unwrap_or(0),
                    cells_label(estimate.detection_cell_mm())
                ),
                Setting {
                    scatter: estimate,
                    ..base.clone()
                },
            ));
        }
    }
    let has_scatter = base.scatter != ScatterModel::None;
    let total = plan.len() + 1 + usize::from(has_scatter);
    let mut done = 0;
    let mut measure = |knob: Knob, label: String, setting: Setting| -> Result<(Rung, Vec<f32>)> {
        let (img, s) = render(scene, view, &setting, options.repeats)?;
        done += 1;
        progress(done, total);
        let rung = Rung {
            knob,
            label,
            setting,
            seconds: s,
            reference_seconds: s,
            rms: 0.0,
            max: 0.0,
        };
        Ok((rung, img))
    };
    let full = measure(Knob::Reference, reference_label(&base), base.clone())?;
    let primary = if has_scatter {
        Some(measure(
            Knob::Reference,
            "reference without scatter".into(),
            primary,
        )?)
    } else {
        None
    };
    let mut rungs = Vec::with_capacity(plan.len());
    for (knob, label, setting) in plan {
        let against = match (&primary, knob) {
            (Some(p), Knob::Projector | Knob::EnergyBins | Knob::Blur) => p,
            _ => &full,
        };
        let (mut rung, img) = measure(knob, label, setting)?;
        (rung.rms, rung.max) = errors(&img, &against.1)?;
        rung.reference_seconds = against.0.seconds;
        rungs.push(rung);
    }
    Ok(Ladder {
        reference: full.0,
        primary: primary.map(|p| p.0),
        rungs,
        reference_image: full.1,
    })
}

fn reference_label(s: &Setting) -> String {
    let mut l = format!("reference: {}", projector_label(s.projector));
    if let Some(n) = s.scatter.photons() {
        l.push_str(&format!(
            ", scatter Monte Carlo, {n} photons{}",
            cells_label(s.scatter.detection_cell_mm())
        ));
    }
    l
}

/// `, 8 mm cells` (nothing at full resolution).
fn cells_label(mm: f64) -> String {
    if mm > 0.0 {
        format!(", {mm} mm cells")
    } else {
        String::new()
    }
}

/// A rung must take less than this fraction of its reference's time to be worth its error:
/// smaller differences are within the timing noise of a few renders on a shared machine.
pub const SPEED_MARGIN: f64 = 0.9;

/// The cheapest combination that should meet `budget` (on `rms`): for each knob, the
/// fastest rung whose own error is within budget/√k (k knobs turned; independent errors
/// add in quadrature) and that is at least 10 % faster than its reference
/// ([`SPEED_MARGIN`]); the reference's setting for a knob with no such rung.
pub fn combine(ladder: &Ladder, budget: f64) -> Setting {
    let knobs = [
        Knob::Projector,
        Knob::EnergyBins,
        Knob::Scatter,
        Knob::ScatterCells,
        Knob::Blur,
    ];
    let present: Vec<Knob> = knobs
        .into_iter()
        .filter(|k| ladder.rungs.iter().any(|r| r.knob == *k))
        .collect();
    let share = budget / (present.len().max(1) as f64).sqrt();
    let mut s = ladder.reference.setting.clone();
    for k in present {
        let best = ladder
            .rungs
            .iter()
            .filter(|r| {
                r.knob == k && r.rms <= share && r.seconds < SPEED_MARGIN * r.reference_seconds
            })
            .min_by(|a, b| a.seconds.total_cmp(&b.seconds));
        if let Some(r) = best {
            match k {
                Knob::Projector => s.projector = r.setting.projector,
                Knob::EnergyBins => s.energy_bins = r.setting.energy_bins,
                Knob::Scatter => {
                    // Keep a coarser detection grid chosen by its own knob.
                    let cell = s.scatter.detection_cell_mm();
                    s.scatter = r.setting.scatter.clone();
                    if matches!(s.scatter, ScatterModel::MonteCarlo { .. }) {
                        s.scatter = s.scatter.clone().with_detection_cell_mm(cell);
                    }
                }
                Knob::ScatterCells => {
                    let cell = r.setting.scatter.detection_cell_mm();
                    if matches!(s.scatter, ScatterModel::MonteCarlo { .. }) {
                        s.scatter = s.scatter.clone().with_detection_cell_mm(cell);
                    }
                }
                Knob::Blur => s.blur = r.setting.blur,
                Knob::Reference => {}
            }
        }
    }
    s
}

/// A human label for a combined setting (`physics`: name the energy bins too).
pub fn describe(s: &Setting, physics: bool) -> String {
    let mut parts = vec![projector_label(s.projector)];
    if physics {
        parts.push(match s.energy_bins {
            Some(b) => format!("{b} energy bins"),
            None => "1 keV bins".into(),
        });
    }
    match &s.scatter {
        ScatterModel::None => {}
        ScatterModel::Estimate {
            photons,
            detection_cell_mm,
            ..
        } => parts.push(format!(
            "scatter estimate {photons} photons{}",
            cells_label(*detection_cell_mm)
        )),
        ScatterModel::MonteCarlo {
            photons,
            detection_cell_mm,
            ..
        } => parts.push(format!(
            "scatter Monte Carlo {photons} photons{}",
            cells_label(*detection_cell_mm)
        )),
    }
    if !s.blur {
        parts.push("no blur".into());
    }
    parts.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rung(knob: Knob, setting: Setting, seconds: f64, rms: f64) -> Rung {
        Rung {
            knob,
            label: String::new(),
            setting,
            seconds,
            reference_seconds: 1.0,
            rms,
            max: rms,
        }
    }

    #[test]
    fn combine_takes_the_fastest_rung_within_each_knobs_share() {
        let base = Setting {
            projector: Projector::Siddon,
            energy_bins: None,
            scatter: ScatterModel::None,
            blur: true,
        };
        let tri = |s| Setting {
            projector: Projector::Trilinear { step_voxels: s },
            ..base.clone()
        };
        let bins = |b| Setting {
            energy_bins: Some(b),
            ..base.clone()
        };
        let ladder = Ladder {
            reference: rung(Knob::Reference, base.clone(), 1.0, 0.0),
            primary: None,
            reference_image: Vec::new(),
            rungs: vec![
                rung(Knob::Projector, tri(0.5), 0.9, 0.001),
                rung(Knob::Projector, tri(1.0), 0.5, 0.005),
                rung(Knob::Projector, tri(2.0), 0.3, 0.02),
                rung(Knob::EnergyBins, bins(16), 0.6, 0.002),
                rung(Knob::EnergyBins, bins(4), 0.4, 0.05),
            ],
        };
        // Two knobs: each may use 0.01/√2 ≈ 0.0071.
        let s = combine(&ladder, 0.01);
        assert_eq!(s.projector, Projector::Trilinear { step_voxels: 1.0 });
        assert_eq!(s.energy_bins, Some(16));
        // A budget no rung meets keeps the reference.
        assert_eq!(combine(&ladder, 1e-6), base);
    }

    #[test]
    fn errors_are_relative_to_the_reference() {
        let r = [1.0f32, 2.0, 2.0];
        let (rms, max) = errors(&[1.0, 2.0, 2.3], &r).unwrap();
        assert!((rms - 0.1).abs() < 1e-6, "{rms}");
        assert!((max - 0.15).abs() < 1e-6, "{max}");
        assert!(errors(&[1.0], &[0.0]).is_err());
        assert!(errors(&[1.0, 2.0], &[1.0]).is_err());
        assert!(errors(&[f32::NAN], &[1.0]).is_err());
    }
}
