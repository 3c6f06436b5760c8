//! The settings a search tries ([`Grid::candidates`]), and which of them lie on its edge.

use super::settings::{FDK, PCA_MAP, SART_TV, SART_TV_FROM_MEAN, TOMOGRAF};
use serde::{Deserialize, Serialize};
use tomograf_model::baseline::SartTvSettings;
use tomograf_model::pca::PcaSettings;
use tomograf_recon::Window;

/// One setting of one method.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Candidate {
    SartTv(SartTvSettings),
    SartTvFromMean(SartTvSettings),
    PcaMap(PcaSettings),
    Fdk(Window),
    /// TomoGRAF's data-consistency sweeps after its network (the network itself is the
    /// checkpoint's and is run once per item and view count).
    Tomograf(SartTvSettings),
}

impl Candidate {
    /// The method's name in the evaluation tables.
    pub fn method(&self) -> &'static str {
        match self {
            Self::SartTv(_) => SART_TV,
            Self::SartTvFromMean(_) => SART_TV_FROM_MEAN,
            Self::PcaMap(_) => PCA_MAP,
            Self::Fdk(_) => FDK,
            Self::Tomograf(_) => TOMOGRAF,
        }
    }

    /// The setting, in words (no commas: it is a CSV field).
    pub fn setting(&self) -> String {
        match self {
            Self::SartTv(s) | Self::SartTvFromMean(s) | Self::Tomograf(s) => {
                format!("{} sweeps; TV step {}", s.sweeps, s.tv_step)
            }
            Self::PcaMap(p) => format!(
                "noise {}; {} components",
                p.noise,
                p.components.map_or("all".to_string(), |c| c.to_string())
            ),
            Self::Fdk(w) => format!("{w:?} window"),
        }
    }
}

/// Which grid a search runs.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Grid {
    /// Sweeps {5, 10, 20, 40, 80} × TV step {0, 0.1, 0.2, 0.4, 0.8} (SART-TV from zero and
    /// from the mean; TomoGRAF's sweeps); PCA-MAP's noise {0.1, 0.3, 1, 3, 10, 30, 100} % ×
    /// the first {4, 8, 16, all} components; FDK's four ramp windows.
    #[default]
    Full,
    /// A smoke test of the search (the studies' `tiny` scale): sweeps {5, 20} × TV step
    /// {0, 0.2}, noise {1, 30} % with every component, the Ram-Lak and Hann windows.
    Smoke,
}

/// The axes of a grid.
struct Axes {
    sweeps: &'static [usize],
    tv_steps: &'static [f64],
    noises: &'static [f64],
    components: &'static [Option<usize>],
    windows: &'static [Window],
}

const FULL: Axes = Axes {
    sweeps: &[5, 10, 20, 40, 80],
    tv_steps: &[0.0, 0.1, 0.2, 0.4, 0.8],
    noises: &[0.001, 0.003, 0.01, 0.03, 0.1, 0.3, 1.0],
    components: &[Some(4), Some(8), Some(16), None],
    windows: &[
        Window::RamLak,
        Window::SheppLogan,
        Window::Cosine,
        Window::Hann,
    ],
};

const SMOKE: Axes = Axes {
    sweeps: &[5, 20],
    tv_steps: &[0.0, 0.2],
    noises: &[0.01, 0.3],
    components: &[None],
    windows: &[Window::RamLak, Window::Hann],
};

impl Grid {
    fn axes(self) -> &'static Axes {
        match self {
            Self::Full => &FULL,
            Self::Smoke => &SMOKE,
        }
    }

    /// Every candidate, in the search's order; TomoGRAF's sweeps too when `model` (a
    /// checkpoint is searched with the baselines). The defaults (20 sweeps, TV step 0.2;
    /// noise 1 %, all components; Ram-Lak) are on every grid.
    pub fn candidates(self, model: bool) -> Vec<Candidate> {
        let a = self.axes();
        let mut out = Vec::new();
        for &sweeps in a.sweeps {
            for &tv_step in a.tv_steps {
                let s = SartTvSettings { sweeps, tv_step };
                out.push(Candidate::SartTv(s));
                out.push(Candidate::SartTvFromMean(s));
                if model {
                    out.push(Candidate::Tomograf(s));
                }
            }
        }
        for &noise in a.noises {
            for &components in a.components {
                out.push(Candidate::PcaMap(PcaSettings { noise, components }));
            }
        }
        out.extend(a.windows.iter().map(|&w| Candidate::Fdk(w)));
        out
    }

    /// Whether `c` lies on an open edge of this grid (the most sweeps, the largest TV step,
    /// the smallest or largest noise): a winner there may have a better setting beyond it.
    pub fn on_edge(self, c: &Candidate) -> bool {
        let a = self.axes();
        let last = |v: &[f64], x: f64| v.last() == Some(&x);
        match c {
            Candidate::SartTv(s) | Candidate::SartTvFromMean(s) | Candidate::Tomograf(s) => {
                a.sweeps.last() == Some(&s.sweeps) || last(a.tv_steps, s.tv_step)
            }
            Candidate::PcaMap(p) => a.noises.first() == Some(&p.noise) || last(a.noises, p.noise),
            Candidate::Fdk(_) => false,
        }
    }
}
