//! Photon transport through a voxel composition: Woodcock (delta) tracking with a majorant
//! per brick of voxels ([`super::majorant`]; or one for the whole volume), interactions
//! sampled from the material tables ([`super::interaction_table`], log–log between knots
//! at every keV and at the edges) — photoelectric absorption
//! (no fluorescence: the energy is taken as deposited locally), Compton (Klein–Nishina ×
//! S) and Rayleigh (Thomson × F²).
//!
//! Units: positions mm (world LPS), energies keV, mass attenuation cm²/g, densities g/cm³,
//! linear attenuation mm⁻¹.

use super::cross_sections::{ScatterFactors, compton_ratio};
use super::interaction_table::{
    COMPTON_NORM, EnergyKnots, INCOHERENT, InteractionTable, Located, PHOTOELECTRIC, RAYLEIGH_NORM,
    TOTAL, TRANSFER_FRACTION,
};
use super::majorant::{DEFAULT_BRICK, MajorantGrid};
use glam::DVec3;
use rand::Rng;
use tomograf_sim::accel::intervals::walk_bricks;
use tomograf_sim::composition::{Composition, unpack};
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::material::Material;
use tomograf_sim::ray::{GridRay, Ray};
use tomograf_sim::trace::{MaterialPaths, siddon};

/// Lowest energy tracked (keV); a photon scattered below it is counted as absorbed.
pub const E_CUTOFF_KEV: f64 = 1.0;

/// One material's angular distributions and interaction table (`None`: absent from the
/// composition, never looked up).
#[derive(Debug, Clone)]
struct MaterialData {
    factors: ScatterFactors,
    tab: Option<InteractionTable>,
}

/// The medium a photon crosses: the composition and, per material, its cross sections.
#[derive(Debug, Clone)]
pub struct Medium {
    composition: Composition,
    /// The energies every material's table holds (one lookup per energy serves them all).
    knots: EnergyKnots,
    materials: Vec<MaterialData>,
    /// Global majorant per whole-keV cell (k: [k + 1, k + 2] keV), mm⁻¹.
    majorant: Vec<f64>,
    /// Per-brick majorants; `None`: the global one everywhere.
    bricks: Option<MajorantGrid>,
    e_max_kev: f64,
}

/// What happened at a real collision: the photon's state before it.
#[derive(Debug, Clone, Copy)]
pub struct Collision {
    /// Position, world mm.
    pub position: DVec3,
    /// Energy, keV.
    pub energy_kev: f64,
    /// Material index at the site.
    pub material: usize,
    /// Probability that the collision is photoelectric / Compton / Rayleigh.
    pub p_photo: f64,
    /// Compton probability.
    pub p_compton: f64,
    /// Rayleigh probability.
    pub p_rayleigh: f64,
}

/// Normalisations of the angular densities at one collision ([`Medium::angular_norms`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AngularNorms {
    /// Of the Compton density (KN × S).
    pub compton: f64,
    /// Of the Rayleigh density (Thomson × F²).
    pub rayleigh: f64,
}

/// The fate of one analog photon history ([`Medium::walk`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fate {
    /// Left the volume without interacting.
    Transmitted,
    /// Left the volume after at least one scatter.
    Escaped,
    /// Absorbed (photoelectric, or scattered below [`E_CUTOFF_KEV`], or past the order limit).
    Absorbed,
}

impl Medium {
    /// Tabulates every material of `composition` (`materials` in its index order) from
    /// 1 keV to `e_max_kev` (the spectrum's highest energy).
    pub fn new(composition: &Composition, materials: &[Material], e_max_kev: f64) -> Result<Self> {
        if materials.len() != composition.materials().len() {
            return Err(SimError::OutOfRange(format!(
                "{} materials given for a composition of {}",
                materials.len(),
                composition.materials().len()
            )));
        }
        if !(e_max_kev.is_finite() && (E_CUTOFF_KEV..=500.0).contains(&e_max_kev)) {
            return Err(SimError::OutOfRange(format!(
                "scatter needs energies in 1–500 keV; the spectrum reaches {e_max_kev} keV"
            )));
        }
        let n = e_max_kev.ceil() as usize + 1;
        let present = composition.present();
        let grid = MajorantGrid::build(composition.packed(), materials.len(), DEFAULT_BRICK)?;
        let rho_max = grid.global_max();
        let in_use: Vec<&Material> = materials
            .iter()
            .zip(&present)
            .filter_map(|(m, &p)| p.then_some(m))
            .collect();
        let knots = EnergyKnots::for_materials(&in_use, n)?;
        let mut data = Vec::with_capacity(materials.len());
        for (i, m) in materials.iter().enumerate() {
            let factors = ScatterFactors::new(m)?;
            let tab = present[i]
                .then(|| InteractionTable::new(m, &factors, &knots))
                .transpose()?;
            data.push(MaterialData { factors, tab });
        }
        let majorant = (0..knots.cells())
            .map(|k| {
                data.iter()
                    .zip(&rho_max)
                    .filter_map(|(d, r)| Some(d.tab.as_ref()?.cell_max_total(&knots, k) * r / 10.0))
                    .fold(0.0, f64::max)
                    * (1.0 + 1e-9)
            })
            .collect();
        let medium = Self {
            composition: composition.clone(),
            knots,
            materials: data,
            majorant,
            bricks: None,
            e_max_kev,
        };
        Ok(Self {
            bricks: Some(medium.tabulated(grid)),
            ..medium
        })
    }

