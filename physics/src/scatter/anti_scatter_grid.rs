//! The anti-scatter grid: a focused linear grid of lead strips in front of the detector.
//!
//! Geometry (the standard geometric model of a focused linear grid, e.g. Day & Dance,
//! "X-ray transmission formula for antiscatter grids", *Phys. Med. Biol.* 28 (1983) 1429,
//! without their septal-penetration term): strips of thickness `d` and height `h`,
//! separated by an interspace of width `D` filled with a low-Z material; grid ratio
//! r = h / D, line density N = 1 / (D + d). The strips run along the detector's `v` axis
//! (down its columns) and are focused on the source (the grid is used at its focal
//! distance). A photon arriving at a point of the grid along unit direction `w` crosses
//! the grid with a slope across the strips (relative to the focused strip there)
//!
//! `Δ = | (w·û)/(w·n̂) − (f·û)/(f·n̂) |`,   `f` = the direction from the source to the point,
//!
//! and passes between two strips if it enters the interspace at least `h·Δ` from the far
//! strip: averaged over where it enters one period `D + d`, the probability is
//!
//! `T(w, E) = D/(D + d) · max(0, 1 − r·Δ) · exp(−μ_i(E) · h / |w·n̂|)`,
//!
//! the last factor being the interspace material's attenuation over the path `h/|w·n̂|`.
//! The strips are taken as opaque: septal penetration is **not** modelled, so the
//! scatter transmission is a lower bound, the more so at high kV. The primary (Δ = 0) is transmitted
//! with `Tp(E) = D/(D + d) · exp(−μ_i(E) · h)` (normal incidence: the obliquity of the
//! primary at the panel's edge, ≤ 1/cos 10° − 1 ≈ 1.5 % more interspace path at
//! SID 1500 mm with a 430 mm panel, is neglected).
//!
//! Units: lengths in mm (strip thickness given in µm), line density per cm, energies keV,
//! μ in mm⁻¹.

use crate::scatter::cross_sections::ScatterFactors;
use crate::scatter::interaction_table::{EnergyKnots, InteractionTable, TOTAL};
use glam::DVec3;
use serde::{Deserialize, Serialize};
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::material;

/// An anti-scatter grid (a scene's `[scatter.anti_scatter_grid]` table).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub struct AntiScatterGrid {
    /// Grid ratio r = strip height / interspace width (typically 6–16).
    pub ratio: f64,
    /// Strip (line) density, lines per cm (typically 30–80).
    pub lines_per_cm: f64,
    /// Lead strip thickness d, µm (default 36, an assumed typical value: give your grid's).
    #[serde(default = "default_strip_um")]
    pub strip_um: f64,
    /// Interspace material ([`material::by_name`]; "air" for none), default "aluminium".
    #[serde(default = "default_interspace")]
    pub interspace: String,
}

fn default_strip_um() -> f64 {
    36.0
}
fn default_interspace() -> String {
    "aluminium".into()
}

impl AntiScatterGrid {
    /// A grid with ratio `ratio`, `lines_per_cm`, and the default strips and interspace.
    pub fn new(ratio: f64, lines_per_cm: f64) -> Self {
        Self {
            ratio,
            lines_per_cm,
            strip_um: default_strip_um(),
            interspace: default_interspace(),
        }
    }

