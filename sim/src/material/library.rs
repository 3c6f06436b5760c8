//! Named materials: compositions (mass fractions) and nominal densities.
//!
//! Tissues are ICRU Report 44 (1989) as tabulated in NIST's "X-Ray Mass Attenuation
//! Coefficients" (Hubbell & Seltzer, NISTIR 5632, Table 2); air, water, PMMA, CsI and Gd₂O₂S
//! are from the same table; pure elements use the density in `data/elements.csv`.

use super::{Material, element_by_name};
use crate::error::{Result, SimError};

/// Iodine concentration of the built-in `iodine-contrast` material, mg of iodine per ml.
pub const IODINE_CONTRAST_MG_PER_ML: f64 = 10.0;

/// Every name [`by_name`] accepts besides element symbols and names (aliases included).
pub const NAMES: &[&str] = &[
    "air",
    "lung",
    "adipose",
    "soft-tissue",
    "muscle",
    "blood",
    "cortical-bone",
    "water",
    "pmma",
    "aluminium",
    "al",
    "titanium",
    "ti",
    "copper",
    "cu",
    "tungsten",
    "w",
    "iodine-contrast",
    "csi",
    "cdte",
    "gos",
];

/// Water, Liquid (NIST Table 2): (Z, mass fraction).
const WATER: &[(u8, f64)] = &[(1, 0.111898), (8, 0.888102)];

/// (name, density g/cm³, [(Z, mass fraction)]) from NIST XAAMDI Table 2.
type Recipe = (&'static str, f64, &'static [(u8, f64)]);

const RECIPES: &[Recipe] = &[
    // Air, Dry (near sea level).
    (
        "air",
        1.205e-3,
        &[(6, 0.000124), (7, 0.755268), (8, 0.231781), (18, 0.012827)],
    ),
    // Lung Tissue (ICRU-44); density of inflated-lung tissue itself, not of the lung (which
    // CT sees at ~0.26 g/cm³: scale with `with_density`).
    (
        "lung",
        1.05,
        &[
            (1, 0.103),
            (6, 0.105),
            (7, 0.031),
            (8, 0.749),
            (11, 0.002),
            (15, 0.002),
            (16, 0.003),
            (17, 0.003),
            (19, 0.002),
        ],
    ),
    // Adipose Tissue (ICRU-44).
    (
        "adipose",
        0.95,
        &[
            (1, 0.114),
            (6, 0.598),
            (7, 0.007),
            (8, 0.278),
            (11, 0.001),
            (16, 0.001),
            (17, 0.001),
        ],
    ),
    // Tissue, Soft (ICRU-44).
    (
        "soft-tissue",
        1.06,
        &[
            (1, 0.102),
            (6, 0.143),
            (7, 0.034),
            (8, 0.708),
            (11, 0.002),
            (15, 0.003),
            (16, 0.003),
            (17, 0.002),
            (19, 0.003),
        ],
    ),
    // Muscle, Skeletal (ICRU-44).
    (
        "muscle",
        1.05,
        &[
            (1, 0.102),
            (6, 0.143),
            (7, 0.034),
            (8, 0.710),
            (11, 0.001),
            (15, 0.002),
            (16, 0.003),
            (17, 0.001),
            (19, 0.004),
        ],
    ),
    // Blood, Whole (ICRU-44).
    (
        "blood",
        1.06,
        &[
            (1, 0.102),
            (6, 0.110),
            (7, 0.033),
            (8, 0.745),
            (11, 0.001),
            (15, 0.001),
            (16, 0.002),
            (17, 0.003),
            (19, 0.002),
            (26, 0.001),
        ],
    ),
    // Bone, Cortical (ICRU-44).
    (
        "cortical-bone",
        1.92,
        &[
            (1, 0.034),
            (6, 0.155),
            (7, 0.042),
            (8, 0.435),
            (11, 0.001),
            (12, 0.002),
            (15, 0.103),
            (16, 0.003),
            (20, 0.225),
        ],
    ),
    // Water, Liquid.
    ("water", 1.0, WATER),
    // Polymethyl Methacrylate (Lucite, Perspex).
    ("pmma", 1.19, &[(1, 0.080541), (6, 0.599846), (8, 0.319613)]),
    // Cesium Iodide.
    ("csi", 4.51, &[(53, 0.488451), (55, 0.511549)]),
    // Cadmium Telluride (photon-counting sensors): stoichiometric CdTe from the atomic
    // masses Cd 112.41, Te 127.60; density 5.85 g/cm³.
    ("cdte", 5.85, &[(48, 0.468356), (52, 0.531644)]),
    // Gadolinium Oxysulfide, Gd2O2S.
    (
        "gos",
        7.44,
        &[(8, 0.084527), (16, 0.084704), (64, 0.830769)],
    ),
];

