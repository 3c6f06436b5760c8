//! Mesh objects in the polychromatic (real detector) path.
//!
//! * A titanium slab mesh inside a water box: the traced mass thicknesses are the closed
//!   form (water loses the slab's thickness: the implant displaces tissue) and the
//!   integrated signal equals the polychromatic Beer–Lambert sum
//!   Σ_b N_b·E_b·exp(−(μ/ρ)_w·t_w − (μ/ρ)_Ti·t_Ti) written out here from the material
//!   tables, for exact Siddon with and without the SIMD packets and for trilinear marching.
//! * A titanium slab in air through `Acquisition::prepare_with_meshes` (the real tungsten
//!   spectrum, the ideal detector): flat-field transmission equals
//!   Σ N_b E_b e^(−μ_b ρ T) / Σ N_b E_b.
//! * A titanium sphere mesh and the same sphere voxelised (label by voxel centre) agree
//!   through the physics path as the voxels shrink: the mean |Δ(−log signal)| halves with
//!   each halving of the voxel (first order, as a staircase surface must), 0.055 at 0.5 mm
//!   for a sphere whose centre reads 4.0.

use glam::{DMat3, DVec3};
use std::sync::Arc;
use tomograf_physics::acquisition::{Acquisition, SpectrumSpec};
use tomograf_physics::detector::{DetectorModel, Mode, Output};
use tomograf_physics::polychromatic::SpectralIntegrator;
use tomograf_physics::scatter::ScatterModel;
use tomograf_sim::composition::Composition;
use tomograf_sim::material::{self, Material};
use tomograf_sim::mesh::{MeshObject, MeshScene, Placement, shapes};
use tomograf_sim::tissue::TissueModel;
use tomograf_sim::{Beam, Detector, Geometry, Pose, Projector, Renderer, Volume};

/// A Kramers-like spectrum 20–`kvp` keV in 1 keV bins (photons per mAs per mm² at 1 m).
fn spectrum(kvp: f64) -> (Vec<f64>, Vec<f64>) {
    let e: Vec<f64> = (20..kvp as usize).map(|e| e as f64 + 0.5).collect();
    let n = e.iter().map(|e| 1e4 * (kvp - e) / e).collect();
    (e, n)
}

fn table(m: &Material, e: &[f64]) -> Vec<f64> {
    e.iter().map(|&e| m.mass_attenuation(e).unwrap()).collect()
}

/// Energy-integrating ideal detector over `materials` (name, material).
fn integrator(materials: &[(&str, &Material)], kvp: f64) -> SpectralIntegrator {
    let (e, n) = spectrum(kvp);
    let w = DetectorModel {
        mode: Mode::energy_integrating(1.0),
        ..DetectorModel::ideal()
    }
    .channel_weights(&e, &vec![1.0; e.len()])
    .unwrap();
    let att = materials
        .iter()
        .map(|(name, m)| (name.to_string(), table(m, &e)))
        .collect();
    SpectralIntegrator::new(e, &n, att, &w).unwrap()
}

fn grid(dims: [usize; 3], voxel: f64, value: impl Fn([usize; 3]) -> f32) -> Volume {
    let mut data = Vec::with_capacity(dims[0] * dims[1] * dims[2]);
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                data.push(value([i, j, k]));
            }
        }
    }
    let origin = DVec3::splat(voxel / 2.0) - DVec3::from(dims.map(|d| d as f64)) * voxel / 2.0;
    Volume::new(dims, DVec3::splat(voxel), origin, DMat3::IDENTITY, data).unwrap()
}

fn titanium(mesh: &tomograf_sim::mesh::TriMesh, at: DVec3) -> MeshObject {
    MeshObject::new(
        "ti",
        mesh,
        &Placement::translation(at),
        "titanium",
        None,
        true,
    )
    .unwrap()
}

fn parallel_ap(rows: usize, pitch: f64) -> tomograf_sim::View {
    Geometry {
        beam: Beam::Parallel,
        detector: Detector::new(rows, rows, pitch),
        isocentre: DVec3::ZERO,
    }
    .view(Pose::new(0.0, 0.0))
    .unwrap()
}