    /// Checks the settings, naming the bad one.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| {
            Err(SimError::OutOfRange(format!(
                "[scatter.anti_scatter_grid] {m}"
            )))
        };
        if !(self.ratio.is_finite() && (0.0..=50.0).contains(&self.ratio)) {
            return bad(format!("ratio = {}; give 0–50", self.ratio));
        }
        if !(self.lines_per_cm.is_finite() && (1.0..=200.0).contains(&self.lines_per_cm)) {
            return bad(format!(
                "lines_per_cm = {}; give 1–200 lines per cm",
                self.lines_per_cm
            ));
        }
        if !(self.strip_um.is_finite() && self.strip_um >= 0.0) {
            return bad(format!(
                "strip_um = {}; give a thickness ≥ 0 µm",
                self.strip_um
            ));
        }
        if self.strip_um * 1e-3 >= self.period_mm() {
            return bad(format!(
                "strip_um = {} fills the whole period of {:.1} µm at {} lines per cm",
                self.strip_um,
                self.period_mm() * 1e3,
                self.lines_per_cm
            ));
        }
        if self.interspace != "air" {
            material::by_name(&self.interspace).map_err(|e| {
                SimError::OutOfRange(format!(
                    "[scatter.anti_scatter_grid] interspace = '{}': {e}",
                    self.interspace
                ))
            })?;
        }
        Ok(())
    }

    /// The period D + d, mm.
    pub fn period_mm(&self) -> f64 {
        10.0 / self.lines_per_cm
    }

    /// Interspace width D, mm.
    pub fn interspace_mm(&self) -> f64 {
        self.period_mm() - self.strip_um * 1e-3
    }

    /// Strip height h = r·D, mm.
    pub fn height_mm(&self) -> f64 {
        self.ratio * self.interspace_mm()
    }

    /// The open fraction D / (D + d).
    pub fn open_fraction(&self) -> f64 {
        self.interspace_mm() / self.period_mm()
    }

    /// The grid with its interspace's μ/ρ tabulated up to `e_max_kev`
    /// ([`InteractionTable`]: log–log between knots, edges exact).
    pub fn tabulate(&self, e_max_kev: f64) -> Result<GridTransmission> {
        self.validate()?;
        let n = e_max_kev.ceil().max(1.0) as usize + 1;
        let interspace = if self.interspace == "air" {
            None
        } else {
            let m = material::by_name(&self.interspace)?;
            let knots = EnergyKnots::for_materials(&[&m], n)?;
            let table = InteractionTable::new(&m, &ScatterFactors::new(&m)?, &knots)?;
            Some((knots, table, m.density() / 10.0))
        };
        Ok(GridTransmission {
            open: self.open_fraction(),
            ratio: self.ratio,
            height_mm: self.height_mm(),
            interspace,
        })
    }
}

/// A grid ready to use: [`AntiScatterGrid`] with the interspace's attenuation tabulated.
#[derive(Debug, Clone, PartialEq)]
pub struct GridTransmission {
    open: f64,
    ratio: f64,
    height_mm: f64,
    /// The interspace's knots, interaction table and density / 10 (μ/ρ cm²/g × this = μ
    /// mm⁻¹); `None`: air, taken as transparent.
    interspace: Option<(EnergyKnots, InteractionTable, f64)>,
}

impl GridTransmission {
    /// Interspace μ at `e` keV, mm⁻¹.
    fn mu(&self, e: f64) -> f64 {
        self.interspace
            .as_ref()
            .map_or(0.0, |(k, t, scale)| t.at(k.locate(e), TOTAL) * scale)
    }

    /// Primary transmission Tp(E) (normal incidence along the focus).
    pub fn primary(&self, e_kev: f64) -> f64 {
        self.open * (-self.mu(e_kev) * self.height_mm).exp()
    }

    /// Transmission of a photon of `e_kev` arriving with slope `delta` across the strips
    /// (relative to the focused strip) and cosine `cos_normal` = |w·n̂| to the grid normal.
    pub fn at_slope(&self, delta: f64, cos_normal: f64, e_kev: f64) -> f64 {
        let c = cos_normal.abs();
        if c <= 1e-12 {
            return 0.0;
        }
        let geometric = (1.0 - self.ratio * delta.abs()).max(0.0);
        if geometric == 0.0 {
            return 0.0;
        }
        self.open * geometric * (-self.mu(e_kev) * self.height_mm / c).exp()
    }

    /// Transmission of a photon travelling along unit `w` to a grid point whose focused
    /// strip has slope `focus_slope` = (f·û)/(f·n̂); `u` and `n` are the detector's unit
    /// column axis and normal.
    pub fn towards(&self, w: DVec3, u: DVec3, n: DVec3, focus_slope: f64, e_kev: f64) -> f64 {
        let wn = w.dot(n);
        if wn.abs() <= 1e-12 {
            return 0.0;
        }
        self.at_slope(w.dot(u) / wn - focus_slope, wn, e_kev)
    }
}

/// The slope (f·û)/(f·n̂) of the focused strip at `point` for a source at `source`.
pub fn focus_slope(source: DVec3, point: DVec3, u: DVec3, n: DVec3) -> f64 {
    let f = point - source;
    f.dot(u) / f.dot(n)
}
