//! AAPM TG-195 Case 3: mammography and breast tomosynthesis. Energy imparted in the breast
//! and in seven 20 × 20 × 10 mm VOIs, 16.8 keV and 30 kVp Mo/Mo (RQR-M3), the source above
//! the breast (radiography) or turned 15° about the chest-wall axis (tomosynthesis).
//!
//! Geometry as the open-source XRayMClib build of the case (the CSV header in
//! `eval/data/tg195/`), in mm with the origin at the centre of the breast's flat chest-wall
//! face, +z towards the source, the world TG-195 dry air:
//!
//! * the breast: a half cylinder of radius 100 mm and thickness 50 mm (|z| ≤ 25) on the
//!   +x side of the chest wall, with a 2 mm skin on its curved face and on its top and
//!   bottom (skin 1.09 g/cm³), inside it 20 % glandular / 80 % adipose tissue by weight at
//!   0.952 g/cm³ (XRayMClib's 0.8 × 0.93 + 0.2 × 1.04);
//! * PMMA compression and support plates, 0 ≤ x ≤ 140, |y| ≤ 130, 25 ≤ |z| ≤ 27;
//! * the body: water, −170 ≤ x ≤ 0, |y| ≤ 150, |z| ≤ 150;
//! * the source 620 mm above the origin (660 mm above the detector plane z = −40), its
//!   field the 140 × 260 mm detector area 0 ≤ x ≤ 140, |y| ≤ 130 on that plane; for
//!   tomosynthesis the source turned by 15° about the x axis through the origin, the field
//!   unchanged.
//!
//! "Total body" is the breast tissue inside the skin (XRayMClib's tally of the case: the
//! half cylinder of radius 98 mm, |z| ≤ 23, the VOIs included, the skin not), scored
//! analytically like the VOIs. The material grid is 1 × 1 × 2 mm: the planes of the skin,
//! plates and chest wall fall on voxel faces; on the curved faces each voxel holds the
//! material of the largest mass among 4 × 4 sub-samples at their mean density (partial
//! volume, mass conserved); the body's far faces at z = ±150 mm fall mid-voxel (1 mm
//! too thick there, 125 mm from the breast).

use super::reference;
use super::tg195::{Beam, Comparison, air, medium, pmma, regions_against, run};
use glam::DVec3;
use tomograf_physics::scatter::energy_imparted::RegionEstimator;
use tomograf_physics::scatter::field::FieldSource;
use tomograf_physics::scatter::region::Region;
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::material::{Material, mixture};

/// VOI centres (mm from the centre of the chest-wall face), by VOI number 1–7.
const VOIS: [[f64; 3]; 7] = [
    [50.0, 50.0, 0.0],
    [20.0, 0.0, 0.0],
    [50.0, 0.0, 0.0],
    [80.0, 0.0, 0.0],
    [50.0, -50.0, 0.0],
    [50.0, 0.0, -15.0],
    [50.0, 0.0, 15.0],
];

/// Breast radius, half thickness and skin thickness, mm.
const RADIUS: f64 = 100.0;
const HALF_THICKNESS: f64 = 25.0;
const SKIN: f64 = 2.0;

/// TG-195 skin, 1.09 g/cm³ (H 9.8, C 17.8, N 5.0, O 66.7, P, S, K, Ca 0.175 % by weight).
fn skin() -> Result<Material> {
    Material::new(
        "tg195-skin",
        &[
            (1, 0.098),
            (6, 0.178),
            (7, 0.050),
            (8, 0.667),
            (15, 0.00175),
            (16, 0.00175),
            (19, 0.00175),
            (20, 0.00175),
        ],
        1.09,
    )
}

/// TG-195 breast tissue: 20 % glandular, 80 % adipose by weight, 0.952 g/cm³.
fn breast_tissue() -> Result<Material> {
    let adipose = Material::new(
        "tg195-adipose",
        &[
            (1, 0.112),
            (6, 0.619),
            (7, 0.017),
            (8, 0.251),
            (15, 0.00025),
            (16, 0.00025),
            (19, 0.00025),
            (20, 0.00025),
        ],
        0.93,
    )?;
    let glandular = Material::new(
        "tg195-glandular",
        &[
            (1, 0.102),
            (6, 0.184),
            (7, 0.032),
            (8, 0.677),
            (15, 0.00125),
            (16, 0.00125),
            (19, 0.00125),
            (20, 0.00125),
        ],
        1.04,
    )?;
    mixture(
        "tg195-breast",
        &[(adipose, 0.8), (glandular, 0.2)],
        0.8 * 0.93 + 0.2 * 1.04,
    )
}

/// TG-195 water, 1.0 g/cm³.
fn water() -> Result<Material> {
    Material::new("tg195-water", &[(1, 0.111898), (8, 0.888102)], 1.0)
}

/// Materials in the order of the grid's labels.
const AIR: usize = 0;
const SKIN_M: usize = 1;
const BREAST: usize = 2;
const PMMA: usize = 3;
const WATER: usize = 4;

