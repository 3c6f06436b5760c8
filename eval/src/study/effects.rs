//! What each of a study's data sets does to the projections, before any network sees them:
//! the first table of a study's report. A realism level or a shift that barely moves the
//! line integrals cannot show what it stands for, whatever the networks then do.
//!
//! Measured on the AP and lateral views of the first [`ITEMS`] test items of each set, at
//! the study's own detector size and geometry, rendered exactly as the data stage renders
//! them ([`ItemScene`]), against the ideal DRR of the same CT (line integrals of μ at the
//! items' effective energy, 60 keV):
//! * **change against the ideal DRR** and **against the reference set** (realism gap: the
//!   level before; domain shift: `lidc`, for the sets made of the same patients, with or
//!   without a table or a pacemaker added, where the panel sees the same): RMS over the
//!   pixels of the difference of the line integrals, as % of the ideal DRR's RMS;
//! * **noise**: RMS over the pixels of (a − b)/√2 for two noise realisations a and b of the
//!   same view (the per-pixel noise SD, on average), same unit, AP and lateral;
//! * **scatter-to-primary ratio**: mean over the panel of the expected scatter over the
//!   expected primary signal, AP and lateral;
//! * **quanta**: the noise-equivalent quanta per pixel of the expected signal (mean² over
//!   its second moment: photons, weighted by what the detector counts) in the lateral view,
//!   its 1st percentile over the pixels, and the pixels whose −log was floored for lack of
//!   signal (photon starvation), in % of the AP and lateral pixels;
//! * **blur**: the MTF50 of the detector's light spread and pixel aperture
//!   (cycles/mm at the panel; [`tomograf_physics::detector::Blur`]) beside the panel's Nyquist
//!   frequency, 1/(2·pitch) (the items' mean pitch).
//!
//! A set whose line integrals move by less than [`NEGLIGIBLE_PCT`] % from its reference's is
//! flagged: at the studies' reconstruction errors (PSNR 17–28 dB on the [0, 1] HU window,
//! i.e. 4–14 % RMS) a change that small cannot show as a difference between models.

use super::Study;
use super::levels::DataSpec;
use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use tomograf_physics::acquisition::add_into;
use tomograf_physics::detector::Blur;
use tomograf_physics::scatter::ScatterModel;
use tomograf_scene::dataset::{DatasetJob, ItemScene};
use tomograf_scene::physics::item_seed;
use tomograf_sim::Geometry;

/// Test items measured per set.
pub const ITEMS: usize = 2;

/// Change below which a set is flagged (% of the ideal DRR's RMS line integral).
pub const NEGLIGIBLE_PCT: f64 = 1.0;

/// Another noise stream for the second realisation (any fixed odd constant).
const SECOND_REALISATION: u64 = 0x9E37_79B9_7F4A_7C15;

/// What one set does to the projections (module docs for each figure).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Effect {
    /// The set.
    pub set: String,
    /// The set it is compared with, when there is one with the same population.
    pub reference: Option<String>,
    /// RMS change against the ideal DRR, % of its RMS.
    pub vs_ideal_pct: f64,
    /// RMS change against the reference set, % of the ideal DRR's RMS.
    pub vs_reference_pct: Option<f64>,
    /// Noise SD in the AP and the lateral view, % of the ideal DRR's RMS (0: noise-free).
    pub noise_pct: [f64; 2],
    /// Mean scatter-to-primary ratio in the AP and the lateral view (`None`: no scatter).
    pub spr: Option<[f64; 2]>,
    /// 1st percentile of the lateral view's noise-equivalent quanta per pixel (`None`: no
    /// quantum noise).
    pub quanta_p1_lateral: Option<f64>,
    /// Pixels floored for lack of signal, % of the AP and lateral pixels.
    pub starved_pct: f64,
    /// MTF50 of the light spread and aperture, cycles/mm (`None`: no blur).
    pub mtf50_per_mm: Option<f64>,
    /// The panel's Nyquist frequency, cycles/mm.
    pub nyquist_per_mm: f64,
    /// Items measured.
    pub items: usize,
}

impl Effect {
    /// Whether the set moves the line integrals by less than [`NEGLIGIBLE_PCT`] from its
    /// reference (`false` without one: nothing to compare with).
    pub fn negligible(&self) -> bool {
        self.vs_reference_pct.is_some_and(|x| x < NEGLIGIBLE_PCT)
    }
}

/// One realisation of a set's AP and lateral views, and what they were made of.
struct Views {
    /// Line integrals (or the set's output), AP then lateral.
    images: [Vec<f32>; 2],
    spr: Option<[f64; 2]>,
    /// Noise-equivalent quanta per pixel of the lateral view.
    quanta_lateral: Option<Vec<f64>>,
    starved: usize,
}

