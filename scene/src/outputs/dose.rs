//! The files of the scene's `[dose]` table ([`crate::dose`]): the absorbed dose the acquisition delivers to the CT,
//! written beside the images as `{prefix}_dose.nii.gz` (Gy, the CT's grid, all views) and
//! `{prefix}_dose.json` (per view: energy imparted and source photons; totals).
//! The Monte Carlo is `tomograf_physics::scatter::dose` (docs/scatter.md, "Dose").

use super::Outputs;
use crate::dose::DoseSection;
use crate::progress::Progress;
use anyhow::{Context, Result, bail};

use std::io::Write as _;
use tomograf_datasets::atomic::write_atomic;
use tomograf_datasets::nifti::write_nifti;
use tomograf_physics::acquisition::Acquisition;
use tomograf_sim::geometry::View;
use tomograf_sim::volume::Volume;

/// Runs the dose Monte Carlo for `views` of the CT `hu` (HU) and writes its files; returns
/// how many files were written.
pub fn write(
    section: &DoseSection,
    acquisition: Option<&(Acquisition, u64)>,
    hu: &Volume,
    views: &[View],
    outputs: &Outputs,
    progress: &dyn Progress,
) -> Result<usize> {
    let Some((acq, seed)) = acquisition else {
        bail!("[dose] needs real detector physics (an [acquisition] preset or a [spectrum])");
    };
    let photons = section.photons();
    progress.note(&format!(
        "dose: {photons} histories per view × {} view(s) …",
        views.len()
    ));
    let dose = acq
        .dose(hu, views, photons, *seed)
        .context("[dose] Monte Carlo")?;
    let nii = outputs.dir.join(format!("{}_dose.nii.gz", outputs.prefix));
    write_nifti(&nii, &dose.gray).with_context(|| format!("writing {}", nii.display()))?;
    let gy = dose.gray.data();
    let max = gy.iter().copied().fold(0.0f32, f32::max);
    let json = serde_json::json!({
        "quantity": "absorbed dose, Gy, summed over the views (photon transport with local \
                     deposition of electron energy; no electron transport)",
        "file": nii.file_name().map(|n| n.to_string_lossy().into_owned()),
        "photons_per_view": photons,
        "mas_per_view": acq.spectrum.mas,
        "seed": seed,
        "max_gy": max,
        "max_gy_per_mas": f64::from(max) / (acq.spectrum.mas * views.len() as f64),
        "energy_imparted_joule": dose.energy_joule,
        "views": dose.per_view.iter().zip(&dose.source_photons).map(|(e, n)| serde_json::json!({
            "source_photons": n,
            "energy_imparted_ev_per_photon": e.ev_per_photon,
            "standard_error_ev_per_photon": e.standard_error,
        })).collect::<Vec<_>>(),
    });
    let path = outputs.dir.join(format!("{}_dose.json", outputs.prefix));
    let text = serde_json::to_string_pretty(&json)?;
    write_atomic(&path, |w| w.write_all(text.as_bytes()))?;
    progress.note(&format!(
        "dose: {:.3e} J imparted, max {:.3e} Gy → {}",
        dose.energy_joule,
        max,
        nii.display()
    ));
    Ok(2)
}