    /// `grid` with its majorants tabulated for this medium's whole-keV cells.
    fn tabulated(&self, mut grid: MajorantGrid) -> MajorantGrid {
        grid.tabulate(self.majorant.len(), |m, k| {
            self.materials[m]
                .tab
                .as_ref()
                .map_or(0.0, |t| t.cell_max_total(&self.knots, k) / 10.0)
        });
        grid
    }

    /// The same medium tracked with a majorant per brick of `size³` voxels (`Some`, the
    /// default with [`DEFAULT_BRICK`]) or one majorant for the whole volume (`None`). The
    /// choice changes which random numbers are drawn, not what is sampled.
    pub fn with_majorant_bricks(mut self, size: Option<usize>) -> Result<Self> {
        self.bricks = size
            .map(|s| MajorantGrid::build(self.composition.packed(), self.materials.len(), s))
            .transpose()?
            .map(|grid| self.tabulated(grid));
        Ok(self)
    }

    /// The composition the photons cross.
    pub fn composition(&self) -> &Composition {
        &self.composition
    }

    /// Highest tabulated energy, keV.
    pub fn e_max_kev(&self) -> f64 {
        self.e_max_kev
    }

    /// Column `col` of material `m`'s interaction table at the energy `at` locates
    /// (log–log between the knots; 0 for a material absent from the composition).
    #[inline]
    fn table(&self, m: usize, at: Located, col: usize) -> f64 {
        self.materials[m]
            .tab
            .as_ref()
            .map_or(0.0, |t| t.at(at, col))
    }

    /// The whole-keV cell holding `e` (the majorants' index).
    #[inline]
    fn cell(&self, e: f64) -> usize {
        ((e - 1.0).max(0.0) as usize).min(self.majorant.len() - 1)
    }

    #[inline]
    fn majorant(&self, e: f64) -> f64 {
        self.majorant[self.cell(e)]
    }

    /// Mass attenuation (cm²/g) of material `m` at `e` keV (total).
    pub fn mass_attenuation(&self, m: usize, e: f64) -> f64 {
        self.table(m, self.knots.locate(e), TOTAL)
    }

    /// Mass energy-deposition coefficient (cm²/g) of material `m` at `e` keV as this
    /// transport deposits energy: μ_pe/ρ (the whole photon energy: no fluorescence) plus
    /// μ_inc/ρ × the mean Compton energy-transfer fraction under KN × S. Times the photon
    /// energy, the expected energy deposited per g/cm² crossed.
    pub fn deposition_coefficient(&self, m: usize, e: f64) -> f64 {
        self.deposition_at(m, self.knots.locate(e))
    }

    /// [`Medium::deposition_coefficient`] at a located energy.
    #[inline]
    fn deposition_at(&self, m: usize, at: Located) -> f64 {
        self.table(m, at, PHOTOELECTRIC)
            + self.table(m, at, INCOHERENT) * self.table(m, at, TRANSFER_FRACTION)
    }

    /// Expected energy (keV) a photon of `e` keV deposits per unit weight while crossing
    /// the segment `from` → `to` (world mm): E·Σ_m (μ_dep/ρ)_m·(ρℓ)_m, with the
    /// per-material ρℓ traced exactly through the voxels (Siddon). The track-length
    /// estimator of the energy imparted.
    pub fn deposited_along(&self, from: DVec3, to: DVec3, e: f64) -> f64 {
        let sums = self.paths(from, to);
        let at = self.knots.locate(e);
        let mut depth = 0.0;
        for (m, &s) in sums.iter().enumerate().take(self.materials.len()) {
            if s > 0.0 {
                depth += self.deposition_at(m, at) * s / 10.0;
            }
        }
        e * depth
    }