/// A 3 mm titanium slab (not on voxel planes) inside a 40 mm water box, parallel beam
/// across it: water 37 mm, titanium 3 mm on every ray.
#[test]
fn titanium_slab_in_water_matches_closed_form() {
    let water = material::by_name("water").unwrap();
    let ti = material::by_name("titanium").unwrap();
    let rho_ti = ti.density();
    let dims = [10, 20, 10];
    let comp = Composition::from_labels(
        &grid(dims, 2.0, |_| 0.0),
        &grid(dims, 2.0, |_| 1.0),
        vec!["water".into()],
    )
    .unwrap();
    let slab = titanium(
        &shapes::cuboid(DVec3::new(100.0, 3.0, 100.0)).unwrap(),
        DVec3::new(0.0, 4.3, 0.0),
    );
    assert_eq!(slab.density_g_cm3, Some(rho_ti), "nominal density by name");
    let meshes = Arc::new(MeshScene::new(vec![slab]));
    let view = parallel_ap(6, 2.0);
    let names = vec!["water".to_string(), "titanium".to_string()];
    let integ = integrator(&[("water", &water), ("titanium", &ti)], 120.0);
    let (e, n) = spectrum(120.0);
    let (t_w, t_ti) = (3.7, rho_ti * 0.3); // g/cm²
    let closed: f64 = e
        .iter()
        .zip(&n)
        .map(|(&e, &n)| {
            n * e
                * (-water.mass_attenuation(e).unwrap() * t_w
                    - ti.mass_attenuation(e).unwrap() * t_ti)
                    .exp()
        })
        .sum::<f64>()
        * 4.0; // 2 mm × 2 mm pixels, 1 mAs
    for (label, projector, packets, tol_water) in [
        // Densities are stored to 2e-6 relative (composition packing).
        ("siddon, packets", Projector::Siddon, true, 1e-5),
        ("siddon, scalar", Projector::Siddon, false, 1e-5),
        // The midpoint rule drops whole samples inside the slab: ≤ one step (0.25 voxel
        // = 0.5 mm) of water at each of its two faces.
        (
            "trilinear",
            Projector::Trilinear { step_voxels: 0.25 },
            false,
            0.1 / 3.7,
        ),
    ] {
        let mut r = Renderer::for_composition(&comp, projector).unwrap();
        if !packets {
            r = r.with_packet_threshold(f64::INFINITY);
        }
        let r = r.with_meshes(meshes.clone()).unwrap();
        let t = r.mass_thickness(&view, &names).unwrap();
        for p in t.data.chunks(2) {
            assert!(
                ((p[0] - t_w) / t_w).abs() < tol_water,
                "{label}: water {} vs {t_w}",
                p[0]
            );
            assert!(
                ((p[1] - t_ti) / t_ti).abs() < 1e-12,
                "{label}: titanium {} vs {t_ti}",
                p[1]
            );
        }
        if tol_water < 1e-4 {
            let img = integ.expected(&t, &view, 1.0).unwrap();
            for &v in &img.mean {
                // 2e-5: the water density's 2e-6 packing error in an exponent of ~1.
                assert!(
                    ((v - closed) / closed).abs() < 2e-5,
                    "{label}: {v} vs {closed}"
                );
            }
        }
    }
    // The material list must name the mesh column.
    let r = Renderer::for_composition(&comp, Projector::Siddon)
        .unwrap()
        .with_meshes(meshes)
        .unwrap();
    assert!(r.mass_thickness(&view, &names[..1]).is_err());
}

/// A 2 mm titanium slab at 4.0 g/cm³ in air, through the acquisition (tungsten 120 kVp
/// with 2.5 mm Al, ideal detector): the flat-field image is the closed-form polychromatic
/// transmission of the slab at every pixel.
#[test]
fn titanium_slab_in_air_through_the_acquisition() {
    let hu = grid([8, 8, 8], 5.0, |_| -1000.0); // air: density 0
    let slab = titanium(
        &shapes::cuboid(DVec3::new(300.0, 2.0, 300.0)).unwrap(),
        DVec3::new(0.0, -50.0, 0.0), // between source and CT, outside the grid
    )
    .with_density(4.0)
    .unwrap();
    let meshes = Arc::new(MeshScene::new(vec![slab]));
    let acq = Acquisition {
        spectrum: SpectrumSpec::tungsten(120.0, &[("al", 2.5)], 1.0),
        materials: TissueModel::water(70.0),
        detector: DetectorModel::ideal(),
        output: Output::FlatField,
        scatter: ScatterModel::None,
        anti_scatter_grid: None,
    };
    let prepared = acq
        .prepare_with_meshes(&hu, 3, Some(meshes.clone()))
        .unwrap();
    let view = parallel_ap(8, 5.0);
    let images = prepared.acquire(Projector::Siddon, &view, 0).unwrap();
    let spec = acq.spectrum.spectrum().unwrap();
    let ti = material::by_name("titanium").unwrap();
    let (mut num, mut den) = (0.0, 0.0);
    for (&e, &n) in spec.energies_kev().iter().zip(spec.fluence()) {
        den += n * e;
        num += n * e * (-ti.mass_attenuation(e).unwrap() * 4.0 * 0.2).exp();
    }
    let closed = num / den;
    assert_eq!(images.len(), 1);
    for &v in &images[0].data {
        // f32 image; the rest is the same sums in another order.
        assert!(
            ((f64::from(v) - closed) / closed).abs() < 1e-6,
            "{v} vs {closed}"
        );
    }
    // Scatter with meshes is refused, naming the problem.
    let with_scatter = Acquisition {
        scatter: ScatterModel::Estimate {
            photons: 100,
            grid: 4,
            multiple_grid: 0,
            smoothing: 1.0,
            detection_cell_mm: 0.0,
        },
        ..acq.clone()
    };
    let err = with_scatter
        .prepare_with_meshes(&hu, 3, Some(meshes))
        .unwrap_err()
        .to_string();
    assert!(err.contains("scatter with mesh objects"), "{err}");
}

