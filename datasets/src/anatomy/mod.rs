//! # Procedural chest-CT phantoms
//!
//! [`generate`] builds a seeded, anatomically plausible chest CT in HU: body outline with
//! subcutaneous fat and chest-wall muscle, two shaped lungs with diaphragm domes, branching
//! pulmonary vessel and airway trees, heart and great vessels, spine, ribs with costal
//! cartilages, sternum, clavicles and scapulae, 0–3 lung nodules, and — depending on the
//! [`Profile`] and switches — arms, neck and head, a patient table and a pacemaker. The same
//! [`AnatomySpec`] always gives the same bytes, whatever the number of threads.
//!
//! ## Frame
//! World frame = DICOM LPS in mm (+x patient left, +y posterior, +z head), as everywhere in
//! tomograf ([`tomograf_sim::volume`]). The grid is centred on the world origin with identity
//! direction. The patient is placed with x = 0 on the midline, y = 0 at the antero-posterior
//! centre of the chest and z = 0 halfway between the lowest point of the lungs and the lung
//! apex, for both profiles: the same seed is the same patient in both.
//!
//! ## Profiles — the domain shift
//! * [`Profile::LidcCropped`] imitates LIDC-IDRI training CTs: the field of view is cropped
//!   to the thorax (a few mm above the lung apex to a little below the lowest lung point)
//!   and to a circle in-plane that may cut the lateral chest wall of large patients; voxels
//!   outside it hold the scanner's padding value (−1024 HU). No arms (raised out of the
//!   field), no neck.
//! * [`Profile::FullChest`] imitates whole-chest CTs: arms (beside the chest or raised
//!   beside the head, one or the other per seed), shoulders, neck with trachea and
//!   vessels, head above it if the grid reaches that far, the complete chest wall and
//!   the upper abdomen.
//!
//! ## Painting order (priority)
//! Primitives are painted in this order; a later one overwrites an earlier one:
//! 1. subcutaneous fat: torso, neck, scalp, breasts, arms (the body outline);
//! 2. muscle: the same outlines shrunk by the fat thickness (chest wall, back, neck, arms),
//!    glandular breast tissue;
//! 3. viscera: soft tissue filling the thoracic cavity and the upper abdomen;
//! 4. lungs (right, left), each cut by its hemidiaphragm dome;
//! 5. mediastinal fat and paravertebral muscle (the medial borders of the lungs);
//! 6. heart: pericardial fat, myocardium, blood in the chambers;
//! 7. great vessels and oesophagus: aorta, pulmonary trunk and arteries, venae cavae,
//!    brachiocephalic, jugular and subclavian vessels, carotids;
//! 8. pulmonary arteries and veins (the trees);
//! 9. airway walls (trachea, bronchi, bronchial tree);
//! 10. nodules;
//! 11. bone: vertebrae (cortex, marrow, discs, arches, processes), spinal canal, ribs and
//!     costal cartilages, sternum, clavicles, scapulae, arm bones, skull and brain;
//! 12. air cavities: airway lumens, stomach gas;
//! 13. pacemaker can and leads;
//! 14. patient table;
//! 15. LidcCropped field of view (padding outside it).
//!
//! Tissue labels and HU ranges are in [`Tissue`] and [`hu_range`]; every voxel's value
//! lies in the range of its tissue, with a seeded texture of a few HU (with
//! [`AnatomySpec::heterogeneity_hu`], soft tissues also carry a correlated texture of that
//! size and lie in [`heterogeneity::RANGE_HU`] instead: [`heterogeneity`]). [`generate_labeled`]
//! also returns organ-level [`Structure`] labels and the sampled [`Patient`] (sizes,
//! landmarks, nodule positions); [`describe`] returns the patient without voxels.
//!
//! ## Variation from the seed
//! Chest width 280–400 mm, depth 64–80 % of it, subcutaneous fat 3–32 mm (growing with
//! width), chest-wall muscle thickness, vertebra height, breathing state (lung height and
//! diaphragm position), dome heights (right higher than left), heart size (±15 %),
//! position (±10 mm) and turn, arm pose, sex (breasts), stomach gas, 0–3 nodules of
//! 3–30 mm at 0–100 HU, the vessel and airway trees, the LidcCropped field of view, and
//! the texture.
//!
//! ## Rendering
//! Primitives are analytic shapes (superelliptic sections interpolated along z, ellipsoids,
//! elliptic cylinders, tapered capsules along polylines and splines, rounded boxes, the
//! couch profile); each is rasterised over its bounding box only, z-slices in parallel,
//! by testing voxel centres (no partial-volume averaging). Randomness is drawn while the
//! primitive list is built (ChaCha8, one stream per part); the texture is a counter-based
//! hash of the voxel index, so the result does not depend on the thread count.
//!
//! ## Simplifications
//! * Voxel centres are point-sampled: no partial-volume effect; structures thinner than a
//!   voxel (small vessels, cortical shells, the scapula) alias on coarse grids. Pacemaker
//!   leads (1 mm radius) are widened to about half a voxel so they stay continuous.
//! * Lungs have no fissures, lobes or pleura; the diaphragm domes are ellipsoidal caps;
//!   parenchyma is −850 HU with a posterior gradient and white-noise texture.
//! * Vessel and airway trees are space-filling constructions, not real segmental anatomy;
//!   arteries run beside the bronchi, veins form an independent tree; unenhanced blood is
//!   indistinguishable from myocardium, as in a non-contrast CT.
//! * The heart is an ellipsoid with four ellipsoidal chambers and pericardial fat (no
//!   valves, coronaries or calcifications); great vessels are tubes along splines; no
//!   thymus, thyroid, lymph nodes or azygos system.
//! * Below the diaphragm the abdomen is homogeneous soft tissue (no liver, spleen or
//!   kidney boundaries) with an optional stomach gas bubble; the trunk continues downwards
//!   as a column (no pelvis or legs).
//! * Bones are shells of cylinders, tubes and plates: ribs are round (real ribs are flat),
//!   vertebrae have no facet joints, the scapula is two plates with a spine and a neck, the
//!   forearm two tubes, no hands; the head is three nested ellipsoids (no face or jaw).
//! * Twelve rib pairs are always built; the field of view decides how many show.
//! * The table is infinitely long; the pacemaker can has no header block.

