//! Tissue classes, their CT numbers, anatomical structure labels, and the seeded voxel
//! texture that turns labels into HU.
//!
//! # Sources for the HU ranges
//! The ranges of [`hu_range`] are published CT-number ranges, widened only where two
//! sources disagree; a generated voxel always lies inside the range of its tissue:
//!
//! * Hounsfield-scale tables (Wikipedia "Hounsfield scale", after Brant & Helms,
//!   *Fundamentals of Diagnostic Radiology*; Buzug, *Computed Tomography*, Springer 2008,
//!   p. 475; Prokop, *Spiral and Multislice CT of the Body*, Thieme 2003): air −1000, lung
//!   parenchyma in inspiration −910 … −850, fat −120 … −90, unclotted blood +13 … +50,
//!   clotted +50 … +75, liver +45 … +65, spleen +35 … +55, cancellous bone +300 … +400,
//!   cortical bone up to +1800 … +1900.
//! * Schneider, Pedroni & Lomax 1996 (*Phys. Med. Biol.* 41:111) and Schneider, Bortfeld &
//!   Schlegel 2000 (*Phys. Med. Biol.* 45:459): CT numbers of ~70 human tissues used to
//!   calibrate HU for dose calculation — lung, adipose, muscle, cartilage, spongiosa and
//!   cortical bone sit in the same order and ranges as below.
//! * Body-composition thresholds: adipose −190 … −30 HU (Kvist et al. 1988; Yoshizumi et
//!   al. 1999), skeletal muscle −29 … +150 HU (Mitsiopoulos et al. 1998, *J. Appl. Physiol.*
//!   85:115).
//! * Lung densitometry: −950 HU is the usual emphysema threshold (Gevenois et al. 1996), so
//!   healthy parenchyma stays above it; the dependent (posterior) lung of a supine patient
//!   is denser than the anterior lung.
//! * 12-bit CT storage spans −1024 … +3071 HU; metal (titanium pacemaker cans, lead
//!   conductors) saturates at the top of it.

use serde::{Deserialize, Serialize};

/// Tissue (material) classes of the phantom. Each voxel has exactly one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[repr(u8)]
pub enum Tissue {
    /// Air outside the patient and in the airways and stomach (−1000 HU).
    Air = 0,
    /// Outside the reconstruction field of view ([`super::Profile::LidcCropped`]): the
    /// scanner's padding value, exactly −1024 HU.
    Padding,
    /// Inflated lung parenchyma (≈ −850 HU, denser posteriorly).
    Lung,
    /// Adipose tissue: subcutaneous, mediastinal, pericardial, breast, yellow marrow.
    Fat,
    /// Skeletal muscle: chest wall (pectorals, intercostals, back muscles), neck, arms.
    Muscle,
    /// Parenchymal organs and other soft tissue: liver and upper abdomen, oesophagus,
    /// airway walls, spinal canal, glandular breast tissue, brain.
    SoftTissue,
    /// Unenhanced blood in the heart chambers, great and pulmonary vessels.
    Blood,
    /// Myocardium.
    Heart,
    /// Cortical bone (the shell of ribs, vertebrae, sternum, clavicles, scapulae, humeri,
    /// skull).
    Bone,
    /// Cancellous (trabecular) bone with red marrow, inside the cortical shell.
    Marrow,
    /// Hyaline cartilage: costal cartilages, intervertebral discs.
    Cartilage,
    /// Solid lung nodules and tumours.
    Nodule,
    /// Metal: the titanium pacemaker can and its lead conductors.
    Metal,
    /// The carbon-fibre skin of the patient table.
    Plastic,
    /// The low-density foam core of the patient table.
    Foam,
}

impl Tissue {
    /// Every tissue, in label order.
    pub const ALL: [Tissue; 15] = [
        Tissue::Air,
        Tissue::Padding,
        Tissue::Lung,
        Tissue::Fat,
        Tissue::Muscle,
        Tissue::SoftTissue,
        Tissue::Blood,
        Tissue::Heart,
        Tissue::Bone,
        Tissue::Marrow,
        Tissue::Cartilage,
        Tissue::Nodule,
        Tissue::Metal,
        Tissue::Plastic,
        Tissue::Foam,
    ];
}

