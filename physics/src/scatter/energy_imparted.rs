//! Energy imparted to the medium by a photon beam: a Monte Carlo tally of the energy
//! deposited per voxel and in named analytic regions, in eV per source photon, and the
//! absorbed dose it gives (Gy).
//!
//! Physics: the transport of [`super::transport`] (Woodcock tracking; photoelectric,
//! Compton with Klein–Nishina × S, Rayleigh with Thomson × F²). **No electron transport**:
//! the photoelectron's energy (the whole photon energy: fluorescence is not followed) and
//! the Compton electron's energy E − E′ are deposited at the interaction point, as
//! TG-195's codes were run for its energy-imparted cases (kerma ≈ dose below 150 keV,
//! where secondary electron ranges are below a millimetre in tissue). A photon scattered
//! below [`E_CUTOFF_KEV`] deposits what it has left where it is.
//!
//! Variance reduction: implicit capture (each collision deposits the photoelectric share
//! of the weight and the photon goes on with the rest) and Russian roulette below 5 % of
//! the starting weight — both unbiased. Energy is conserved per history except for the
//! roulette, so deposited + escaped + stopped = source energy to Monte Carlo error
//! ([`EnergyImparted::balance`]).
//!
//! Determinism: histories in batches of [`super::engine::BATCH`], batch `b` on its own
//! ChaCha8 stream seeded by SplitMix64(seed, b); batch tallies are added in batch order, so
//! the bytes do not depend on the thread count.
//!
//! Units: positions mm, energies keV inside the transport, tallies eV per source photon,
//! dose Gy.

use super::MAX_PHOTONS;
use super::engine::BATCH;
use super::field::FieldSource;
use super::region::{PlacedRegion, Region};
use super::transport::{E_CUTOFF_KEV, Medium};
use glam::{DMat3, DVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use tomograf_sim::composition::unpack;
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::seed::frame_seed;
use tomograf_sim::solid::{PlacedSolid, Solid};

/// Electronvolts per keV.
const EV_PER_KEV: f64 = 1000.0;
/// Joules per electronvolt (CODATA 2018, exact).
pub const JOULE_PER_EV: f64 = 1.602_176_634e-19;
/// Russian roulette threshold, as a fraction of the starting weight.
const ROULETTE: f64 = 0.05;
/// Batches simulated in parallel before their tallies are added (bounds memory).
const ROUND: u64 = 256;

/// A beam's energies: monoenergetic or a spectrum (relative photon numbers per bin).
#[derive(Debug, Clone, PartialEq)]
pub struct BeamSpectrum {
    energies_kev: Vec<f64>,
    cdf: Vec<f64>,
    mean_kev: f64,
}

impl BeamSpectrum {
    /// Photons of `energies_kev` in proportion to `photons` (any scale). Errors on empty or
    /// mismatched lists, energies outside 1–500 keV, or weights that are negative, not
    /// finite, or all zero.
    pub fn new(energies_kev: Vec<f64>, photons: &[f64]) -> Result<Self> {
        let bad = |m: String| Err(SimError::OutOfRange(format!("beam spectrum: {m}")));
        if energies_kev.is_empty() || energies_kev.len() != photons.len() {
            return bad(format!(
                "{} energies and {} weights; give the same number, at least one",
                energies_kev.len(),
                photons.len()
            ));
        }
        if let Some(e) = energies_kev
            .iter()
            .find(|e| !(e.is_finite() && (E_CUTOFF_KEV..=500.0).contains(*e)))
        {
            return bad(format!("energy {e} keV is outside 1–500 keV"));
        }
        if let Some(w) = photons.iter().find(|w| !(w.is_finite() && **w >= 0.0)) {
            return bad(format!("weight {w}; weights must be finite and ≥ 0"));
        }
        let total: f64 = photons.iter().sum();
        if total <= 0.0 {
            return bad("every weight is zero".into());
        }
        let mut acc = 0.0;
        let cdf = photons
            .iter()
            .map(|w| {
                acc += w / total;
                acc
            })
            .collect();
        let mean_kev = energies_kev
            .iter()
            .zip(photons)
            .map(|(e, w)| e * w)
            .sum::<f64>()
            / total;
        Ok(Self {
            energies_kev,
            cdf,
            mean_kev,
        })
    }

    /// A monoenergetic beam.
    pub fn monoenergetic(e_kev: f64) -> Result<Self> {
        Self::new(vec![e_kev], &[1.0])
    }

    /// Mean photon energy, keV.
    pub fn mean_kev(&self) -> f64 {
        self.mean_kev
    }

    /// Highest energy, keV.
    pub fn max_kev(&self) -> f64 {
        self.energies_kev.iter().copied().fold(0.0, f64::max)
    }

    fn sample<R: Rng>(&self, rng: &mut R) -> f64 {
        let u = rng.random::<f64>();
        let k = self
            .cdf
            .partition_point(|&c| c <= u)
            .min(self.cdf.len() - 1);
        self.energies_kev[k]
    }
}

/// A fluence scorer: photons crossing a disc (either way) are tallied with the
/// plane-crossing estimator Φ = Σ w / (A·|cos θ|), weighted by a response of energy,
/// e.g. E·(μen/ρ)_air for air kerma (keV/g per source photon with μen/ρ in cm²/g and
/// A in cm²). The scorer is not matter: it does not change the transport.
#[derive(Clone)]
pub struct FluenceDisc {
    /// Name used in tables.
    pub name: String,
    /// Centre, mm.
    pub centre: DVec3,
    /// Unit normal.
    pub normal: DVec3,
    /// Radius, mm.
    pub radius: f64,
    /// Response per photon crossing per cm² as a function of energy (keV).
    pub response: std::sync::Arc<dyn Fn(f64) -> f64 + Send + Sync>,
}

impl std::fmt::Debug for FluenceDisc {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FluenceDisc")
            .field("name", &self.name)
            .field("centre", &self.centre)
            .field("normal", &self.normal)
            .field("radius", &self.radius)
            .finish_non_exhaustive()
    }
}

