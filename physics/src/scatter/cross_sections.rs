//! Angular distributions of photon scattering: Klein–Nishina modified by the incoherent
//! scattering function S(x, Z) (Compton), and Thomson modified by the atomic form factor
//! F(x, Z) (Rayleigh), for a material (independent-atom mixture).
//!
//! Data: `physics/data/scatter_factors.csv`, Hubbell et al., J. Phys. Chem. Ref. Data 4 (1975)
//! 471 via xraylib (made by `scripts/make_scatter_tables.py`). Momentum transfer
//! `x = sin(θ/2)/λ` in Å⁻¹, `λ = 12.39842/E[keV]` Å.
//!
//! The interaction *probabilities* (how often each process happens) come from the
//! material's attenuation tables ([`tomograf_sim::material`]); this module gives only *where the
//! photon goes*: a sampler and the matching normalised density `p(cos θ)` per steradian
//! (`2π ∫ p dμ = 1`), which the point-detector estimator needs. Sampler and density are
//! consistent by construction (the Rayleigh density is exactly the piecewise form sampled;
//! the Compton normalisation is a 4096-interval Simpson quadrature, relative error < 10⁻⁶).

use rand::Rng;
use std::sync::OnceLock;
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::material::{Material, element};

/// hc in keV·Å: `λ[Å] = HC_KEV_ANGSTROM / E[keV]`.
pub const HC_KEV_ANGSTROM: f64 = 12.398_419_84;
/// Electron rest energy, keV.
pub const ELECTRON_REST_KEV: f64 = 510.998_950;
/// Classical electron radius squared, cm².
pub const RE2_CM2: f64 = 7.940_787_5e-26;

const TABLE_CSV: &str = include_str!("../../data/scatter_factors.csv");

/// Per element: (x, S, F) rows, x ascending.
fn tables() -> &'static std::result::Result<Vec<Vec<[f64; 3]>>, String> {
    static T: OnceLock<std::result::Result<Vec<Vec<[f64; 3]>>, String>> = OnceLock::new();
    T.get_or_init(|| {
        let mut out: Vec<Vec<[f64; 3]>> = vec![Vec::new(); 92];
        for (n, line) in TABLE_CSV.lines().enumerate() {
            if line.starts_with('#') || line.starts_with("z,") || line.trim().is_empty() {
                continue;
            }
            let f: Vec<f64> = line
                .split(',')
                .map(|s| s.trim().parse::<f64>())
                .collect::<std::result::Result<_, _>>()
                .map_err(|e| format!("scatter_factors.csv line {}: {e}", n + 1))?;
            if f.len() != 4 || !(1.0..=92.0).contains(&f[0]) {
                return Err(format!("scatter_factors.csv line {}: bad row", n + 1));
            }
            out[f[0] as usize - 1].push([f[1], f[2], f[3]]);
        }
        if out.iter().any(|t| t.len() < 2) {
            return Err("scatter_factors.csv lacks elements".into());
        }
        Ok(out)
    })
}

/// Linear interpolation of column `col` of an element table at `x` (clamped at the ends).
fn interp(t: &[[f64; 3]], x: f64, col: usize) -> f64 {
    let i = t.partition_point(|r| r[0] <= x);
    if i == 0 {
        return t[0][col];
    }
    if i >= t.len() {
        return t[t.len() - 1][col];
    }
    let (a, b) = (t[i - 1], t[i]);
    a[col] + (b[col] - a[col]) * (x - a[0]) / (b[0] - a[0])
}

/// Incoherent scattering function S(x, Z) of element `z` (Hubbell 1975), `x` in Å⁻¹.
pub fn incoherent_function(z: u8, x: f64) -> Result<f64> {
    Ok(interp(element_table(z)?, x, 1))
}

/// Atomic form factor F(x, Z) of element `z` (Hubbell 1975), `x` in Å⁻¹.
pub fn form_factor(z: u8, x: f64) -> Result<f64> {
    Ok(interp(element_table(z)?, x, 2))
}

fn element_table(z: u8) -> Result<&'static [[f64; 3]]> {
    let t = tables()
        .as_ref()
        .map_err(|e| SimError::InvalidMaterial(e.clone()))?;
    if !(1..=92).contains(&z) {
        return Err(SimError::InvalidMaterial(format!(
            "Z = {z} has no scattering factors (1..=92)"
        )));
    }
    Ok(&t[z as usize - 1])
}

/// Klein–Nishina differential cross-section per free electron, cm²/sr, at photon energy
/// `e_kev` and scattering-angle cosine `mu`.
pub fn klein_nishina(e_kev: f64, mu: f64) -> f64 {
    let ratio = compton_ratio(e_kev, mu);
    0.5 * RE2_CM2 * ratio * ratio * (ratio + 1.0 / ratio - (1.0 - mu * mu))
}