mod body;
pub mod deform;
mod devices;
mod great_vessels;
mod heart;
pub mod heterogeneity;
mod lungs;
mod mediastinum;
mod patient;
mod raster;
mod scene;
mod shapes;
mod skeleton;
mod spec;
mod tissue;
mod trees;

pub use devices::DeviceMesh;
pub use spec::{AnatomySpec, ArmPose, FieldOfView, Labeled, NoduleInfo, Patient, Profile};
pub use tissue::{Structure, Tissue, hu_range};

/// The widest [`AnatomySpec::organ_spread`]: three times the drawn ranges already give hearts
/// of 0.61–1.42 × the mean size.
pub const MAX_ORGAN_SPREAD: f64 = 3.0;

use crate::error::{DatasetError, Result};
use glam::DVec3;
use patient::Params;
use raster::Grid;
use rayon::prelude::*;
pub(crate) use scene::{Scene, frame, spline};
use tissue::Material;
use tomograf_sim::Volume;

fn check(spec: &AnatomySpec) -> Result<()> {
    tomograf_sim::volume::checked_voxel_count(spec.dims)
        .map_err(|e| DatasetError::Invalid(format!("anatomy: {e}")))?;
    if let Some(s) = spec
        .spacing_mm
        .iter()
        .find(|s| !(s.is_finite() && **s > 0.0))
    {
        return Err(DatasetError::Invalid(format!(
            "anatomy: voxel spacing {s} mm is not a finite positive number"
        )));
    }
    let h = spec.heterogeneity_hu;
    if !(h.is_finite() && (0.0..=200.0).contains(&h)) {
        return Err(DatasetError::Invalid(format!(
            "anatomy: soft-tissue heterogeneity {h} HU is outside 0–200 HU"
        )));
    }
    let d = spec.deform_mm;
    if !(d.is_finite() && (0.0..=deform::MAX_DEFORM_MM).contains(&d)) {
        return Err(DatasetError::Invalid(format!(
            "anatomy: deformation {d} mm is outside 0–{} mm",
            deform::MAX_DEFORM_MM
        )));
    }
    let k = spec.organ_spread;
    if !(k.is_finite() && (0.0..=MAX_ORGAN_SPREAD).contains(&k)) {
        return Err(DatasetError::Invalid(format!(
            "anatomy: organ spread {k} is outside 0–{MAX_ORGAN_SPREAD} (1: the ranges as drawn)"
        )));
    }
    Ok(())
}

