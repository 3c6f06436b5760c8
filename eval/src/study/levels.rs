//! The data sets the studies are made of: realism levels (the same phantoms through ever
//! more realistic physics) and domain shifts (other patients, hardware or exposure).

use anyhow::{Result, bail};
use std::path::PathBuf;
use tomograf_model::scatter_correction::ScatterCorrection;
use tomograf_scene::overrides::PhysicsOverrides;

/// One data set a study trains or tests on: a phantom population and a physics.
#[derive(Debug, Clone)]
pub struct DataSpec {
    /// Folder name and table label.
    pub name: &'static str,
    /// What it contains, for the report.
    pub about: &'static str,
    /// Phantom profile: `lidc` or `full-chest`.
    pub profile: &'static str,
    pub table: bool,
    pub pacemaker: bool,
    /// Detector physics (ideal DRR when empty).
    pub physics: PhysicsOverrides,
    /// A test set that evaluates another set's data (its folder name) differently: with
    /// `correction`, and no data of its own.
    pub data_of: Option<&'static str>,
    /// The scatter correction every method's views get before reconstruction.
    pub correction: ScatterCorrection,
    /// The user's CTs (NIfTI files or DICOM series folders) instead of phantoms: the
    /// population, in this order; empty for phantoms of `profile`.
    pub cts: Vec<PathBuf>,
}

impl DataSpec {
    fn lidc(name: &'static str, about: &'static str, physics: PhysicsOverrides) -> Self {
        Self {
            name,
            about,
            profile: "lidc",
            table: false,
            pacemaker: false,
            physics,
            data_of: None,
            correction: ScatterCorrection::None,
            cts: Vec::new(),
        }
    }

    /// The same set made of `cts` instead of phantoms (unchanged when `cts` is empty).
    pub fn with_cts(mut self, cts: &[PathBuf]) -> Self {
        if !cts.is_empty() {
            self.cts = cts.to_vec();
        }
        self
    }

    /// Who is in the set, for the report: "lidc phantoms", "3 CTs (a.nii.gz, …)".
    pub fn population(&self) -> String {
        if self.cts.is_empty() {
            return format!("{} phantoms", self.profile);
        }
        let names: Vec<String> = self
            .cts
            .iter()
            .take(3)
            .map(|p| {
                p.file_name()
                    .unwrap_or(p.as_os_str())
                    .to_string_lossy()
                    .into_owned()
            })
            .collect();
        let more = if self.cts.len() > 3 { ", …" } else { "" };
        format!("{} CT(s): {}{more}", self.cts.len(), names.join(", "))
    }

    /// The folder name of the data this set evaluates.
    pub fn data_name(&self) -> &'static str {
        self.data_of.unwrap_or(self.name)
    }

    /// Whether the physics is real (a spectrum and a detector; it then takes a noise seed).
    pub fn real_physics(&self) -> bool {
        self.physics.preset.is_some() || self.physics.kvp.is_some()
    }
}

/// The 120 kVp chest-radiography preset, with `detector` replacing its flat panel.
fn kv(
    detector: Option<&str>,
    scatter: Option<&str>,
    scatter_photons: Option<u64>,
) -> PhysicsOverrides {
    PhysicsOverrides {
        preset: Some("kv-flat-panel-120kvp".into()),
        detector_model: detector.map(str::to_string),
        scatter: scatter.map(str::to_string),
        scatter_photons,
        ..PhysicsOverrides::default()
    }
}

/// The realism levels: lidc phantoms through
/// 1. `ideal-drr` — the monochromatic line integral at 60 keV (what DRR-trained networks see);
/// 2. `polychromatic` — the 120 kVp spectrum (2.5 mm Al + 0.1 mm Cu) through Schneider
///    tissues, an ideal detector (no noise, no blur): beam hardening only;
/// 3. `noise-blur` — the same beam on the indirect CsI flat panel: quantum and electronic
///    noise, light spread, gain and offset maps, flat-field corrected (the preset itself);
/// 4. `scatter` — level 3 plus the fast scatter estimate (`scatter_photons` histories/view).
pub fn realism_levels(scatter_photons: u64) -> Vec<DataSpec> {
    vec![
        DataSpec::lidc(
            "ideal-drr",
            "ideal DRR: monochromatic line integrals at 60 keV, exact Siddon",
            PhysicsOverrides::default(),
        ),
        DataSpec::lidc(
            "polychromatic",
            "120 kVp tungsten spectrum (2.5 mm Al + 0.1 mm Cu), Schneider tissues, ideal \
             detector (no noise, no blur), −log of the flat-field-corrected signal",
            kv(Some("ideal"), None, None),
        ),
        DataSpec::lidc(
            "noise-blur",
            "preset kv-flat-panel-120kvp: the same beam, 1 mAs, indirect CsI flat panel with \
             quantum and electronic noise, light spread, gain/offset maps, flat-field corrected",
            kv(None, None, None),
        ),
        DataSpec::lidc(
            "scatter",
            "as noise-blur plus scattered radiation (fast estimate: coarse Monte Carlo, smoothed)",
            kv(None, Some("estimate"), Some(scatter_photons)),
        ),
    ]
}