/// E′/E of a photon Compton-scattered by a free electron at rest through cos θ = `mu`.
pub fn compton_ratio(e_kev: f64, mu: f64) -> f64 {
    1.0 / (1.0 + e_kev / ELECTRON_REST_KEV * (1.0 - mu))
}

/// Momentum transfer x = sin(θ/2)/λ (Å⁻¹) for energy `e_kev` and cos θ = `mu`.
pub fn momentum_transfer(e_kev: f64, mu: f64) -> f64 {
    e_kev / HC_KEV_ANGSTROM * (0.5 * (1.0 - mu)).max(0.0).sqrt()
}

/// Cells of the Rayleigh density in x: 0, then log-spaced to `X_MAX`.
const RAYLEIGH_CELLS: usize = 2048;
const X_MIN: f64 = 1e-4;
const X_MAX: f64 = 40.0;
const SIMPSON_INTERVALS: usize = 4096;

/// The scattering factors of one material (an independent-atom mixture), ready to sample.
#[derive(Debug, Clone)]
pub struct ScatterFactors {
    /// (x, S_mix(x) / S_mix(∞)) on the element grid, S normalised to [0, 1].
    s: Vec<[f64; 3]>,
    /// Cell edges in x² (Å⁻²), `RAYLEIGH_CELLS + 1` values.
    x2: Vec<f64>,
    /// F²_mix / F²_mix(0) at each cell's mid-point (piecewise-constant density in x²).
    f2: Vec<f64>,
    /// Cumulative ∫ f2 d(x²) at the cell edges.
    cum: Vec<f64>,
}

impl ScatterFactors {
    /// The mixture's factors: `S_mix = Σ (wᵢ/Aᵢ) Sᵢ`, `F²_mix = Σ (wᵢ/Aᵢ) Fᵢ²`.
    pub fn new(material: &Material) -> Result<Self> {
        let parts: Vec<(u8, f64)> = material
            .composition()
            .iter()
            .map(|&(z, w)| Ok((z, w / element(z)?.atomic_mass_u)))
            .collect::<Result<_>>()?;
        let z_sum: f64 = parts.iter().map(|&(z, n)| n * f64::from(z)).sum();
        let z2_sum: f64 = parts.iter().map(|&(z, n)| n * f64::from(z).powi(2)).sum();
        let grid = element_table(1)?;
        let mut s = Vec::with_capacity(grid.len());
        for row in grid {
            let mut v = 0.0;
            for &(z, n) in &parts {
                v += n * interp(element_table(z)?, row[0], 1);
            }
            s.push([row[0], (v / z_sum).clamp(0.0, 1.0), 0.0]);
        }
        let f2_at = |x: f64| -> Result<f64> {
            let mut v = 0.0;
            for &(z, n) in &parts {
                v += n * interp(element_table(z)?, x, 2).powi(2);
            }
            Ok(v / z2_sum)
        };
        let mut xe = vec![0.0];
        let r = (X_MAX / X_MIN).powf(1.0 / (RAYLEIGH_CELLS - 1) as f64);
        xe.extend((0..RAYLEIGH_CELLS).map(|i| X_MIN * r.powi(i as i32)));
        let x2: Vec<f64> = xe.iter().map(|x| x * x).collect();
        let mut f2 = Vec::with_capacity(RAYLEIGH_CELLS);
        let mut cum = vec![0.0];
        for i in 0..RAYLEIGH_CELLS {
            let v = f2_at(0.5 * (xe[i] + xe[i + 1]))?.max(0.0);
            f2.push(v);
            cum.push(cum[i] + v * (x2[i + 1] - x2[i]));
        }
        Ok(Self { s, x2, f2, cum })
    }

    /// S_mix(x)/S_mix(∞) ∈ [0, 1].
    pub fn incoherent(&self, x: f64) -> f64 {
        interp(&self.s, x, 1)
    }

    /// F²_mix(x)/F²_mix(0) as the Rayleigh sampler uses it (constant on each cell in x²).
    pub fn form_factor_squared(&self, x: f64) -> f64 {
        let x2 = x * x;
        let i = self.x2.partition_point(|&e| e <= x2);
        if i == 0 || i > self.f2.len() {
            return if i == 0 { self.f2[0] } else { 0.0 };
        }
        self.f2[i - 1]
    }