impl FluenceDisc {
    /// The score of a flight from `p` along unit `d` to parameter `t_end` (mm; ∞: no
    /// further collision) at energy `e` keV with weight `w`.
    #[inline]
    fn score(&self, p: DVec3, d: DVec3, t_end: f64, e: f64, w: f64) -> f64 {
        let cos = d.dot(self.normal);
        if cos == 0.0 {
            return 0.0;
        }
        let t = (self.centre - p).dot(self.normal) / cos;
        if !(t > 0.0 && t < t_end) {
            return 0.0;
        }
        if (p + d * t - self.centre).length_squared() > self.radius * self.radius {
            return 0.0;
        }
        let area_cm2 = std::f64::consts::PI * self.radius * self.radius / 100.0;
        w * (self.response)(e) / (area_cm2 * cos.abs())
    }
}

/// How the scoring regions are tallied (the voxel map and the totals are always scored
/// at the interaction point).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RegionEstimator {
    /// Analog: each collision inside a region scores what it deposits there.
    #[default]
    Collision,
    /// Track length (the kerma approximation of MC-GPU and the EGSnrc user codes): every
    /// flight that crosses a region scores its expected deposition along the chord,
    /// w·E·Σ (μ_dep/ρ)·ρℓ ([`Medium::deposited_along`]). Unbiased for the same physics,
    /// with far less variance in small or thin regions, where few photons interact.
    TrackLength,
}

/// How a run is made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TallySettings {
    /// Source photons (histories), 1 to [`MAX_PHOTONS`].
    pub photons: u64,
    /// Most interactions followed per history; the rest of the photon's energy is counted
    /// as stopped (1: first-collision deposition only).
    pub max_collisions: u32,
    /// Whether to keep the per-voxel map (regions are always tallied).
    pub voxel_map: bool,
    /// How the regions are scored.
    pub regions: RegionEstimator,
}

impl Default for TallySettings {
    fn default() -> Self {
        Self {
            photons: 1_000_000,
            max_collisions: 1000,
            voxel_map: true,
            regions: RegionEstimator::Collision,
        }
    }
}

/// A tallied quantity: mean per source photon and its Monte Carlo standard error (from
/// the spread of the batch tallies), eV.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Estimate {
    /// eV per source photon.
    pub ev_per_photon: f64,
    /// Standard error of the mean, eV per source photon.
    pub standard_error: f64,
}

/// The result of a run.
#[derive(Debug, Clone)]
pub struct EnergyImparted {
    /// Source photons simulated.
    pub photons: u64,
    /// Mean source photon energy, eV.
    pub source_ev: f64,
    /// Energy deposited per voxel of the composition grid, eV per source photon (empty
    /// without a voxel map); same layout as the grid (i fastest).
    pub voxel_ev: Vec<f64>,
    /// Per region, in the order given.
    pub regions: Vec<(String, Estimate)>,
    /// Per fluence disc, in the order given: response-weighted fluence per source photon
    /// (the `ev_per_photon` field holds the response's unit, not eV).
    pub discs: Vec<(String, Estimate)>,
    /// Deposited anywhere in the grid.
    pub deposited: Estimate,
    /// Carried out of the grid by photons (including those that never entered).
    pub escaped: Estimate,
    /// Left in photons stopped at `max_collisions`.
    pub stopped: Estimate,
    /// Covariance of the region means, row-major (regions × regions), (eV per source
    /// photon)²: from the batch tallies, as the standard errors are.
    region_covariance: Vec<f64>,
}