/// The realism-gap study's test sets: the levels, and — when `scatter` is among them —
/// `scatter-corrected`, the `scatter` test data with every method's views corrected for
/// scatter from the mean training volume (`tomograf evaluate --scatter-correction prior`).
pub fn realism_test_sets(levels: &[DataSpec]) -> Vec<DataSpec> {
    let mut out = levels.to_vec();
    if let Some(s) = levels.iter().find(|s| s.name == "scatter") {
        out.push(DataSpec {
            name: "scatter-corrected",
            about: "the scatter test data, every method's views corrected for scatter first: a \
                    Monte Carlo scatter-to-primary estimate through the mean training volume \
                    with the acquisition's own physics",
            data_of: Some("scatter"),
            correction: ScatterCorrection::Prior,
            ..s.clone()
        });
    }
    out
}

/// The domain-shift study's training set: lidc phantoms, preset kv-flat-panel-120kvp.
pub fn shift_training() -> DataSpec {
    DataSpec::lidc(
        "lidc",
        "lidc phantoms (cropped thorax), preset kv-flat-panel-120kvp (120 kVp, 1 mAs, CsI panel)",
        kv(None, None, None),
    )
}

/// The name of the domain-shift test set made of the user's CTs.
pub const USER_CT: &str = "user-ct";

/// The domain-shift test set of the user's `cts`: the training physics on real anatomy.
pub fn user_ct_shift(cts: &[PathBuf]) -> DataSpec {
    DataSpec {
        name: USER_CT,
        about: "the user's CTs (into the patient frame, the body alone), the training physics",
        ..shift_training().with_cts(cts)
    }
}

/// The domain-shift test sets: one change each from the training set, and the paper's
/// in-house setting (all anatomy changes at once).
pub fn shifts() -> Vec<DataSpec> {
    let base = shift_training();
    let with = |name, about, f: &dyn Fn(&mut DataSpec)| {
        let mut s = base.clone();
        s.name = name;
        s.about = about;
        f(&mut s);
        s
    };
    vec![
        with(
            "lidc",
            "held-out phantoms of the training population",
            &|_| {},
        ),
        with(
            "full-chest",
            "full chest: arms, neck, whole chest wall",
            &|s| s.profile = "full-chest",
        ),
        with("table", "lidc on a patient table", &|s| s.table = true),
        with("pacemaker", "lidc with a pacemaker and leads", &|s| {
            s.pacemaker = true
        }),
        with(
            "paper-in-house",
            "full chest on a table with a pacemaker (the paper's in-house test set)",
            &|s| {
                s.profile = "full-chest";
                s.table = true;
                s.pacemaker = true
            },
        ),
        with(
            "kvp-80",
            "80 kVp instead of 120 kVp (same filtration, 1 mAs)",
            &|s| s.physics.kvp = Some(80.0),
        ),
        with(
            "low-mas",
            "0.001 mAs instead of 1 mAs: 1000× fewer photons, more noise",
            &|s| s.physics.mas = Some(0.005),
        ),
        with("starved", "0.0001 mAs instead of 1 mAs", &|s| {
            s.physics.mas = Some(0.001)
        }),
    ]
}

/// The specs named in `only` (all when empty), in their order; errors naming an unknown
/// name and listing the known ones.
pub fn select(all: Vec<DataSpec>, only: &[String], what: &str) -> Result<Vec<DataSpec>> {
    if only.is_empty() {
        return Ok(all);
    }
    for n in only {
        if !all.iter().any(|s| s.name == n) {
            let names: Vec<&str> = all.iter().map(|s| s.name).collect();
            bail!("unknown {what} '{n}': choose from {}", names.join(", "));
        }
    }
    Ok(all
        .into_iter()
        .filter(|s| only.iter().any(|n| n == s.name))
        .collect())
}
