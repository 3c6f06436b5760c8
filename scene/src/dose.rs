//! The scene's `[dose]` table: the absorbed dose the acquisition delivers to the CT
//! (`tomograf_physics::scatter::dose`, docs/scatter.md, "Dose").

use anyhow::{Result, bail};
use serde::{Deserialize, Serialize};
use tomograf_physics::acquisition::Acquisition;
use tomograf_physics::scatter::dose::DEFAULT_DOSE_PHOTONS;
/// `[dose]`: photon histories per view (default 1 000 000).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DoseSection {
    /// Monte Carlo histories per view.
    pub photons: Option<u64>,
}

impl DoseSection {
    /// Histories per view.
    pub fn photons(&self) -> u64 {
        self.photons.unwrap_or(DEFAULT_DOSE_PHOTONS)
    }
}

/// Checks before any rendering that the scene can have a dose.
pub fn check(
    section: &DoseSection,
    acquisition: Option<&(Acquisition, u64)>,
    meshes: bool,
) -> Result<()> {
    if acquisition.is_none() {
        bail!(
            "[dose] needs real detector physics (an [acquisition] preset or a [spectrum]): the \
             ideal DRR has no spectrum or exposure to deliver a dose"
        );
    }
    if meshes {
        bail!("[dose] with mesh objects is not modelled (the Monte Carlo medium is the voxel CT)");
    }
    let n = section.photons();
    if !(1..=tomograf_physics::scatter::MAX_PHOTONS).contains(&n) {
        bail!(
            "[dose] photons = {n}; give 1 to {}",
            tomograf_physics::scatter::MAX_PHOTONS
        );
    }
    Ok(())
}