/// Published HU range `(low, high)` of a tissue (see the module docs for the sources).
/// Every voxel [`super::generate`] labels with `t` has a value in `hu_range(t)`.
pub fn hu_range(t: Tissue) -> (f32, f32) {
    match t {
        Tissue::Air => (-1024.0, -950.0),
        Tissue::Padding => (-1024.0, -1024.0),
        Tissue::Lung => (-950.0, -700.0),
        Tissue::Fat => (-190.0, -30.0),
        Tissue::Muscle => (-29.0, 150.0),
        Tissue::SoftTissue => (0.0, 80.0),
        Tissue::Blood => (13.0, 75.0),
        Tissue::Heart => (20.0, 80.0),
        Tissue::Bone => (500.0, 1900.0),
        Tissue::Marrow => (100.0, 450.0),
        Tissue::Cartilage => (50.0, 250.0),
        Tissue::Nodule => (-50.0, 150.0),
        Tissue::Metal => (2000.0, 3071.0),
        Tissue::Plastic => (-100.0, 250.0),
        Tissue::Foam => (-1000.0, -800.0),
    }
}

/// Default mean HU and texture standard deviation of a tissue.
pub(crate) fn default_hu(t: Tissue) -> (f32, f32) {
    match t {
        Tissue::Air => (-1000.0, 5.0),
        Tissue::Padding => (-1024.0, 0.0),
        Tissue::Lung => (-850.0, 15.0),
        Tissue::Fat => (-100.0, 8.0),
        Tissue::Muscle => (45.0, 8.0),
        Tissue::SoftTissue => (45.0, 6.0),
        Tissue::Blood => (40.0, 4.0),
        Tissue::Heart => (45.0, 5.0),
        Tissue::Bone => (1000.0, 50.0),
        Tissue::Marrow => (250.0, 25.0),
        Tissue::Cartilage => (120.0, 10.0),
        Tissue::Nodule => (50.0, 6.0),
        Tissue::Metal => (3000.0, 20.0),
        Tissue::Plastic => (150.0, 12.0),
        Tissue::Foam => (-920.0, 8.0),
    }
}

/// Anatomical structure labels (organ-level ground truth), one per voxel, alongside the
/// tissue label.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[repr(u8)]
pub enum Structure {
    /// Air around the patient.
    Outside = 0,
    /// Outside the reconstruction field of view ([`super::Profile::LidcCropped`]).
    OutsideFov,
    /// Subcutaneous fat of trunk, neck and arms (the body outline).
    SubcutaneousFat,
    /// Skeletal muscle: chest wall (pectorals, intercostals), back and paraspinal muscles,
    /// neck, arms.
    Muscle,
    /// Breast (fat and glandular tissue).
    Breast,
    /// Soft tissue inside the rib cage that is not lung, heart or a vessel: liver and upper
    /// abdomen below the diaphragm.
    Viscera,
    /// Mediastinal fat between the lungs.
    Mediastinum,
    /// Left lung parenchyma (patient left, +x).
    LungLeft,
    /// Right lung parenchyma (patient right, −x).
    LungRight,
    /// Pulmonary arteries and veins inside the lungs (the branching trees).
    PulmonaryVessel,
    /// Trachea and bronchi: wall.
    AirwayWall,
    /// Trachea and bronchi: air lumen.
    AirwayLumen,
    /// Lung nodule or tumour.
    Nodule,
    /// Heart: myocardium, chambers and pericardial fat.
    Heart,
    /// Aorta (ascending, arch, descending).
    Aorta,
    /// Pulmonary trunk and arteries, venae cavae, brachiocephalic, jugular and subclavian
    /// veins, arch branches and carotids.
    GreatVessel,
    /// Oesophagus.
    Esophagus,
    /// Vertebrae: bodies, arches, transverse and spinous processes.
    Vertebra,
    /// Intervertebral discs.
    Disc,
    /// Spinal canal (cord and CSF).
    SpinalCanal,
    /// Ribs (bony part).
    Rib,
    /// Costal cartilages.
    CostalCartilage,
    /// Sternum (manubrium, body, xiphoid).
    Sternum,
    /// Clavicles.
    Clavicle,
    /// Scapulae.
    Scapula,
    /// Arm bones (humerus, radius, ulna).
    ArmBone,
    /// Head (scalp, skull, brain) above the neck.
    Head,
    /// Gas in the stomach under the left hemidiaphragm.
    StomachGas,
    /// Pacemaker can.
    Pacemaker,
    /// Pacemaker leads.
    PacemakerLead,
    /// Patient table.
    Table,
}