/// Builds the primitive list in painting order, and the patient summary.
/// With `device_meshes`, the pacemaker and table go there as meshes instead of into the
/// scene.
fn build(
    spec: &AnatomySpec,
    mut device_meshes: Option<&mut Vec<DeviceMesh>>,
) -> (Scene, Params, Patient) {
    let p = Params::sample_spread(spec.seed, spec.organ_spread);
    let full = spec.profile == Profile::FullChest;
    let min_spacing = spec
        .spacing_mm
        .iter()
        .cloned()
        .fold(f64::INFINITY, f64::min);
    let mut sc = Scene::new();

    let arms = full.then(|| body::arm_geometry(&p));
    body::outline(&mut sc, &p, arms.as_ref());
    body::muscle(&mut sc, &p, arms.as_ref());
    body::viscera(&mut sc, &p);
    let lungs = lungs::Lungs::new(&p);
    lungs.paint(&mut sc, &p);
    let mut blockers = body::mediastinum(&mut sc, &p);
    let heart = heart::Heart::new(&p);
    heart.paint(&mut sc);
    blockers.push(heart.pericardium());
    let free = |q: DVec3, side: f64| -> bool {
        lungs.side_of(q) == Some(side) && !blockers.iter().any(|b| b.contains(q))
    };
    let airways = trees::Airways::new(&p, &heart, &free);
    great_vessels::great_vessels(&mut sc, &p, &heart, &airways);
    airways.paint_vessels(&mut sc);
    airways.paint_walls(&mut sc);
    let nodules = lungs::nodules(&mut sc, &p, spec.seed, &free);
    skeleton::paint(&mut sc, &p, arms.as_ref());
    airways.paint_lumens(&mut sc);
    lungs::stomach_gas(&mut sc, &p);
    let pacemaker = spec.pacemaker.then(|| {
        devices::pacemaker(
            &mut sc,
            &p,
            &heart,
            min_spacing,
            device_meshes.as_deref_mut(),
        )
    });
    let table_top = spec.table.then(|| devices::table(&mut sc, device_meshes));

    let patient = Patient {
        seed: spec.seed,
        profile: spec.profile,
        width_mm: p.width,
        depth_mm: p.depth,
        fat_mm: p.fat,
        breathing: p.breath,
        lung_apex_z_mm: p.z_apex,
        lung_base_z_mm: p.z_base,
        dome_top_z_mm: [p.z_base + p.dome_h[0], p.z_base + p.dome_h[1]],
        heart_centre_mm: heart.centre.to_array(),
        heart_scale: p.heart_scale,
        arms: arms.as_ref().map(|_| p.arms),
        female: p.female,
        nodules,
        field_of_view: (!full).then_some(FieldOfView {
            z_min_mm: p.crop.z0,
            z_max_mm: p.crop.z1,
            radius_mm: p.crop.radius,
        }),
        table_top_y_mm: table_top,
        pacemaker_mm: pacemaker.map(|c| c.to_array()),
    };
    (sc, p, patient)
}

/// The patient a spec describes (sizes, landmarks, nodules) without generating voxels.
pub fn describe(spec: &AnatomySpec) -> Result<Patient> {
    check(spec)?;
    Ok(build(spec, None).2)
}

/// Generates the phantom (HU), grid centred on the world origin with identity direction.
/// Same spec, same bytes, whatever the thread count.
pub fn generate(spec: &AnatomySpec) -> Result<Volume> {
    Ok(render(spec, None)?.volume)
}

