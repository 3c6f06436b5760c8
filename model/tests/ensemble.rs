//! `[infer] ensemble`: several fits from drawn starting codes, averaged (`tiny` model).

mod common;

use tomograf_model::baseline::MeanVolume;
use tomograf_model::checkpoint;
use tomograf_model::config::TrainConfig;
use tomograf_model::ensemble::{fit_ensemble, member_seed, starting_codes};
use tomograf_model::fit::{fit_network, fit_network_from, projection_psnr};
use tomograf_model::reconstruct::{Reference, reconstruct};
use tomograf_model::train::{Trainer, projection_scale};

fn device() -> burn::tensor::Device {
    tomograf_model::backend::device("flex").unwrap()
}

/// The ensemble's volume is the voxel-wise mean of its fits, each fit made on its own
/// (first from the mean code with the ensemble's seed, the others from
/// `starting_codes` with their own seeds); one fit is the plain fit, byte for byte; the
/// recorded projection PSNR is the average volume's; the drawn fits differ from the first;
/// `reconstruct` runs every fit's iterations; bad settings are refused by name.
#[test]
fn an_ensemble_is_the_mean_of_its_fits() {
    let item = common::item(16, 4, 16, 0.0);
    let other = common::item(16, 4, 16, -0.5);
    let items = std::slice::from_ref(&item);
    let config = TrainConfig::load("tiny").unwrap();
    let scale = projection_scale(items).unwrap();
    let dev = device();
    let mean = MeanVolume::from_volumes(items.iter().filter_map(|i| i.ct.as_ref())).unwrap();
    let t = Trainer::new(config.clone(), scale, mean, vec![item.id.clone()], &dev).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let ck = dir.path().join("ck");
    checkpoint::save(&t, item.scale, &ck).unwrap();
    let generator = checkpoint::load_generator(&ck, &dev).unwrap();
    let refs: Vec<Reference> = [0, 1]
        .iter()
        .map(|&i| Reference {
            view: other.views[i],
            pose: other.poses[i],
            image: other.projection(i).to_vec(),
        })
        .collect();
    let grid = item.ct.as_ref().unwrap();
    let mut infer = config.infer.clone();
    infer.iterations = 6;
    infer.code_iterations = 3;
    infer.psnr_threshold = 99.0;
    infer.refine_iterations = 0;
    let seed = 11;
    let quiet = &mut |_: usize, _: f64| {};

    let single = fit_network(&generator, &refs, grid, &infer, seed, &dev, quiet).unwrap();
    let one = fit_ensemble(&generator, &refs, grid, &infer, seed, &dev, quiet).unwrap();
    assert_eq!(one.volume.data(), single.volume.data());
    assert_eq!(one.psnr, single.psnr);

    infer.ensemble = 3;
    infer.ensemble_code_sd = 1.5;
    let three = fit_ensemble(&generator, &refs, grid, &infer, seed, &dev, quiet).unwrap();
    let m = &config.model;
    let starts = starting_codes(seed, 2, 1.5, m.z_shape, m.z_app);
    assert_eq!(starts.len(), 2);
    let mut fits = vec![single.volume.data().to_vec()];
    for (k, start) in (1..).zip(starts.clone()) {
        let f = fit_network_from(
            &generator,
            &refs,
            grid,
            &infer,
            member_seed(seed, k),
            Some(start),
            &dev,
            quiet,
        )
        .unwrap();
        fits.push(f.volume.data().to_vec());
    }
    for (i, &v) in three.volume.data().iter().enumerate() {
        let want = fits.iter().map(|f| f64::from(f[i])).sum::<f64>() / 3.0;
        assert!(
            (f64::from(v) - want).abs() < 1e-6,
            "voxel {i}: {v} against {want}"
        );
    }
    let spread = fits[1]
        .iter()
        .zip(&fits[0])
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(spread > 1e-3, "a drawn start changed nothing: {spread}");
    let state = &generator.state;
    let psnr =
        projection_psnr(&three.volume, &state.density_scale, &refs, state.proj_scale).unwrap();
    assert_eq!(three.psnr, psnr);
    assert_eq!(three.iterations, 18);
    assert_eq!(three.losses.len(), 18);
    // The drawn codes have the asked spread (2 × 16 draws of N(0, 1.5²) per fit here).
    let all: Vec<f64> = starts
        .iter()
        .flat_map(|(s, a)| s.iter().chain(a).map(|&x| f64::from(x)))
        .collect();
    let sd = (all.iter().map(|x| x * x).sum::<f64>() / all.len() as f64).sqrt();
    assert!((1.0..2.0).contains(&sd), "drawn code sd {sd} for 1.5");
    // Same seed, same bytes.
    let again = fit_ensemble(&generator, &refs, grid, &infer, seed, &dev, quiet).unwrap();
    assert_eq!(again.volume.data(), three.volume.data());

    let rec = reconstruct(
        checkpoint::load_generator(&ck, &dev).unwrap(),
        &refs,
        grid,
        &infer,
        seed,
        &dev,
        |_, _| {},
    )
    .unwrap();
    assert_eq!(rec.volume.data(), three.volume.data());
    assert_eq!(rec.iterations, 18);

    let mut bad = config.clone();
    bad.infer.ensemble = 0;
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("infer.ensemble = 0"), "{e}");
    let mut bad = config.clone();
    bad.infer.ensemble_code_sd = f64::NAN;
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("infer.ensemble_code_sd"), "{e}");
}