    /// Samples a Compton scattering: (cos θ, E′/E), Klein–Nishina by Kahn's method
    /// (Butcher & Messel) then rejection with S(x)/S(∞).
    pub fn sample_compton<R: Rng>(&self, e_kev: f64, rng: &mut R) -> (f64, f64) {
        let k = e_kev / ELECTRON_REST_KEV;
        let eps0 = 1.0 / (1.0 + 2.0 * k);
        let eps0sq = eps0 * eps0;
        let alpha1 = -eps0.ln();
        let alpha2 = alpha1 + 0.5 * (1.0 - eps0sq);
        loop {
            let (eps, epssq) = if alpha1 > alpha2 * rng.random::<f64>() {
                let e = (-alpha1 * rng.random::<f64>()).exp();
                (e, e * e)
            } else {
                let e2 = eps0sq + (1.0 - eps0sq) * rng.random::<f64>();
                (e2.sqrt(), e2)
            };
            let onecost = (1.0 - eps) / (eps * k);
            let sint2 = onecost * (2.0 - onecost);
            let g = 1.0 - eps * sint2 / (1.0 + epssq);
            if g < rng.random::<f64>() {
                continue;
            }
            let mu = (1.0 - onecost).clamp(-1.0, 1.0);
            if self.incoherent(momentum_transfer(e_kev, mu)) >= rng.random::<f64>() {
                return (mu, eps);
            }
        }
    }

    /// Samples a Rayleigh scattering cos θ: x² from F² (truncated at the kinematic limit),
    /// then rejection with the Thomson factor (1 + cos²θ)/2.
    pub fn sample_rayleigh<R: Rng>(&self, e_kev: f64, rng: &mut R) -> f64 {
        let k2 = (e_kev / HC_KEV_ANGSTROM).powi(2);
        let top = self.cum_at(k2);
        loop {
            let target = rng.random::<f64>() * top;
            let i = (self.cum.partition_point(|&c| c <= target)).clamp(1, self.f2.len()) - 1;
            let x2 = if self.f2[i] > 0.0 {
                self.x2[i] + (target - self.cum[i]) / self.f2[i]
            } else {
                self.x2[i]
            };
            let mu = (1.0 - 2.0 * x2.min(k2) / k2).clamp(-1.0, 1.0);
            if 0.5 * (1.0 + mu * mu) >= rng.random::<f64>() {
                return mu;
            }
        }
    }

    /// ∫₀^{x²} f2 d(x²).
    fn cum_at(&self, x2: f64) -> f64 {
        let i = self.x2.partition_point(|&e| e <= x2);
        if i == 0 {
            return 0.0;
        }
        if i > self.f2.len() {
            return self.cum[self.f2.len()];
        }
        self.cum[i - 1] + self.f2[i - 1] * (x2 - self.x2[i - 1])
    }

    /// Normalisation of the Compton density at `e_kev`: 2π ∫ KN·S/S(∞) dμ (cm²/sr·sr).
    pub fn compton_norm(&self, e_kev: f64) -> f64 {
        self.compton_integrals(e_kev).0
    }

    /// Mean fraction of the photon's energy given to the electron in a Compton scatter at
    /// `e_kev`, ⟨1 − E′/E⟩ = ∫ KN·S·(1 − E′/E) dμ / ∫ KN·S dμ, by Simpson's rule on the
    /// grid of [`ScatterFactors::compton_norm`]: the mean of exactly the distribution that
    /// [`ScatterFactors::sample_compton`] draws from.
    pub fn compton_transfer_fraction(&self, e_kev: f64) -> f64 {
        self.compton_integrals(e_kev).1
    }