/// The reference of each test set: realism gap, the level before; domain shift, the first
/// set (`lidc`) when the population is the same.
fn reference(study: &Study, k: usize) -> Option<&DataSpec> {
    let sets: Vec<&DataSpec> = study.test.iter().filter(|s| s.data_of.is_none()).collect();
    let me = sets[k];
    // The same patients (a table or a pacemaker is added to them; another profile is
    // other patients).
    let same = |r: &DataSpec| r.profile == me.profile && r.cts == me.cts;
    match study.settings.kind {
        super::Kind::RealismGap => k.checked_sub(1).map(|j| sets[j]),
        super::Kind::DomainShift => sets.first().copied().filter(|r| k > 0 && same(r)),
    }
}

/// Item `index` of a set's data-set job: its AP and lateral views, realisations `a` (the item's own
/// noise stream) and `b` (another; the same as `a` without noise), the ideal DRR, and the
/// geometry (the panel's pitch, mm, and where it looks).
fn item_views(job: &DatasetJob, index: usize) -> Result<([Views; 2], [Vec<f32>; 2], Geometry)> {
    let settings = &job.settings;
    let scene = ItemScene::new(settings, index, &job.sources[index])?;
    let n = scene.views.len();
    let apl = n - 2..n;
    let geometry = scene.geometry;
    let [ap, lateral]: [Vec<f32>; 2] = scene
        .ideal_drr(settings.energy_kev, apl.clone())?
        .try_into()
        .map_err(|_| anyhow::anyhow!("two views expected"))?;
    let ideal = [ap, lateral];
    let Some((acq, seed)) = &settings.acquisition else {
        let v = || Views {
            images: ideal.clone(),
            spr: None,
            quanta_lateral: None,
            starved: 0,
        };
        return Ok(([v(), v()], ideal.clone(), geometry));
    };
    let realisation = |stream: u64| -> Result<Views> {
        let prepared = scene.prepare(
            scene.hu.clone(),
            settings.energy_kev,
            Some((acq.clone(), item_seed(seed ^ stream, index))),
        )?;
        let renderer = prepared.renderer()?;
        let mut images: [Vec<f32>; 2] = Default::default();
        let mut spr = [0.0; 2];
        let mut quanta = None;
        let mut starved = 0;
        for (i, k) in apl.clone().enumerate() {
            // The view's index in the item, so that stream 0 gives the item's own bytes.
            let frame = renderer.render(k, &prepared.job.views[k])?;
            let got = frame.parts.context("real physics renders its parts")?;
            starved += got.clipped;
            let mut object = got.primary.clone();
            if let Some(s) = &got.scatter {
                let s = s.total();
                let ratios: Vec<f64> = s
                    .mean
                    .iter()
                    .zip(&got.primary.mean)
                    .filter(|(_, p)| **p > 0.0)
                    .map(|(s, p)| s / p)
                    .collect();
                spr[i] = ratios.iter().sum::<f64>() / ratios.len().max(1) as f64;
                add_into(&mut object, &s);
            }
            if i == 1 && acq.detector.quantum_noise {
                quanta = Some(
                    object
                        .mean
                        .iter()
                        .zip(&object.second_moment)
                        .map(|(m, m2)| if *m2 > 0.0 { m * m / m2 } else { 0.0 })
                        .collect(),
                );
            }
            images[i] = frame.images.into_iter().next().context("no image")?.data;
        }
        Ok(Views {
            images,
            spr: (acq.scatter != ScatterModel::None).then_some(spr),
            quanta_lateral: quanta,
            starved,
        })
    };
    Ok((
        [realisation(0)?, realisation(SECOND_REALISATION)?],
        ideal,
        geometry,
    ))
}

fn rms(a: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for x in a {
        s += x * x;
        n += 1;
    }
    (s / n.max(1) as f64).sqrt()
}

fn rms_diff(a: &[Vec<f32>], b: &[Vec<f32>]) -> f64 {
    rms(a
        .iter()
        .zip(b)
        .flat_map(|(x, y)| x.iter().zip(y).map(|(p, q)| f64::from(*p) - f64::from(*q))))
}

/// The frequency (cycles/mm) at which the blur's MTF times the aperture's sinc falls to ½
/// (bisection; the product falls monotonically to its first zero at 1/pitch).
pub fn mtf50(blur: &Blur, pitch_mm: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    let mtf = |f: f64| {
        let core = (-0.5 * (tau * blur.sigma_mm * f).powi(2)).exp();
        let tail = 1.0 / (1.0 + (tau * blur.tail_length_mm * f).powi(2));
        let x = std::f64::consts::PI * pitch_mm * f;
        let sinc = if x == 0.0 { 1.0 } else { x.sin() / x };
        ((1.0 - blur.tail_fraction) * core + blur.tail_fraction * tail) * sinc
    };
    let (mut lo, mut hi) = (0.0, 1.0 / pitch_mm);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if mtf(mid) > 0.5 { lo = mid } else { hi = mid }
    }
    0.5 * (lo + hi)
}