/// The material at a point (mm) and its density (g/cm³).
fn at(p: DVec3) -> (usize, f64) {
    let r2 = p.x * p.x + p.y * p.y;
    if p.x >= 0.0 && p.z.abs() <= HALF_THICKNESS && r2 <= RADIUS * RADIUS {
        let inner = RADIUS - SKIN;
        return if p.z.abs() > HALF_THICKNESS - SKIN || r2 > inner * inner {
            (SKIN_M, 1.09)
        } else {
            (BREAST, 0.952)
        };
    }
    if (0.0..=140.0).contains(&p.x)
        && p.y.abs() <= 130.0
        && (HALF_THICKNESS..=HALF_THICKNESS + 2.0).contains(&p.z.abs())
    {
        return (PMMA, 1.19);
    }
    if (-170.0..=0.0).contains(&p.x) && p.y.abs() <= 150.0 && p.z.abs() <= 150.0 {
        return (WATER, 1.0);
    }
    (AIR, 0.001205)
}

/// Case 3: energy imparted in the breast tissue and the seven VOIs (radiography, or
/// tomosynthesis at 15°), `photons` per run, 16.8 keV or 30 kVp.
pub fn case3(beam: Beam, tomo: bool, photons: u64, seed: u64) -> Result<Vec<Comparison>> {
    let label = beam.label();
    if !matches!(beam, Beam::Kvp(30)) && beam != Beam::Mono(16.8) {
        return Err(SimError::OutOfRange(format!(
            "TG-195 case 3 has 16.8 keV and 30 kVp beams, not {label}"
        )));
    }
    let spectrum = beam.spectrum()?;
    let mode = if tomo { "tomosynthesis" } else { "radiography" };
    let angle = if tomo { 15f64.to_radians() } else { 0.0 };
    // (0, 0, 620) turned about +x by the angle.
    let position = DVec3::new(0.0, -620.0 * angle.sin(), 620.0 * angle.cos());
    let source = FieldSource::new(
        position,
        DVec3::new(70.0, 0.0, -40.0),
        DVec3::X * 70.0,
        DVec3::Y * 130.0,
    )?;
    // From the body's back to the plates' far edge, the body's sides (and the tilted
    // source at y = −160.5), the body's bottom to the source.
    let spacing = DVec3::new(1.0, 1.0, 2.0);
    let min = DVec3::new(-170.0, -162.0, -151.0);
    let dims = [310, 312, 387];
    let sub = 4;
    let m = medium(
        min,
        dims,
        spacing,
        vec![air()?, skin()?, breast_tissue()?, pmma()?, water()?],
        spectrum.max_kev() + 1.0,
        |c| {
            let r = (c.x * c.x + c.y * c.y).sqrt();
            let curved = c.x > -1.0
                && c.z.abs() < HALF_THICKNESS
                && (RADIUS - SKIN - 1.5..=RADIUS + 1.5).contains(&r);
            if !curved {
                let (m, rho) = at(c);
                return (rho as f32, m);
            }
            // Partial volume: the largest mass's material at the mean density.
            let mut mass = [0.0f64; 5];
            for a in 0..sub {
                for b in 0..sub {
                    let x = c.x + ((a as f64 + 0.5) / sub as f64 - 0.5) * spacing.x;
                    let y = c.y + ((b as f64 + 0.5) / sub as f64 - 0.5) * spacing.y;
                    let (m, rho) = at(DVec3::new(x, y, c.z));
                    mass[m] += rho;
                }
            }
            let heaviest = (0..mass.len())
                .max_by(|&a, &b| mass[a].total_cmp(&mass[b]))
                .unwrap_or(AIR);
            let rho = mass.iter().sum::<f64>() / (sub * sub) as f64;
            (rho as f32, heaviest)
        },
    )?;
    let mut regions = vec![Region::half_cylinder(
        "Total body",
        DVec3::ZERO,
        DVec3::Z,
        RADIUS - SKIN,
        2.0 * (HALF_THICKNESS - SKIN),
        DVec3::X,
    )];
    for (v, c) in VOIS.iter().enumerate() {
        regions.push(Region::cube(
            &format!("VOI {}", v + 1),
            DVec3::from(*c),
            DVec3::new(20.0, 20.0, 10.0),
        ));
    }
    let r = run(
        &m,
        &source,
        &spectrum,
        &regions,
        &[],
        (RegionEstimator::Collision, photons),
        seed,
    )?;
    regions_against(&r, &reference::case3()?, "3", &label, mode)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The materials at named points of the case's geometry.
    #[test]
    fn the_geometry_puts_each_material_where_the_case_says() {
        assert_eq!(at(DVec3::new(50.0, 0.0, 0.0)).0, BREAST);
        assert_eq!(at(DVec3::new(50.0, 0.0, 24.0)).0, SKIN_M);
        assert_eq!(at(DVec3::new(99.0, 0.0, 0.0)).0, SKIN_M);
        assert_eq!(at(DVec3::new(0.0, 99.0, 0.0)).0, SKIN_M);
        assert_eq!(at(DVec3::new(101.0, 0.0, 0.0)).0, AIR);
        assert_eq!(at(DVec3::new(120.0, 0.0, 26.0)).0, PMMA);
        assert_eq!(at(DVec3::new(120.0, 0.0, -26.0)).0, PMMA);
        assert_eq!(at(DVec3::new(-1.0, 0.0, 0.0)).0, WATER);
        assert_eq!(at(DVec3::new(-1.0, 0.0, 200.0)).0, AIR);
        // The chest-wall face is not skinned: tissue reaches x = 0.
        assert_eq!(at(DVec3::new(0.5, 0.0, 0.0)).0, BREAST);
        let b = breast_tissue().unwrap();
        let w: f64 = b.composition().iter().map(|(_, w)| w).sum();
        assert!((w - 1.0).abs() < 1e-9);
    }
}