/// Generates the phantom with its pacemaker and table (as the spec asks) as closed meshes
/// instead of voxels: the volume holds no device, and the meshes (world mm, same frame as
/// the volume) carry their materials and densities. Everything else is the same as
/// [`generate`], voxel for voxel.
pub fn generate_with_device_meshes(spec: &AnatomySpec) -> Result<(Volume, Vec<DeviceMesh>)> {
    let mut meshes = Vec::new();
    let volume = render(spec, Some(&mut meshes))?.volume;
    Ok((volume, meshes))
}

/// Generates the phantom together with its tissue and structure labels and the patient
/// summary (same volume as [`generate`]).
pub fn generate_labeled(spec: &AnatomySpec) -> Result<Labeled> {
    let r = render(spec, None)?;
    let tissue = r
        .mats
        .par_iter()
        .map(|&m| r.materials[m as usize].tissue)
        .collect();
    let structure = r
        .sts
        .par_iter()
        .map(|&s| Structure::ALL[s as usize])
        .collect();
    Ok(Labeled {
        volume: r.volume,
        tissue,
        structure,
        patient: r.patient,
    })
}

struct Rendered {
    volume: Volume,
    mats: Vec<u8>,
    sts: Vec<u8>,
    materials: Vec<Material>,
    patient: Patient,
}

/// Rasterises the scene into labels, then labels into HU with a counter-based texture.
fn render(spec: &AnatomySpec, device_meshes: Option<&mut Vec<DeviceMesh>>) -> Result<Rendered> {
    check(spec)?;
    let (sc, p, patient) = build(spec, device_meshes);
    let spacing = DVec3::from(spec.spacing_mm);
    let grid = Grid::centred(spec.dims, spacing);
    let crop = (spec.profile == Profile::LidcCropped)
        .then_some((p.crop, (Tissue::Padding as u8, Structure::OutsideFov as u8)));
    let (mats, sts) = raster::rasterize(
        &grid,
        &sc.prims,
        (Tissue::Air as u8, Structure::Outside as u8),
        crop,
    );
    let seed = tissue::mix64(spec.seed ^ patient::stream::TEXTURE.rotate_left(40));
    let [nx, ny, _] = spec.dims;
    let plane = nx * ny;
    let hetero = spec.heterogeneity_hu as f32;
    let hetero_seed = tissue::mix64(seed ^ 0x4845_5445_524F);
    let mut data = vec![0f32; mats.len()];
    data.par_chunks_mut(plane)
        .zip(mats.par_chunks(plane))
        .enumerate()
        .for_each(|(k, (out, m))| {
            let z = grid.coord(2, k);
            for j in 0..ny {
                let y = grid.coord(1, j);
                for i in 0..nx {
                    let idx = i + nx * j;
                    let n = tissue::gauss(seed, (k * plane + idx) as u64);
                    let material = &sc.materials[m[idx] as usize];
                    out[idx] = material.hu(y, n);
                    if hetero > 0.0 && heterogeneity::applies_to(material.tissue) {
                        let p = DVec3::new(grid.coord(0, i), y, z);
                        let t = hetero * heterogeneity::value_noise(hetero_seed, p);
                        let (lo, hi) = heterogeneity::RANGE_HU;
                        out[idx] = (out[idx] + t).clamp(lo, hi);
                    }
                }
            }
        });
    let (data, mats, sts) = if spec.deform_mm > 0.0 {
        let seed = tissue::mix64(spec.seed ^ 0x5741_5250);
        let sources = deform::sources(&grid, seed, spec.deform_mm);
        (
            deform::warp_values(&grid, &data, &sources),
            deform::warp_labels(&grid, &mats, &sources),
            deform::warp_labels(&grid, &sts, &sources),
        )
    } else {
        (data, mats, sts)
    };
    let volume = Volume::centred(spec.dims, spacing, DVec3::ZERO, data)
        .map_err(|e| DatasetError::Invalid(format!("anatomy: {e}")))?;
    Ok(Rendered {
        volume,
        mats,
        sts,
        materials: sc.materials,
        patient,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn structure_table_matches_discriminants() {
        for (i, s) in Structure::ALL.iter().enumerate() {
            assert_eq!(*s as usize, i);
        }
    }
}