/// A named material. Case-insensitive; accepts the names in [`NAMES`] (ICRU-44 tissues,
/// NIST compounds, filter metals, scintillators, `iodine-contrast` =
/// [`iodine_contrast`]`(10 mg/ml)`) and any element symbol or English name ("Fe", "iron",
/// "gadolinium") at the element's natural density.
pub fn by_name(name: &str) -> Result<Material> {
    let key = name.trim().to_ascii_lowercase();
    let canonical = match key.as_str() {
        "al" | "aluminium" | "aluminum" => return named_element(13, "aluminium"),
        "ti" | "titanium" => return named_element(22, "titanium"),
        "cu" | "copper" => return named_element(29, "copper"),
        "w" | "tungsten" => return named_element(74, "tungsten"),
        "iodine-contrast" => return iodine_contrast(IODINE_CONTRAST_MG_PER_ML),
        "gd2o2s" => "gos",
        "soft tissue" | "tissue" => "soft-tissue",
        "bone" | "cortical bone" => "cortical-bone",
        k => k,
    };
    if let Some((n, d, comp)) = RECIPES.iter().find(|(n, _, _)| *n == canonical) {
        return Material::new(n, comp, *d);
    }
    match element_by_name(&key) {
        Ok(el) => Material::element(el.z),
        Err(_) => Err(SimError::UnknownMaterial(format!(
            "'{name}'; known materials: {}, or any element symbol or name (e.g. Fe, iron)",
            NAMES.join(", ")
        ))),
    }
}

fn named_element(z: u8, name: &str) -> Result<Material> {
    Material::element(z)?.renamed(name)
}

/// Iodinated contrast diluted in water at `mg_i_per_ml` milligrams of iodine per millilitre.
///
/// Model: the iodine adds mass to water without adding volume (the organic carrier of real
/// agents is neglected), so `ρ = 1.000 + c/1000` g/cm³ and the iodine mass fraction is
/// `(c/1000)/ρ`. Then `μ = μ_water + c·(μ/ρ)_I` exactly — the usual contrast-enhancement
/// model. At the built-in 10 mg/ml: ρ = 1.010 g/cm³, iodine fraction 0.990 %.
pub fn iodine_contrast(mg_i_per_ml: f64) -> Result<Material> {
    if !(mg_i_per_ml.is_finite() && mg_i_per_ml > 0.0 && mg_i_per_ml <= 400.0) {
        return Err(SimError::InvalidMaterial(format!(
            "iodine concentration {mg_i_per_ml} mg/ml must be in (0, 400]"
        )));
    }
    let c = mg_i_per_ml / 1000.0; // g/cm³
    let rho = 1.0 + c;
    let wi = c / rho;
    let mut comp: Vec<(u8, f64)> = WATER.iter().map(|&(z, w)| (z, w * (1.0 - wi))).collect();
    comp.push((53, wi));
    Material::new(&format!("iodine-contrast-{mg_i_per_ml}mg/ml"), &comp, rho)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_listed_name_resolves_and_published_fractions_sum_to_one() {
        for n in NAMES {
            let m = by_name(n).unwrap();
            assert!(m.density() > 0.0, "{n}");
        }
        for (n, _, comp) in RECIPES {
            let s: f64 = comp.iter().map(|c| c.1).sum();
            assert!((s - 1.0).abs() < 2e-6, "{n}: {s}");
        }
        assert_eq!(by_name("AL").unwrap().name(), "aluminium");
        assert_eq!(by_name("Fe").unwrap().composition(), &[(26, 1.0)]);
        assert_eq!(by_name("Gd2O2S").unwrap().name(), "gos");
    }

    #[test]
    fn unknown_name_lists_the_known_ones() {
        let e = by_name("kryptonite").unwrap_err().to_string();
        assert!(e.contains("kryptonite") && e.contains("cortical-bone") && e.contains("gos"));
    }

    #[test]
    fn iodine_contrast_is_water_plus_concentration_times_iodine() {
        let c = 10.0;
        let m = iodine_contrast(c).unwrap();
        let w = by_name("water").unwrap();
        let i = by_name("I").unwrap();
        for e in [30.0, 33.5, 70.0] {
            let mu = m.mu_per_mm(e, m.density()).unwrap();
            let expect =
                w.mu_per_mm(e, 1.0).unwrap() + i.mass_attenuation(e).unwrap() * c / 1000.0 / 10.0;
            assert!((mu / expect - 1.0).abs() < 1e-9, "{e}: {mu} vs {expect}");
        }
        assert!(iodine_contrast(0.0).is_err());
        assert!(iodine_contrast(f64::NAN).is_err());
    }
}