impl EnergyImparted {
    /// A weighted sum Σ wᵢ·Tᵢ of region tallies (`(region index, weight)`), with its
    /// standard error from the regions' covariance (regions scored from the same
    /// histories are correlated). Errors on an index beyond the regions.
    pub fn combine(&self, terms: &[(usize, f64)]) -> Result<Estimate> {
        let n = self.regions.len();
        if let Some((i, _)) = terms.iter().find(|(i, _)| *i >= n) {
            return Err(SimError::OutOfRange(format!(
                "region {i} of a tally with {n} regions"
            )));
        }
        let mean = terms
            .iter()
            .map(|&(i, w)| w * self.regions[i].1.ev_per_photon)
            .sum();
        let mut var = 0.0;
        for &(i, wi) in terms {
            for &(j, wj) in terms {
                var += wi * wj * self.region_covariance[i * n + j];
            }
        }
        Ok(Estimate {
            ev_per_photon: mean,
            standard_error: if var.is_nan() {
                f64::INFINITY
            } else {
                var.max(0.0).sqrt()
            },
        })
    }

    /// (deposited + escaped + stopped) − source energy, eV per photon, and its standard
    /// error: zero to Monte Carlo error when energy is conserved.
    pub fn balance(&self) -> (f64, f64) {
        let sum =
            self.deposited.ev_per_photon + self.escaped.ev_per_photon + self.stopped.ev_per_photon;
        let se = (self.deposited.standard_error.powi(2)
            + self.escaped.standard_error.powi(2)
            + self.stopped.standard_error.powi(2))
        .sqrt();
        (sum - self.source_ev, se)
    }
}

/// Per-batch tallies.
struct Batch {
    voxels: Vec<(u32, f64)>,
    regions: Vec<f64>,
    discs: Vec<f64>,
    deposited: f64,
    escaped: f64,
    stopped: f64,
}

/// Runs the tally: `settings.photons` histories from `source` with energies from `beam`
/// through `medium`, scoring in `regions` and (optionally) every voxel.
pub fn simulate(
    medium: &Medium,
    source: &FieldSource,
    beam: &BeamSpectrum,
    regions: &[Region],
    settings: TallySettings,
    seed: u64,
) -> Result<EnergyImparted> {
    simulate_with_fluence(medium, source, beam, regions, &[], settings, seed)
}