    /// Per-material Σρℓ (g/cm³·mm) along the segment `from` → `to`.
    pub fn paths(&self, from: DVec3, to: DVec3) -> [f64; tomograf_sim::composition::MAX_MATERIALS] {
        let packed = self.composition.packed();
        let mut acc = MaterialPaths::new(packed.data());
        if let Some(g) = GridRay::clip(packed, &Ray::segment(from, to)) {
            siddon::trace(packed.dims(), &g, &mut acc);
        }
        *acc.sums()
    }

    /// Transmission exp(−Σ μ/ρ·ρℓ) at energy `e` for paths from [`Medium::paths`].
    pub fn transmission(&self, sums: &[f64], e: f64) -> f64 {
        let at = self.knots.locate(e);
        let mut tau = 0.0;
        for (m, &s) in sums.iter().enumerate().take(self.materials.len()) {
            if s > 0.0 {
                tau += self.table(m, at, TOTAL) * s / 10.0;
            }
        }
        (-tau).exp()
    }

    /// Each material's total μ/ρ (cm²/g) at `e` keV, for many [`Medium::transmission_with`]
    /// at one energy (materials past the medium's list: 0).
    pub fn attenuations(&self, e: f64) -> [f64; tomograf_sim::composition::MAX_MATERIALS] {
        let at = self.knots.locate(e);
        let mut out = [0.0; tomograf_sim::composition::MAX_MATERIALS];
        for (m, o) in out.iter_mut().enumerate().take(self.materials.len()) {
            *o = self.table(m, at, TOTAL);
        }
        out
    }

    /// [`Medium::transmission`] with the μ/ρ of [`Medium::attenuations`]: the same value,
    /// bit for bit.
    pub fn transmission_with(&self, sums: &[f64], mass_attenuation: &[f64]) -> f64 {
        let mut tau = 0.0;
        for (&s, &mu) in sums.iter().zip(mass_attenuation).take(self.materials.len()) {
            if s > 0.0 {
                tau += mu * s / 10.0;
            }
        }
        (-tau).exp()
    }

    /// Flies a photon from `p` along unit `d` to its next real collision (Woodcock):
    /// `None` if it leaves the volume first.
    pub fn fly<R: Rng>(&self, p: DVec3, d: DVec3, e: f64, rng: &mut R) -> Option<Collision> {
        let ray = Ray {
            origin: p,
            direction: d,
            t_min: 0.0,
            t_max: f64::INFINITY,
        };
        let g = GridRay::clip(self.composition.packed(), &ray)?;
        let at = self.knots.locate(e);
        let (t, m) = match &self.bricks {
            None => self.fly_global(&g, e, at, rng),
            Some(grid) => self.fly_bricks(grid, &g, e, at, rng),
        }?;
        Some(self.collision(p + d * t, e, m))
    }

    /// Forced collision for a flight from `p` along unit `d` at `e` keV: the photon is made
    /// to collide inside the volume, at the optical depth τ* = −ln(1 − u·P) for the uniform
    /// `u` ∈ [0, 1) the caller draws (so that it may stratify it), where P = 1 − e^(−τ) is
    /// the probability that the flight collides at all (τ: the optical depth of the whole
    /// chord, traced exactly through the voxels). Returns the collision and P, the weight
    /// the photon must carry on: the expected score of the flight is P × the expected score
    /// at a collision drawn this way, so the estimate stays unbiased while the depth of the
    /// collision — the main source of variance of a forced-detection score (a site near the
    /// exit scores e^τ times one near the entrance) — no longer comes from an analog draw
    /// and the flights that would leave the volume without colliding no longer score
    /// nothing. `None` when the chord misses the volume or crosses no matter. `segments` is
    /// scratch space (the chord's voxels), reused between calls.
    pub fn fly_forced(
        &self,
        p: DVec3,
        d: DVec3,
        e: f64,
        u: f64,
        segments: &mut Vec<(usize, f64)>,
    ) -> Option<(Collision, f64)> {
        let ray = Ray {
            origin: p,
            direction: d,
            t_min: 0.0,
            t_max: f64::INFINITY,
        };
        let packed = self.composition.packed();
        let g = GridRay::clip(packed, &ray)?;
        segments.clear();
        siddon::trace(packed.dims(), &g, &mut SegmentList(segments));
        let at = self.knots.locate(e);
        let data = packed.data();
        // μ (mm⁻¹) of a voxel; zero for empty voxels.
        let mu = |v: usize| {
            let (rho, m) = unpack(data[v]);
            (self.table(m, at, TOTAL) * f64::from(rho) / 10.0, m)
        };
        let tau: f64 = segments.iter().map(|&(v, l)| mu(v).0 * l).sum();
        if tau.is_nan() || tau <= 0.0 {
            return None;
        }
        let p_collide = -(-tau).exp_m1();
        // Never past the chord's own depth (rounding of the sums).
        let target = (-(-u * p_collide).ln_1p()).min(tau);
        let mut depth = 0.0;
        let mut t = g.t_enter.max(0.0);
        let mut last = None;
        for &(v, l) in segments.iter() {
            let (mu_v, m) = mu(v);
            if mu_v > 0.0 {
                last = Some((t + l, m));
                if depth + mu_v * l >= target {
                    let s = ((target - depth) / mu_v).clamp(0.0, l);
                    return Some((self.collision(p + d * (t + s), e, m), p_collide));
                }
                depth += mu_v * l;
            }
            t += l;
        }
        // Rounding left the target a hair beyond the summed depth: the chord's last matter.
        let (t, m) = last?;
        Some((self.collision(p + d * t, e, m), p_collide))
    }

