//! The public description of a phantom: profile, spec, the sampled patient and the
//! labelled result.

use super::{Structure, Tissue};
use crate::error::{DatasetError, Result};
use serde::{Deserialize, Serialize};
use tomograf_sim::Volume;

/// Which population the phantom imitates (the paper's domain shift: LIDC-IDRI training CTs
/// are cropped to the thorax; the in-house test CTs show the whole chest with arms, neck
/// and chest wall).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Profile {
    /// Field of view cropped to the thorax (lung apex to diaphragm), no arms, no neck.
    LidcCropped,
    /// The whole chest with arms, shoulders, neck and the complete chest wall.
    FullChest,
}

impl Profile {
    /// Parses `"lidc"`, `"lidc-cropped"` or `"full-chest"` (case-insensitive).
    pub fn parse(s: &str) -> Result<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "lidc" | "lidc-cropped" => Ok(Profile::LidcCropped),
            "full-chest" => Ok(Profile::FullChest),
            other => Err(DatasetError::Invalid(format!(
                "unknown anatomy profile '{other}': expected lidc, lidc-cropped or full-chest"
            ))),
        }
    }
}

/// Where the arms are ([`Profile::FullChest`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ArmPose {
    /// Upper arms beside the chest.
    Down,
    /// Arms raised beside the head.
    Raised,
}

/// What to generate.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct AnatomySpec {
    /// Seed of the patient: anatomy, variation and texture.
    pub seed: u64,
    /// Population imitated.
    pub profile: Profile,
    /// Add a patient table under the patient's back (+y).
    pub table: bool,
    /// Add a pacemaker in the left upper chest with leads into the heart.
    pub pacemaker: bool,
    /// Voxels along x, y, z.
    pub dims: [usize; 3],
    /// Voxel size along x, y, z in mm.
    pub spacing_mm: [f64; 3],
    /// Standard deviation (HU) of a spatially correlated texture added to muscle, organs,
    /// blood and myocardium ([`super::heterogeneity`]); 0: none (the default, and every spec
    /// written before it existed).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub heterogeneity_hu: f64,
    /// How many times wider than drawn the ranges of the heart's size (0.88–1.15 ×),
    /// offset (±8 mm left–right, 0–12 mm anterior–posterior, ±10 mm along z, × the size
    /// factor) and turn (±0.15 rad), and of the diaphragm domes' heights (0.27–0.35 of the
    /// lungs' height, ±8 mm, the left dome 8–22 mm below the right) are, about their
    /// centres: a population whose organs the views of a prior trained at 1 under-determine
    /// (a large heart, a high liver dome). 1: as drawn (the default, and every spec written
    /// before it existed); 0: every patient's organs at the ranges' centres; at most
    /// [`MAX_ORGAN_SPREAD`](super::MAX_ORGAN_SPREAD). Widened domes are kept 25 mm to 0.45
    /// of the lungs' height above their base.
    #[serde(
        default = "default_organ_spread",
        skip_serializing_if = "is_default_organ_spread"
    )]
    pub organ_spread: f64,
    /// Standard deviation (mm, per component) of a smooth random displacement field the
    /// rendered phantom is warped by ([`super::deform`]: a 64 mm lattice): shapes the
    /// generator cannot draw. 0: none (the default, and every spec written before it
    /// existed); at most [`MAX_DEFORM_MM`](super::deform::MAX_DEFORM_MM).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub deform_mm: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}
fn default_organ_spread() -> f64 {
    1.0
}
fn is_default_organ_spread(v: &f64) -> bool {
    *v == 1.0
}

impl AnatomySpec {
    /// A spec without table and pacemaker.
    pub fn new(seed: u64, profile: Profile, dims: [usize; 3], spacing_mm: [f64; 3]) -> Self {
        Self {
            seed,
            profile,
            table: false,
            pacemaker: false,
            dims,
            spacing_mm,
            heterogeneity_hu: 0.0,
            organ_spread: 1.0,
            deform_mm: 0.0,
        }
    }
}

/// A lung nodule of the phantom (ground truth for detection).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NoduleInfo {
    /// Centre, world LPS mm.
    pub centre_mm: [f64; 3],
    /// Mean diameter, mm (3–30).
    pub diameter_mm: f64,
    /// Mean HU (0–100).
    pub hu: f64,
}

/// The LidcCropped field of view.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FieldOfView {
    /// Lowest z (mm) inside the field of view.
    pub z_min_mm: f64,
    /// Highest z (mm) inside the field of view.
    pub z_max_mm: f64,
    /// Radius (mm) of the circular in-plane field of view around the z axis.
    pub radius_mm: f64,
}

/// The sampled patient: sizes and landmarks, world LPS mm.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Patient {
    /// Seed.
    pub seed: u64,
    /// Profile.
    pub profile: Profile,
    /// Lateral width of the chest, skin to skin.
    pub width_mm: f64,
    /// Antero-posterior depth of the chest, skin to skin.
    pub depth_mm: f64,
    /// Subcutaneous fat thickness.
    pub fat_mm: f64,
    /// Breathing state: 0 expiration … 1 deep inspiration.
    pub breathing: f64,
    /// Height of the lung apex.
    pub lung_apex_z_mm: f64,
    /// Height of the lowest point of the lungs (posterior costophrenic recess).
    pub lung_base_z_mm: f64,
    /// Heights of the tops of the right and left hemidiaphragm domes.
    pub dome_top_z_mm: [f64; 2],
    /// Centre of the heart.
    pub heart_centre_mm: [f64; 3],
    /// Heart size relative to an average heart of the same body size.
    pub heart_scale: f64,
    /// Arm pose (`None`: no arms, LidcCropped).
    pub arms: Option<ArmPose>,
    /// Female (with breasts).
    pub female: bool,
    /// Lung nodules.
    pub nodules: Vec<NoduleInfo>,
    /// The cropped field of view (LidcCropped only).
    pub field_of_view: Option<FieldOfView>,
    /// y of the table top under the spine (when a table is present).
    pub table_top_y_mm: Option<f64>,
    /// Centre of the pacemaker can (when present).
    pub pacemaker_mm: Option<[f64; 3]>,
}

/// A generated phantom with its labels.
#[derive(Debug, Clone)]
pub struct Labeled {
    /// The CT in HU.
    pub volume: Volume,
    /// Tissue of each voxel, same layout as the volume (`i` fastest).
    pub tissue: Vec<Tissue>,
    /// Anatomical structure of each voxel, same layout.
    pub structure: Vec<Structure>,
    /// The sampled patient.
    pub patient: Patient,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profile_parsing() {
        assert_eq!(Profile::parse("lidc").unwrap(), Profile::LidcCropped);
        assert_eq!(
            Profile::parse("LIDC-cropped").unwrap(),
            Profile::LidcCropped
        );
        assert_eq!(Profile::parse("full-chest").unwrap(), Profile::FullChest);
        assert!(Profile::parse("abdomen").is_err());
    }
}