/// [`simulate`] with fluence discs scored as well.
pub fn simulate_with_fluence(
    medium: &Medium,
    source: &FieldSource,
    beam: &BeamSpectrum,
    regions: &[Region],
    discs: &[FluenceDisc],
    settings: TallySettings,
    seed: u64,
) -> Result<EnergyImparted> {
    if !(1..=MAX_PHOTONS).contains(&settings.photons) {
        return Err(SimError::OutOfRange(format!(
            "energy imparted: photons = {}; give 1 to {MAX_PHOTONS}",
            settings.photons
        )));
    }
    if settings.max_collisions == 0 {
        return Err(SimError::OutOfRange(
            "energy imparted: max_collisions must be ≥ 1".into(),
        ));
    }
    if beam.max_kev() > medium.e_max_kev() {
        return Err(SimError::OutOfRange(format!(
            "energy imparted: the beam reaches {} keV but the medium is tabulated to {} keV",
            beam.max_kev(),
            medium.e_max_kev()
        )));
    }
    let placed = regions
        .iter()
        .map(Region::placed)
        .collect::<Result<Vec<_>>>()?;
    for d in discs {
        if !(d.centre.is_finite()
            && d.normal.is_finite()
            && (d.normal.length() - 1.0).abs() < 1e-9
            && d.radius.is_finite()
            && d.radius > 0.0)
        {
            return Err(SimError::InvalidGeometry(format!(
                "fluence disc '{}': give a finite centre, a unit normal and a radius > 0",
                d.name
            )));
        }
    }
    let packed = medium.composition().packed();
    let n_vox = packed.len();
    if settings.voxel_map {
        if n_vox > u32::MAX as usize {
            return Err(SimError::OutOfRange(format!(
                "energy imparted: {n_vox} voxels is beyond the voxel map's 2³² limit"
            )));
        }
        // This map and the caller's sum over views (f64 each).
        tomograf_sim::memory::check(n_vox as u128 * 16, "the energy-imparted voxel map")?;
    }
    let photons = settings.photons;
    let batches = photons.div_ceil(BATCH);
    let mut voxel_ev = if settings.voxel_map {
        vec![0.0; n_vox]
    } else {
        Vec::new()
    };
    // Running sums over batches: Σ T_b and Σ T_b² per quantity (regions, discs, then
    // deposited, escaped, stopped).
    let nq = regions.len() + discs.len() + 3;
    let (mut s1, mut s2) = (vec![0.0; nq], vec![0.0; nq]);
    // Σ T_i·T_j over batches for every pair of regions.
    let nr = regions.len();
    let mut s12 = vec![0.0; nr * nr];
    let mut start = 0;
    while start < batches {
        let end = (start + ROUND).min(batches);
        let round: Vec<Batch> = (start..end)
            .into_par_iter()
            .map(|b| {
                let n = BATCH.min(photons - b * BATCH);
                run_batch(medium, source, beam, &placed, discs, settings, seed, b, n)
            })
            .collect();
        for batch in round {
            for (i, e) in &batch.voxels {
                voxel_ev[*i as usize] += e;
            }
            let q = batch.regions.iter().chain(&batch.discs).copied().chain([
                batch.deposited,
                batch.escaped,
                batch.stopped,
            ]);
            for (k, t) in q.enumerate() {
                s1[k] += t;
                s2[k] += t * t;
            }
            for (i, ti) in batch.regions.iter().enumerate() {
                for (j, tj) in batch.regions.iter().enumerate() {
                    s12[i * nr + j] += ti * tj;
                }
            }
        }
        start = end;
    }
    let nf = photons as f64;
    let nb = batches as f64;
    let estimate = |k: usize| {
        let se = if batches < 2 {
            f64::INFINITY
        } else {
            let var = ((s2[k] - s1[k] * s1[k] / nb) / (nb - 1.0)).max(0.0);
            (nb * var).sqrt() / nf
        };
        Estimate {
            ev_per_photon: s1[k] / nf,
            standard_error: se,
        }
    };
    // Cov(mean_i, mean_j) = nb·cov_batch(T_i, T_j) / N² (as the standard errors above).
    let region_covariance = (0..nr * nr)
        .map(|ij| {
            let (i, j) = (ij / nr, ij % nr);
            if batches < 2 {
                return f64::INFINITY;
            }
            let cov = (s12[ij] - s1[i] * s1[j] / nb) / (nb - 1.0);
            nb * cov / (nf * nf)
        })
        .collect();
    voxel_ev.iter_mut().for_each(|e| *e /= nf);
    let m = regions.len() + discs.len();
    Ok(EnergyImparted {
        photons,
        source_ev: beam.mean_kev() * EV_PER_KEV,
        voxel_ev,
        regions: regions
            .iter()
            .enumerate()
            .map(|(k, r)| (r.name.clone(), estimate(k)))
            .collect(),
        discs: discs
            .iter()
            .enumerate()
            .map(|(k, d)| (d.name.clone(), estimate(regions.len() + k)))
            .collect(),
        deposited: estimate(m),
        escaped: estimate(m + 1),
        stopped: estimate(m + 2),
        region_covariance,
    })
}