    /// The collision at `position` in material `m` at `e` keV.
    fn collision(&self, position: DVec3, e: f64, m: usize) -> Collision {
        let at = self.knots.locate(e);
        let tot = self.table(m, at, TOTAL);
        let (pe, inc) = (
            self.table(m, at, PHOTOELECTRIC),
            self.table(m, at, INCOHERENT),
        );
        Collision {
            position,
            energy_kev: e,
            material: m,
            p_photo: pe / tot,
            p_compton: inc / tot,
            p_rayleigh: 1.0 - (pe + inc) / tot,
        }
    }

    /// Woodcock tracking with the global majorant: the parameter of the real collision and
    /// the material there.
    fn fly_global<R: Rng>(
        &self,
        g: &GridRay,
        e: f64,
        at: Located,
        rng: &mut R,
    ) -> Option<(f64, usize)> {
        let maj = self.majorant(e);
        if maj <= 0.0 {
            return None;
        }
        let mut t = g.t_enter.max(0.0);
        loop {
            t += -(1.0 - rng.random::<f64>()).ln() / maj;
            if t >= g.t_exit {
                return None;
            }
            if let Some(m) = self.accept(g, t, at, maj, rng) {
                return Some((t, m));
            }
        }
    }

    /// Woodcock tracking with per-brick majorants: an exponential optical depth is spent
    /// brick by brick (each at its own majorant, empty bricks crossed for free); where it
    /// runs out is a tentative collision, accepted with probability σ(x)/σ̄_b, else a new
    /// depth is drawn there.
    fn fly_bricks<R: Rng>(
        &self,
        grid: &MajorantGrid,
        g: &GridRay,
        e: f64,
        at: Located,
        rng: &mut R,
    ) -> Option<(f64, usize)> {
        let interval = self.cell(e);
        let mut depth = -(1.0 - rng.random::<f64>()).ln();
        let mut hit = None;
        walk_bricks(grid.size(), grid.brick_dims(), g, |b, t0, t1| {
            let sigma = grid.sigma_in(b, interval);
            if sigma <= 0.0 {
                return true;
            }
            let mut t = t0;
            loop {
                let room = (t1 - t) * sigma;
                if depth >= room {
                    depth -= room;
                    return true;
                }
                t += depth / sigma;
                if let Some(m) = self.accept(g, t, at, sigma, rng) {
                    hit = Some((t, m));
                    return false;
                }
                depth = -(1.0 - rng.random::<f64>()).ln();
            }
        });
        hit
    }

    /// The material at a tentative collision at `t` under majorant `sigma` (mm⁻¹) if the
    /// collision is real, `None` if it is a null collision.
    #[inline]
    fn accept<R: Rng>(
        &self,
        g: &GridRay,
        t: f64,
        at: Located,
        sigma: f64,
        rng: &mut R,
    ) -> Option<usize> {
        let (rho, m) = self.voxel_at(g, t)?;
        (rng.random::<f64>() * sigma < self.table(m, at, TOTAL) * rho / 10.0).then_some(m)
    }

    /// The packed voxel at parameter `t` of `g`: (density g/cm³, material), `None` past
    /// the grid's far faces (rounding) or in a voxel of zero density.
    #[inline]
    fn voxel_at(&self, g: &GridRay, t: f64) -> Option<(f64, usize)> {
        let packed = self.composition.packed();
        let dims = packed.dims();
        let at = g.at(t);
        // `as usize` saturates: a coordinate rounded below 0 is voxel 0.
        let (i, j, k) = (at[0] as usize, at[1] as usize, at[2] as usize);
        if i >= dims[0] || j >= dims[1] || k >= dims[2] {
            return None;
        }
        let (rho, m) = unpack(packed.data()[i + dims[0] * (j + dims[1] * k)]);
        (rho > 0.0).then_some((f64::from(rho), m))
    }

