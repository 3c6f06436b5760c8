//! The input volume: a NIfTI file, a DICOM series or the built-in phantom, as mu or HU.

use crate::Scene;
use anyhow::{Result, bail};
use glam::DVec3;
use tomograf_sim::Volume;
use tomograf_sim::attenuation::Attenuation;
use tomograf_sim::phantom::Phantom;

/// Default grid of the built-in phantom when rendered directly: 256 × 256 × 133 voxels of
/// 1.4 × 1.4 × 2.5 mm (a chest CT's field of view at half its in-plane resolution).
pub const PHANTOM_DIMS: [usize; 3] = [256, 256, 133];
/// See [`PHANTOM_DIMS`].
pub const PHANTOM_SPACING: [f64; 3] = [1.4, 1.4, 2.5];

/// The built-in thorax phantom on a grid centred at the world origin, in HU.
pub fn phantom_volume(dims: [usize; 3], spacing: [f64; 3]) -> Result<Volume> {
    Ok(Phantom::thorax().voxelize(dims, DVec3::from(spacing), DVec3::ZERO)?)
}

/// Where the volume came from and its grid, as the sidecar records it.
pub use tomograf_datasets::sidecar::VolumeRecord as VolumeSource;

/// Effective energy (keV) of the HU → mu conversion of the ideal DRR when none is given.
pub const DEFAULT_ENERGY_KEV: f64 = 60.0;

/// Loads the input volume (or phantom) and converts it to mu (mm⁻¹).
pub fn load_mu(scene: &Scene) -> Result<(Volume, VolumeSource)> {
    load(scene, None)
}

/// Loads the input volume (or phantom) in HU, for real detector physics whose tissue
/// model is calibrated at `calibration_kev` (recorded as the volume's HU → mu energy).
pub fn load_hu(scene: &Scene, calibration_kev: f64) -> Result<(Volume, VolumeSource)> {
    load(scene, Some(calibration_kev))
}

/// Loads the input; converts HU to mu unless `keep_hu` (the calibration energy) is given.
fn load(scene: &Scene, keep_hu: Option<f64>) -> Result<(Volume, VolumeSource)> {
    let v = &scene.volume;
    let units = v
        .units
        .clone()
        .unwrap_or_else(|| "hu".into())
        .to_ascii_lowercase();
    if let Some(p) = &v.path
        && (v.phantom_dims.is_some() || v.phantom_spacing_mm.is_some())
    {
        bail!(
            "[volume] phantom_dims and phantom_spacing_mm (--phantom-dims, --phantom-spacing) \
             are for the built-in phantom; the input {} \
             has its own grid (resample it first, or drop the input)",
            p.display()
        );
    }
    // An ideal DRR of a CT file in HU: converted to mu while the file is read.
    let read_as_mu = (units == "hu" && keep_hu.is_none() && v.path.is_some())
        .then(|| Attenuation::hounsfield_at_kev(v.energy_kev.unwrap_or(DEFAULT_ENERGY_KEV)))
        .transpose()?;
    let allow_non_ct = v.allow_non_ct.unwrap_or(false);
    let (mut vol, phantom) = match (&v.path, &read_as_mu) {
        (Some(p), Some(att)) => (load_volume_file_as_mu(p, allow_non_ct, att)?, None),
        (Some(p), None) => (load_volume_file(p, allow_non_ct)?, None),
        (None, _) => (
            phantom_volume(
                v.phantom_dims.unwrap_or(PHANTOM_DIMS),
                v.phantom_spacing_mm.unwrap_or(PHANTOM_SPACING),
            )?,
            Some("thorax".to_string()),
        ),
    };
    let attenuation = match (units.as_str(), keep_hu) {
        ("hu", Some(e)) => {
            if v.energy_kev.is_some() {
                bail!(
                    "[volume] energy_kev (--energy-kev) is the monochromatic DRR's energy; with \
                     a spectrum the CT's \
                     energy is [materials] calibration_kev"
                );
            }
            Attenuation::hounsfield_at_kev(e)?
        }
        ("mu", Some(e)) => {
            // Tissues are classified by CT number: a mu volume is read as HU at the energy
            // its values hold at, HU = 1000·(μ/μ_water(E) − 1).
            let Some(at) = v.energy_kev else {
                bail!(
                    "real detector physics classifies tissues by CT number, and a volume in mu \
                     (mm⁻¹) has none: give the effective energy its values hold at ([volume] \
                     energy_kev or --energy-kev, keV), and it is read as HU = 1000·(μ/μ_water(E) \
                     − 1); or give the CT in HU (--units hu)"
                );
            };
            let mu_w = tomograf_sim::attenuation::mu_water_per_mm(at)?;
            if vol
                .first_voxel_where(|m| !(m.is_finite() && m >= 0.0))
                .is_some()
            {
                bail!("a volume in mu (mm⁻¹) must hold finite values ≥ 0");
            }
            vol = vol.map_in_place(|m| tomograf_sim::attenuation::mu_to_hu(m, mu_w))?;
            Attenuation::hounsfield_at_kev(e)?
        }
        (other, Some(_)) => bail!("unknown units '{other}': use hu (Hounsfield) or mu (mm⁻¹)"),
        ("hu", None) => match read_as_mu {
            Some(att) => att,
            None => Attenuation::hounsfield_at_kev(v.energy_kev.unwrap_or(DEFAULT_ENERGY_KEV))?,
        },
        ("mu", None) => {
            if v.energy_kev.is_some() {
                bail!(
                    "[volume] energy_kev (--energy-kev) only applies to HU input (units = \"hu\", --units hu)"
                );
            }
            Attenuation::LinearPerMm
        }
        (other, None) => bail!("unknown units '{other}': use hu (Hounsfield) or mu (mm⁻¹)"),
    };
    let mu = match (keep_hu, &read_as_mu) {
        (Some(_), _) | (None, Some(_)) => vol,
        (None, None) => attenuation.to_mu(vol)?,
    };
    let source = record(&mu, v.path.clone(), phantom, units, attenuation);
    Ok((mu, source))
}