/// One batch of `n` histories on stream `b`.
#[allow(clippy::too_many_arguments)]
fn run_batch(
    medium: &Medium,
    source: &FieldSource,
    beam: &BeamSpectrum,
    regions: &[PlacedRegion],
    discs: &[FluenceDisc],
    settings: TallySettings,
    seed: u64,
    b: u64,
    n: u64,
) -> Batch {
    let mut rng = ChaCha8Rng::seed_from_u64(frame_seed(seed, b));
    let packed = medium.composition().packed();
    let dims = packed.dims();
    let mut batch = Batch {
        voxels: Vec::new(),
        regions: vec![0.0; regions.len()],
        discs: vec![0.0; discs.len()],
        deposited: 0.0,
        escaped: 0.0,
        stopped: 0.0,
    };
    let track_length = settings.regions == RegionEstimator::TrackLength;
    // For the track-length estimator: each region with its bounding box, which rejects
    // most flights (short ones, in a dense medium) before the exact chord.
    // (A box that cannot be formed — sides overflowing to infinity — filters nothing.)
    let scorers: Vec<(&PlacedRegion, Option<PlacedSolid>)> = if track_length {
        regions
            .iter()
            .map(|r| {
                let (lo, hi) = r.bounds();
                let size = hi - lo;
                let bounds = Solid::Box { size };
                let centre = lo + size * 0.5;
                (
                    r,
                    PlacedSolid::rotated(bounds, centre, DMat3::IDENTITY).ok(),
                )
            })
            .collect()
    } else {
        Vec::new()
    };
    let deposit = |batch: &mut Batch, p: DVec3, ev: f64| {
        if ev <= 0.0 {
            return;
        }
        if !track_length {
            for (k, r) in regions.iter().enumerate() {
                if r.contains(p) {
                    batch.regions[k] += ev;
                }
            }
        }
        let g = packed.world_to_grid(p);
        let inside = (0..3).all(|a| g[a] >= 0.0 && (g[a] as usize) < dims[a]);
        if inside {
            batch.deposited += ev;
            if settings.voxel_map {
                let (i, j, k) = (g.x as usize, g.y as usize, g.z as usize);
                batch
                    .voxels
                    .push(((i + dims[0] * (j + dims[1] * k)) as u32, ev));
            }
        } else {
            // A collision sits on the grid's faces only by rounding: count it as escaped
            // so that the balance still closes.
            batch.escaped += ev;
        }
    };
    for _ in 0..n {
        let mut p = source.position();
        let mut d = source.sample(&mut rng);
        let mut e = beam.sample(&mut rng);
        let mut w = 1.0;
        let mut collisions = 0;
        loop {
            let c = medium.fly(p, d, e, &mut rng);
            let t_end = c.map_or(f64::INFINITY, |c| (c.position - p).length());
            for (k, disc) in discs.iter().enumerate() {
                batch.discs[k] += disc.score(p, d, t_end, e, w);
            }
            if track_length {
                for (k, (r, bounds)) in scorers.iter().enumerate() {
                    let span = bounds.map_or(Some((0.0, t_end)), |b| {
                        b.span(p, d)
                            .map(|(a, b)| (a.max(0.0), b.min(t_end)))
                            .filter(|(a, b)| a < b)
                    });
                    let Some((b0, b1)) = span else {
                        continue;
                    };
                    if let Some((t0, t1)) = r.chord(p, d, b0, b1) {
                        let kev = medium.deposited_along(p + d * t0, p + d * t1, e);
                        batch.regions[k] += w * kev * EV_PER_KEV;
                    }
                }
            }
            let Some(c) = c else {
                batch.escaped += w * e * EV_PER_KEV;
                break;
            };
            deposit(&mut batch, c.position, w * c.p_photo * e * EV_PER_KEV);
            w *= 1.0 - c.p_photo;
            let (nd, ne, compton) = medium.scatter(&c, d, &mut rng);
            if compton {
                deposit(&mut batch, c.position, w * (e - ne) * EV_PER_KEV);
            }
            collisions += 1;
            if ne < E_CUTOFF_KEV {
                deposit(&mut batch, c.position, w * ne * EV_PER_KEV);
                break;
            }
            if collisions >= settings.max_collisions {
                batch.stopped += w * ne * EV_PER_KEV;
                break;
            }
            if w < ROULETTE {
                if rng.random::<f64>() < 0.5 {
                    w *= 2.0;
                } else {
                    break;
                }
            }
            p = c.position;
            d = nd;
            e = ne;
        }
    }
    batch
}

/// Absorbed dose per voxel (Gy) from a voxel map of eV per source photon and the number
/// of source photons the exposure emits into the field: D = E·N / (ρ·V), with the mass
/// from the composition's density. Voxels of zero density get 0.
pub fn dose_gy(medium: &Medium, voxel_ev: &[f64], source_photons: f64) -> Result<Vec<f32>> {
    let packed = medium.composition().packed();
    if voxel_ev.len() != packed.len() {
        return Err(SimError::OutOfRange(format!(
            "dose: a map of {} voxels for a grid of {}",
            voxel_ev.len(),
            packed.len()
        )));
    }
    if !(source_photons.is_finite() && source_photons >= 0.0) {
        return Err(SimError::OutOfRange(format!(
            "dose: {source_photons} source photons; give a finite number ≥ 0"
        )));
    }
    let s = packed.spacing();
    let voxel_cm3 = s.x * s.y * s.z / 1000.0;
    Ok(voxel_ev
        .iter()
        .zip(packed.data())
        .map(|(&ev, &v)| {
            let (rho, _) = unpack(v);
            if rho <= 0.0 {
                return 0.0;
            }
            let kg = f64::from(rho) * voxel_cm3 / 1000.0;
            (ev * source_photons * JOULE_PER_EV / kg) as f32
        })
        .collect())
}