    /// The normalisations of the Compton and Rayleigh angular densities at collision `c`'s
    /// material and energy: looked up once per collision, used for every direction scored
    /// from it ([`Medium::compton_towards`], [`Medium::rayleigh_towards`]).
    pub fn angular_norms(&self, c: &Collision) -> AngularNorms {
        let at = self.knots.locate(c.energy_kev);
        AngularNorms {
            compton: self.table(c.material, at, COMPTON_NORM),
            rayleigh: self.table(c.material, at, RAYLEIGH_NORM),
        }
    }

    /// Compton density p(μ) (sr⁻¹) and E′ at a collision towards cos θ = `mu`.
    #[inline]
    pub fn compton_towards(&self, c: &Collision, norms: &AngularNorms, mu: f64) -> (f64, f64) {
        let e = c.energy_kev;
        let d = &self.materials[c.material];
        (
            d.factors.compton_density(e, mu, norms.compton),
            e * compton_ratio(e, mu),
        )
    }

    /// Rayleigh density p(μ) (sr⁻¹) at a collision towards cos θ = `mu`.
    #[inline]
    pub fn rayleigh_towards(&self, c: &Collision, norms: &AngularNorms, mu: f64) -> f64 {
        self.materials[c.material]
            .factors
            .rayleigh_density(c.energy_kev, mu, norms.rayleigh)
    }

    /// Samples a scatter at a collision: Compton with probability p_c/(p_c + p_r), else
    /// Rayleigh. Returns (new direction, new energy, was Compton).
    pub fn scatter<R: Rng>(&self, c: &Collision, d: DVec3, rng: &mut R) -> (DVec3, f64, bool) {
        let f = &self.materials[c.material].factors;
        let compton = rng.random::<f64>() * (c.p_compton + c.p_rayleigh) < c.p_compton;
        let (mu, e) = if compton {
            let (mu, r) = f.sample_compton(c.energy_kev, rng);
            (mu, c.energy_kev * r)
        } else {
            (f.sample_rayleigh(c.energy_kev, rng), c.energy_kev)
        };
        let phi = 2.0 * std::f64::consts::PI * rng.random::<f64>();
        (rotate(d, mu, phi), e, compton)
    }

    /// One analog history from `p` along `d` at `e` keV, at most `max_order` scatters:
    /// its fate, scatter count and, if it left the volume, its exit direction and energy.
    pub fn walk<R: Rng>(
        &self,
        mut p: DVec3,
        mut d: DVec3,
        mut e: f64,
        max_order: u32,
        rng: &mut R,
    ) -> (Fate, u32, DVec3, f64) {
        let mut order = 0;
        loop {
            let Some(c) = self.fly(p, d, e, rng) else {
                let fate = if order == 0 {
                    Fate::Transmitted
                } else {
                    Fate::Escaped
                };
                return (fate, order, d, e);
            };
            if rng.random::<f64>() < c.p_photo || order >= max_order {
                return (Fate::Absorbed, order, d, e);
            }
            let (nd, ne, _) = self.scatter(&c, d, rng);
            order += 1;
            if ne < E_CUTOFF_KEV {
                return (Fate::Absorbed, order, nd, ne);
            }
            p = c.position;
            d = nd;
            e = ne;
        }
    }
}

/// Records a chord's `(voxel, length_mm)` pairs in order ([`Medium::fly_forced`]).
struct SegmentList<'a>(&'a mut Vec<(usize, f64)>);

impl tomograf_sim::trace::PathAccumulator for SegmentList<'_> {
    #[inline]
    fn segment(&mut self, voxel: usize, length_mm: f64) {
        if length_mm > 0.0 {
            self.0.push((voxel, length_mm));
        }
    }
}

/// `d` turned by polar cos θ = `mu` and azimuth `phi` (radians) about itself; unit result.
pub fn rotate(d: DVec3, mu: f64, phi: f64) -> DVec3 {
    let sin = (1.0 - mu * mu).max(0.0).sqrt();
    let a = if d.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let e1 = d.cross(a).normalize();
    let e2 = d.cross(e1);
    (d * mu + (e1 * phi.cos() + e2 * phi.sin()) * sin).normalize()
}