    /// [`ScatterFactors::compton_norm`] and [`ScatterFactors::compton_transfer_fraction`]
    /// from one evaluation of KN·S on Simpson's grid (`SIMPSON_INTERVALS` + 1 points of μ),
    /// each summed in its own order.
    pub fn compton_integrals(&self, e_kev: f64) -> (f64, f64) {
        let n = SIMPSON_INTERVALS;
        let h = 2.0 / n as f64;
        let mu = |i: usize| -1.0 + i as f64 * h;
        // x grows as μ falls: S's interval is found by walking the table from μ = 1 down
        // (the same interval, and so the same value, as `incoherent`'s search).
        let mut f = vec![0.0; n + 1];
        let mut ratio = vec![0.0; n + 1];
        let t = &self.s;
        let mut at = 0;
        for i in (0..=n).rev() {
            let x = momentum_transfer(e_kev, mu(i));
            while at < t.len() && t[at][0] <= x {
                at += 1;
            }
            let s = if at == 0 {
                t[0][1]
            } else if at >= t.len() {
                t[t.len() - 1][1]
            } else {
                let (a, b) = (t[at - 1], t[at]);
                a[1] + (b[1] - a[1]) * (x - a[0]) / (b[0] - a[0])
            };
            // klein_nishina(e_kev, μ), its E′/E kept for the transfer fraction.
            let (m, r) = (mu(i), compton_ratio(e_kev, mu(i)));
            f[i] = 0.5 * RE2_CM2 * r * r * (r + 1.0 / r - (1.0 - m * m)) * s;
            ratio[i] = r;
        }
        // Simpson's weights are 1, 4, 2, …, 4, 1: powers of two, so w·f is exact.
        let weight = |i: usize| {
            if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            }
        };
        let mut sum = f[0] + f[n];
        for (i, &fi) in f.iter().enumerate().take(n).skip(1) {
            sum += weight(i) * fi;
        }
        let norm = 2.0 * std::f64::consts::PI * sum * h / 3.0;
        let (mut num, mut den) = (0.0, 0.0);
        for (i, &fi) in f.iter().enumerate() {
            let wf = weight(i) * fi;
            num += wf * (1.0 - ratio[i]);
            den += wf;
        }
        (norm, if den > 0.0 { num / den } else { 0.0 })
    }

    /// Normalisation of the Rayleigh density at `e_kev`: 2π ∫ (1+μ²)/2 · f2 dμ, exact for
    /// the piecewise-constant f2 (μ = 1 − 2x²/k², so dμ = 2 d(x²)/k²).
    pub fn rayleigh_norm(&self, e_kev: f64) -> f64 {
        let k2 = (e_kev / HC_KEV_ANGSTROM).powi(2);
        // ∫ (1+μ²)/2 dμ over μ ∈ [m1, m0] = [(μ + μ³/3)/2].
        let prim = |x2: f64| {
            let mu = 1.0 - 2.0 * x2 / k2;
            0.5 * (mu + mu * mu * mu / 3.0)
        };
        let mut sum = 0.0;
        for i in 0..self.f2.len() {
            let (a, b) = (self.x2[i], self.x2[i + 1].min(k2));
            if a >= k2 {
                break;
            }
            sum += self.f2[i] * (prim(a) - prim(b));
        }
        2.0 * std::f64::consts::PI * sum
    }

    /// The normalised Compton density p(μ) per steradian given `norm` =
    /// [`ScatterFactors::compton_norm`] at `e_kev`.
    #[inline]
    pub fn compton_density(&self, e_kev: f64, mu: f64, norm: f64) -> f64 {
        klein_nishina(e_kev, mu) * self.incoherent(momentum_transfer(e_kev, mu)) / norm
    }

    /// The normalised Rayleigh density p(μ) per steradian given `norm` =
    /// [`ScatterFactors::rayleigh_norm`] at `e_kev`.
    #[inline]
    pub fn rayleigh_density(&self, e_kev: f64, mu: f64, norm: f64) -> f64 {
        0.5 * (1.0 + mu * mu) * self.form_factor_squared(momentum_transfer(e_kev, mu)) / norm
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tomograf_sim::material::by_name;

    /// The Compton integrals from one pass (S found by walking its table, the E′/E kept)
    /// equal, bit for bit, Simpson's rule written out with S looked up point by point: the
    /// tables, and so every scatter image, are unchanged by the faster pass.
    #[test]
    fn compton_integrals_equal_simpsons_rule_point_by_point() {
        for name in ["water", "cortical-bone", "iodine-contrast", "air"] {
            let f = ScatterFactors::new(&by_name(name).unwrap()).unwrap();
            for e in [1.0, 4.9, 10.25, 33.17, 60.0, 99.5, 150.0, 499.0] {
                let n = SIMPSON_INTERVALS;
                let h = 2.0 / n as f64;
                let g = |mu: f64| klein_nishina(e, mu) * f.incoherent(momentum_transfer(e, mu));
                let mut sum = g(-1.0) + g(1.0);
                let (mut num, mut den) = (0.0, 0.0);
                for i in 0..=n {
                    let mu = -1.0 + i as f64 * h;
                    let w = if i == 0 || i == n {
                        1.0
                    } else if i % 2 == 1 {
                        4.0
                    } else {
                        2.0
                    };
                    if i > 0 && i < n {
                        sum += w * g(mu);
                    }
                    let v = w * klein_nishina(e, mu) * f.incoherent(momentum_transfer(e, mu));
                    num += v * (1.0 - compton_ratio(e, mu));
                    den += v;
                }
                let norm = 2.0 * std::f64::consts::PI * sum * h / 3.0;
                let (got_norm, got_transfer) = f.compton_integrals(e);
                assert_eq!(
                    got_norm.to_bits(),
                    norm.to_bits(),
                    "{name} at {e} keV: norm"
                );
                assert_eq!(
                    got_transfer.to_bits(),
                    (num / den).to_bits(),
                    "{name} at {e} keV: transfer fraction"
                );
            }
        }
    }
}
