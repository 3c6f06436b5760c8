//! Scatter correction of a data-set item's −log projections before any method sees them.
//!
//! A network trained on ideal DRRs, PCA-MAP and SART-TV all fit their volume to the views;
//! scatter lowers the views' line integrals behind the patient, so every one of them
//! reconstructs too little attenuation (docs/studies.md: 6 dB lost on `scatter` test data).
//! The standard remedy in cone-beam CT is a Monte Carlo scatter estimate from a prior
//! object: here the item's own acquisition (spectrum, tissues, detector, scatter model, as
//! recorded in `item.json`) is run through an estimate of the patient and each view is
//! corrected by its scatter-to-primary ratio
//! ([`tomograf_recon::scatter_correction`]). The estimate is
//! * [`ScatterCorrection::Prior`] — the mean training volume: what a method knows before
//!   it sees the patient (fair to every method, since all of them get the same corrected
//!   views);
//! * [`ScatterCorrection::Oracle`] — the item's ground-truth CT: the best a correction can
//!   do, to tell the correction's error from a method's (not a method: it uses the answer).

use crate::data::Item;
use crate::error::{ModelError, Result, ensure};
use serde::{Deserialize, Serialize};
use tomograf_physics::acquisition::Acquisition;
use tomograf_recon::scatter_correction::{correct_log, scatter_to_primary};
use tomograf_sim::Volume;

/// Where the object estimate of a scatter correction comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum ScatterCorrection {
    /// No correction: the views as recorded (default).
    #[default]
    None,
    /// Estimate from the mean training volume.
    Prior,
    /// Estimate from the ground truth (an upper bound, not a method).
    Oracle,
}

impl std::str::FromStr for ScatterCorrection {
    type Err = ModelError;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "none" => Ok(Self::None),
            "prior" => Ok(Self::Prior),
            "oracle" => Ok(Self::Oracle),
            _ => Err(ModelError::Invalid(format!(
                "scatter correction '{s}': expected 'none', 'prior' or 'oracle'"
            ))),
        }
    }
}

impl std::fmt::Display for ScatterCorrection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::None => "none",
            Self::Prior => "prior",
            Self::Oracle => "oracle",
        })
    }
}

/// The acquisition `item`'s views were recorded with, when it models scatter; otherwise an
/// error saying why there is nothing to correct.
pub fn correctable(item: &Item) -> Result<&Acquisition> {
    let acquisition = item.acquisition.as_ref().ok_or_else(|| {
        ModelError::Invalid(format!(
            "item {}: scatter correction needs the acquisition the views were recorded with, \
             and its item.json has none (an ideal-DRR data set has no scatter to correct)",
            item.id
        ))
    })?;
    ensure!(
        !acquisition.scatter.is_none(),
        "item {}: its acquisition models no scatter, so there is none to correct",
        item.id
    );
    Ok(acquisition)
}

/// `item` with the projections at `indices` corrected for scatter through `estimate` (the
/// normalised density on the item's grid, as its `ct.nii.gz` holds it), using the item's
/// recorded acquisition; the other projections are left as they are. `seed` seeds the
/// estimate's Monte Carlo (view `i` uses stream `i`, so the result does not depend on which
/// other views are corrected). Errors when the item has no acquisition with scatter.
pub fn correct_item(item: &Item, estimate: &Volume, indices: &[usize], seed: u64) -> Result<Item> {
    let acquisition = correctable(item)?;
    if let Some(ct) = &item.ct {
        ensure!(
            ct.dims() == estimate.dims(),
            "item {}: the scatter estimate's grid is {:?} but the item's CT is {:?}",
            item.id,
            estimate.dims(),
            ct.dims()
        );
    }
    let hu = item
        .window
        .denormalize(estimate)
        .map_err(|e| ModelError::Invalid(format!("item {}: {e}", item.id)))?;
    let prepared = acquisition.prepare(&hu, seed)?;
    let mut out = item.clone();
    let n = item.rows * item.cols;
    for &i in indices {
        ensure!(
            i < item.views.len(),
            "item {}: view {i} does not exist (it has {})",
            item.id,
            item.views.len()
        );
        let spr = scatter_to_primary(&prepared, &item.views[i], i)?;
        correct_log(&mut out.projections[i * n..(i + 1) * n], &spr)?;
    }
    Ok(out)
}
