//! A CT given in memory (`prepare_in_memory`: data-set items, the trade-off ladder) renders
//! as the same CT read from a file by `prepare`: the ideal DRR and real detector physics,
//! through the one renderer. The file path converts HU while it decodes the NIfTI, the
//! in-memory path after; both must give the same bytes. And what does not fit is refused.

use glam::{DMat3, DVec3};
use tomograf_physics::acquisition::Acquisition;
use tomograf_scene::{Scene, prepare, prepare_in_memory};
use tomograf_sim::Volume;

/// A 20 × 16 × 12 CT of 3 mm voxels (HU): water, a bone rod and a lung-like block in air.
fn ct() -> Volume {
    let [nx, ny, nz] = [20usize, 16, 12];
    let mut data = Vec::with_capacity(nx * ny * nz);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let (x, y) = (i as f64 - 9.5, j as f64 - 7.5);
                let body = (x / 8.0).powi(2) + (y / 6.0).powi(2) <= 1.0 && (1..11).contains(&k);
                let bone = x.abs() < 1.5 && (y - 3.0).abs() < 1.5;
                let lung = (x + 4.0).abs() < 2.5 && y.abs() < 2.5 && (3..9).contains(&k);
                data.push(match (body, bone, lung) {
                    (false, _, _) => -1000.0,
                    (true, true, _) => 900.0,
                    (true, _, true) => -750.0,
                    _ => 20.0 + (i % 3) as f32,
                });
            }
        }
    }
    Volume::new(
        [nx, ny, nz],
        DVec3::splat(3.0),
        DVec3::new(-30.0, -20.0, 5.0),
        DMat3::IDENTITY,
        data,
    )
    .unwrap()
}

/// Three views of the CT on a 24 × 20 panel; no volume, no physics.
fn views_scene() -> Scene {
    toml::from_str(
        "[geometry]\nsad_mm = 600.0\nsid_mm = 900.0\n\
         [detector]\nrows = 20\ncols = 24\n\
         [views]\nposes = [\"ap\", \"lateral\", \"30,10\"]\n",
    )
    .unwrap()
}

/// Every view's images, concatenated.
fn render_all(p: &tomograf_scene::Prepared) -> Vec<f32> {
    let r = p.renderer().unwrap();
    let mut out = Vec::new();
    for (i, v) in p.job.views.iter().enumerate() {
        for image in r.render(i, v).unwrap().images {
            out.extend(image.data);
        }
    }
    out
}

/// The scene with the CT written to `dir` as its `[volume]`.
fn from_file(dir: &std::path::Path, extra: &str) -> Vec<f32> {
    let path = dir.join("ct.nii.gz");
    tomograf_datasets::nifti::write_nifti(&path, &ct()).unwrap();
    let mut text = format!("[volume]\npath = {:?}\n", path.to_str().unwrap());
    text.push_str(extra);
    let base: Scene = toml::from_str(&text).unwrap();
    let mut scene = views_scene();
    scene.volume = base.volume;
    scene.acquisition = base.acquisition;
    render_all(&prepare(&scene).unwrap())
}

#[test]
fn the_ideal_drr_of_a_ct_in_memory_is_that_of_the_ct_read_from_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let file = from_file(dir.path(), "energy_kev = 70.0\n");
    let mut scene = views_scene();
    scene.volume.energy_kev = Some(70.0);
    let memory = render_all(&prepare_in_memory(&scene, ct(), None).unwrap());
    assert_eq!(file.len(), 3 * 20 * 24);
    assert!(file.iter().any(|&v| v > 0.3), "the views see the CT");
    assert_eq!(file, memory);
}

#[test]
fn real_physics_of_a_ct_in_memory_is_that_of_the_ct_read_from_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let file = from_file(
        dir.path(),
        "[acquisition]\npreset = \"kv-flat-panel-120kvp\"\nseed = 11\n",
    );
    let acq = Acquisition::preset("kv-flat-panel-120kvp").unwrap();
    let prepared = prepare_in_memory(&views_scene(), ct(), Some((acq, 11))).unwrap();
    // Real physics renders the CT itself and hands it back.
    assert_eq!(prepared.volume.data(), ct().data());
    let memory = render_all(&prepared);
    assert_eq!(file.len(), 3 * 20 * 24);
    assert_eq!(file, memory);
}

#[test]
fn what_does_not_fit_a_ct_in_memory_is_refused() {
    let acq = || Some((Acquisition::preset("kv-flat-panel-120kvp").unwrap(), 1));
    // A scene that names a file as well.
    let mut scene = views_scene();
    scene.volume.path = Some("ct.nii.gz".into());
    let e = prepare_in_memory(&scene, ct(), None)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("in memory") && e.contains("ct.nii.gz"), "{e}");
    // Physics given twice: by the scene and with the CT.
    let mut scene = views_scene();
    scene.acquisition.preset = Some("kv-flat-panel-120kvp".into());
    let e = prepare_in_memory(&scene, ct(), acq())
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("must be absent"), "{e}");
    // The monochromatic energy beside a spectrum.
    let mut scene = views_scene();
    scene.volume.energy_kev = Some(60.0);
    let e = prepare_in_memory(&scene, ct(), acq())
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("energy_kev"), "{e}");
    // A renderer of the other kind than the volume was prepared for.
    let ideal = prepare_in_memory(&views_scene(), ct(), None).unwrap();
    let e = ideal
        .renderer_with(tomograf_sim::Projector::Siddon, acq().as_ref())
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("ideal DRR") && e.contains("mu"), "{e}");
}