/// Measures every test set of `study` that has data of its own.
pub fn measure(study: &Study) -> Result<Vec<Effect>> {
    let sets: Vec<&DataSpec> = study.test.iter().filter(|s| s.data_of.is_none()).collect();
    let mut out = Vec::new();
    // The first realisations and the items' geometries, per set, for the references.
    let mut firsts: Vec<(Vec<Vec<f32>>, Vec<Geometry>)> = Vec::new();
    for (k, spec) in sets.iter().enumerate() {
        let items = ITEMS.min(study.test_items(spec.name));
        let (mut a, mut b, mut ideal) = (Vec::new(), Vec::new(), Vec::new());
        let (mut spr, mut quanta, mut starved) = (None, Vec::new(), 0);
        let (mut sprs, mut geometries) = (Vec::new(), Vec::new());
        let job = study.dataset_job("test", spec, (0, 1))?;
        for index in 0..items {
            let ([first, second], drr, geometry) = item_views(&job, index)
                .with_context(|| format!("set '{}', item {index}", spec.name))?;
            geometries.push(geometry);
            ideal.extend(drr);
            sprs.extend(first.spr);
            quanta.extend(first.quanta_lateral.unwrap_or_default());
            starved += first.starved;
            a.extend(first.images);
            b.extend(second.images);
        }
        if !sprs.is_empty() {
            let m =
                |i: usize| sprs.iter().map(|s: &[f64; 2]| s[i]).sum::<f64>() / sprs.len() as f64;
            spr = Some([m(0), m(1)]);
        }
        let scale =
            rms(ideal.iter().flat_map(|v| v.iter().map(|x| f64::from(*x)))).max(f64::MIN_POSITIVE);
        let pct = |x: f64| 100.0 * x / scale;
        let noise = |view: usize| {
            let pick = |s: &[Vec<f32>]| -> Vec<Vec<f32>> {
                s.iter().skip(view).step_by(2).cloned().collect()
            };
            pct(rms_diff(&pick(&a), &pick(&b)) / std::f64::consts::SQRT_2)
        };
        // Pixel by pixel only where the panels see the same: a table, say, widens the crop
        // and with it the fitted pitch.
        let r = reference(study, k).filter(|r| {
            sets.iter()
                .position(|s| s.name == r.name)
                .is_some_and(|j| firsts[j].1 == geometries)
        });
        let vs_reference_pct = r.and_then(|r| {
            let j = sets.iter().position(|s| s.name == r.name)?;
            Some(pct(rms_diff(&a, &firsts[j].0)))
        });
        let pitch = geometries
            .iter()
            .map(|g| g.detector.pitch_u_mm)
            .sum::<f64>()
            / geometries.len().max(1) as f64;
        let (acq_blur, has_noise) = match &job.settings.acquisition {
            Some((acq, _)) => (
                (!acq.detector.blur.is_identity()).then_some(acq.detector.blur),
                acq.detector.quantum_noise,
            ),
            None => (None, false),
        };
        quanta.sort_by(f64::total_cmp);
        out.push(Effect {
            set: spec.name.to_string(),
            reference: r.map(|r| r.name.to_string()),
            vs_ideal_pct: pct(rms_diff(&a, &ideal)),
            vs_reference_pct,
            noise_pct: [noise(0), noise(1)],
            spr,
            quanta_p1_lateral: (has_noise && !quanta.is_empty())
                .then(|| quanta[quanta.len() / 100]),
            starved_pct: 100.0 * starved as f64
                / a.iter().map(Vec::len).sum::<usize>().max(1) as f64,
            mtf50_per_mm: acq_blur.map(|b| mtf50(&b, pitch)),
            nyquist_per_mm: 0.5 / pitch,
            items,
        });
        firsts.push((a, geometries));
    }
    Ok(out)
}

/// The study's effects: read from `effects.json` in the study folder, or measured and
/// written there.
pub fn load_or_measure(study: &Study) -> Result<Vec<Effect>> {
    let path = study.dir.join("effects.json");
    if let Ok(bytes) = std::fs::read(&path)
        && let Ok(e) = serde_json::from_slice::<Vec<Effect>>(&bytes)
        && e.len() == study.test.iter().filter(|s| s.data_of.is_none()).count()
    {
        return Ok(e);
    }
    let e = measure(study)?;
    tomograf_datasets::atomic::write_json(&path, &serde_json::to_value(&e)?)?;
    Ok(e)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Analytic MTF50s: the aperture alone, sinc(p·f) = ½ at p·f = 0.60335 (x = 1.89549 rad,
    /// the root of sin x = x/2); a Gaussian core alone (pitch → 0),
    /// exp(−2π²σ²f²) = ½ at f = √(2 ln 2)/(2πσ) = 0.187390/σ.
    #[test]
    fn mtf50_matches_the_closed_forms() {
        let aperture = mtf50(&Blur::none(), 2.0);
        assert!((aperture - 0.603_355 / 2.0).abs() < 1e-5, "{aperture}");
        let sigma = 0.25;
        let core = mtf50(&Blur::gaussian(sigma), 1e-6);
        assert!((core - 0.187_390 / sigma).abs() < 1e-5, "{core}");
        // Both: lower than either alone.
        let both = mtf50(&Blur::gaussian(sigma), 2.0);
        assert!(both < aperture && both < core, "{both}");
    }
}