impl Structure {
    /// Every structure, in label order.
    pub const ALL: [Structure; 31] = [
        Structure::Outside,
        Structure::OutsideFov,
        Structure::SubcutaneousFat,
        Structure::Muscle,
        Structure::Breast,
        Structure::Viscera,
        Structure::Mediastinum,
        Structure::LungLeft,
        Structure::LungRight,
        Structure::PulmonaryVessel,
        Structure::AirwayWall,
        Structure::AirwayLumen,
        Structure::Nodule,
        Structure::Heart,
        Structure::Aorta,
        Structure::GreatVessel,
        Structure::Esophagus,
        Structure::Vertebra,
        Structure::Disc,
        Structure::SpinalCanal,
        Structure::Rib,
        Structure::CostalCartilage,
        Structure::Sternum,
        Structure::Clavicle,
        Structure::Scapula,
        Structure::ArmBone,
        Structure::Head,
        Structure::StomachGas,
        Structure::Pacemaker,
        Structure::PacemakerLead,
        Structure::Table,
    ];

    /// True for the patient's own body (everything except air, padding and devices
    /// outside the body: the table).
    pub fn is_body(self) -> bool {
        !matches!(
            self,
            Structure::Outside | Structure::OutsideFov | Structure::Table
        )
    }
}

/// A material: a tissue with its mean HU, texture and optional linear gradient along y
/// (the gravity-dependent density of lung in a supine patient).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Material {
    pub tissue: Tissue,
    pub mean: f32,
    pub sigma: f32,
    /// HU per mm along +y (posterior).
    pub grad_y: f32,
    /// y (mm) where the mean applies.
    pub y0: f32,
}

impl Material {
    pub fn of(tissue: Tissue) -> Self {
        let (mean, sigma) = default_hu(tissue);
        Self {
            tissue,
            mean,
            sigma,
            grad_y: 0.0,
            y0: 0.0,
        }
    }

    /// HU at a voxel at world y (mm) with standard normal deviate `n`, inside the range.
    #[inline]
    pub fn hu(&self, y: f64, n: f32) -> f32 {
        let (lo, hi) = hu_range(self.tissue);
        let v = self.mean + self.grad_y * (y as f32 - self.y0) + self.sigma * n;
        v.clamp(lo, hi).clamp(-1024.0, 3071.0)
    }
}

/// SplitMix64 finaliser: a well-mixed 64-bit hash.
#[inline]
pub(crate) fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// An approximately standard-normal deviate that depends only on `(seed, index)`:
/// Irwin–Hall sum of four 16-bit uniforms, rescaled to unit variance. Counter-based, so
/// the texture is the same whatever the thread count or visiting order.
#[inline]
pub(crate) fn gauss(seed: u64, index: u64) -> f32 {
    let h = mix64(seed ^ index.wrapping_mul(0xD6E8_FEB8_6659_FD93));
    let s = (h & 0xFFFF) + ((h >> 16) & 0xFFFF) + ((h >> 32) & 0xFFFF) + (h >> 48);
    // Sum of 4 uniforms on [0, 1): mean 2, variance 1/3.
    let u = s as f32 / 65536.0;
    (u - 2.0) * 1.732_050_8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_are_ordered_and_within_12_bit() {
        for t in Tissue::ALL {
            let (lo, hi) = hu_range(t);
            let (mean, _) = default_hu(t);
            assert!(lo <= hi && lo >= -1024.0 && hi <= 3071.0, "{t:?}");
            assert!(
                (lo..=hi).contains(&mean),
                "{t:?}: mean {mean} outside range"
            );
            assert_eq!(Tissue::ALL[t as usize], t);
        }
    }

    #[test]
    fn gauss_is_roughly_standard_normal() {
        let n = 200_000u64;
        let (mut s, mut s2) = (0.0f64, 0.0f64);
        for i in 0..n {
            let g = gauss(42, i) as f64;
            s += g;
            s2 += g * g;
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        assert!(mean.abs() < 0.01, "{mean}");
        assert!((var - 1.0).abs() < 0.02, "{var}");
    }
}