/// What the sidecar records of a loaded `volume`: where it came from (`path` or the
/// built-in `phantom`; neither for a CT given in memory), its units, how they became mu,
/// and its grid.
pub(crate) fn record(
    volume: &Volume,
    path: Option<std::path::PathBuf>,
    phantom: Option<String>,
    units: String,
    attenuation: Attenuation,
) -> VolumeSource {
    let d = volume.direction();
    VolumeSource {
        path,
        phantom,
        units,
        attenuation,
        dims: volume.dims(),
        spacing_mm: volume.spacing().to_array(),
        origin_mm: volume.origin().to_array(),
        direction: [
            d.x_axis.to_array(),
            d.y_axis.to_array(),
            d.z_axis.to_array(),
        ],
    }
}

/// As [`load_volume_file`], converted to mu by `attenuation`: a NIfTI file in the pass that
/// decodes it (one pass over the volume fewer; docs/datasets.md, "Loading speed"), a DICOM
/// series afterwards. The same values either way.
fn load_volume_file_as_mu(
    path: &std::path::Path,
    allow_non_ct: bool,
    attenuation: &Attenuation,
) -> Result<Volume> {
    if let (true, Some(convert)) = (is_nifti(path), attenuation.per_voxel()?) {
        return Ok(tomograf_datasets::nifti::read_nifti_mapped(path, convert)?);
    }
    Ok(attenuation.to_mu(load_volume_file(path, allow_non_ct)?)?)
}

fn is_nifti(path: &std::path::Path) -> bool {
    let name = path.to_string_lossy().to_ascii_lowercase();
    !path.is_dir() && (name.ends_with(".nii") || name.ends_with(".nii.gz"))
}

/// Whether `path` names an NRRD volume (`.nrrd`, or a detached header `.nhdr`).
pub fn is_nrrd(path: &std::path::Path) -> bool {
    let name = path.to_string_lossy().to_ascii_lowercase();
    !path.is_dir() && (name.ends_with(".nrrd") || name.ends_with(".nhdr"))
}

/// Reads a CT volume: a NIfTI or NRRD file, or a folder holding one DICOM series.
pub fn load_volume_file(path: &std::path::Path, allow_non_ct: bool) -> Result<Volume> {
    if path.is_dir() {
        Ok(tomograf_datasets::dicom::read_dicom_series(
            path,
            allow_non_ct,
        )?)
    } else if is_nifti(path) {
        Ok(tomograf_datasets::nifti::read_nifti(path)?)
    } else if is_nrrd(path) {
        Ok(tomograf_datasets::nrrd::read_nrrd(path)?)
    } else {
        bail!(
            "cannot read {}: give a NIfTI volume (.nii, .nii.gz), an NRRD volume (.nrrd, \
             .nhdr) or a folder holding one DICOM series",
            path.display()
        )
    }
}