/// A titanium sphere (r = 6 mm) in a water box, as a mesh and voxelised (voxel centre
/// inside → titanium), through Siddon and the spectral sums: the mean |−log signal|
/// difference falls as the voxels shrink (2, 1, 0.5 mm) and is small at 0.5 mm.
#[test]
fn mesh_and_voxelised_twin_agree_through_the_physics_path() {
    let water = material::by_name("water").unwrap();
    let ti = material::by_name("titanium").unwrap();
    let rho_ti = ti.density() as f32;
    let radius = 6.0;
    let side = 16.0; // mm
    let centre = DVec3::new(0.3, -0.2, 0.1);
    let sphere = Arc::new(MeshScene::new(vec![titanium(
        &shapes::icosphere(radius, 6).unwrap(),
        centre,
    )]));
    let integ = integrator(&[("water", &water), ("titanium", &ti)], 100.0);
    let view = parallel_ap(40, 0.4);
    let names = vec!["water".to_string(), "titanium".to_string()];
    let log_image = |t: &tomograf_sim::render::MassThickness| -> Vec<f64> {
        let img = integ.expected(t, &view, 1.0).unwrap();
        let open = integ.open(&view, 1.0).unwrap();
        img.mean
            .iter()
            .zip(&open.mean)
            .map(|(a, b)| -(a / b).ln())
            .collect()
    };
    let mut previous = f64::INFINITY;
    for voxel in [2.0, 1.0, 0.5] {
        let n = (side / voxel) as usize;
        let dims = [n; 3];
        let inside = |ijk: [usize; 3]| {
            let p = (DVec3::from(ijk.map(|i| i as f64)) + 0.5) * voxel - side / 2.0;
            (p - centre).length() < radius
        };
        let labels = grid(dims, voxel, |ijk| if inside(ijk) { 1.0 } else { 0.0 });
        let density = grid(dims, voxel, |ijk| if inside(ijk) { rho_ti } else { 1.0 });
        let twin = Composition::from_labels(&labels, &density, names.clone()).unwrap();
        let voxelised = Renderer::for_composition(&twin, Projector::Siddon)
            .unwrap()
            .mass_thickness(&view, &names)
            .unwrap();
        let water_box = Composition::from_labels(
            &grid(dims, voxel, |_| 0.0),
            &grid(dims, voxel, |_| 1.0),
            vec!["water".into()],
        )
        .unwrap();
        let meshed = Renderer::for_composition(&water_box, Projector::Siddon)
            .unwrap()
            .with_meshes(sphere.clone())
            .unwrap()
            .mass_thickness(&view, &names)
            .unwrap();
        let (a, b) = (log_image(&voxelised), log_image(&meshed));
        let err = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).sum::<f64>() / a.len() as f64;
        let peak = b.iter().copied().fold(0.0, f64::max);
        eprintln!("voxel {voxel} mm: mean |Δ(−log)| {err:.4} (peak {peak:.3})");
        // A label volume's staircase surface converges at first order in the voxel
        // size: each halving must at least nearly halve the error.
        assert!(
            err < 0.6 * previous,
            "voxel {voxel}: {err} after {previous}"
        );
        previous = err;
    }
    assert!(previous < 0.06, "0.5 mm voxels: mean |Δ(−log)| {previous}");
}
