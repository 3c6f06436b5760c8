//! Inference settings beyond the single fit (`tiny` model): `[infer] ensemble` (several fits
//! from drawn starting codes, averaged) and `mean_sweeps_weight` (the final volume shrunk
//! towards SART-TV from the mean).

mod common;

use std::path::{Path, PathBuf};
use tomograf_model::baseline::{Baseline, MeanVolume, SartTv, SartTvSettings};
use tomograf_model::checkpoint;
use tomograf_model::config::TrainConfig;
use tomograf_model::data::Item;
use tomograf_model::ensemble::{fit_ensemble, member_seed, starting_codes};
use tomograf_model::fit::{fit_network, fit_network_from, projection_psnr};
use tomograf_model::reconstruct::{Reference, reconstruct};
use tomograf_model::train::{Trainer, projection_scale};

/// An untrained `tiny` model of one item saved under `dir`, and two views of another item.
struct Setup {
    item: Item,
    config: TrainConfig,
    ck: PathBuf,
    refs: Vec<Reference>,
    dev: burn::tensor::Device,
}

fn untrained_one_item(dir: &Path) -> Setup {
    let item = common::item(16, 4, 16, 0.0);
    let other = common::item(16, 4, 16, -0.5);
    let items = std::slice::from_ref(&item);
    let config = TrainConfig::load("tiny").unwrap();
    let scale = projection_scale(items).unwrap();
    let dev = tomograf_model::backend::device("flex").unwrap();
    let mean = MeanVolume::from_volumes(items.iter().filter_map(|i| i.ct.as_ref())).unwrap();
    let t = Trainer::new(config.clone(), scale, mean, vec![item.id.clone()], &dev).unwrap();
    let ck = dir.join("ck");
    checkpoint::save(&t, item.scale, &ck).unwrap();
    let refs = [0, 1]
        .iter()
        .map(|&i| Reference {
            view: other.views[i],
            pose: other.poses[i],
            image: other.projection(i).to_vec(),
        })
        .collect();
    Setup {
        item,
        config,
        ck,
        refs,
        dev,
    }
}

/// The ensemble's volume is the voxel-wise mean of its fits, each fit made on its own
/// (first from the mean code with the ensemble's seed, the others from
/// `starting_codes` with their own seeds); one fit is the plain fit, byte for byte; the
/// recorded projection PSNR is the average volume's; the drawn fits differ from the first;
/// `reconstruct` runs every fit's iterations; `ensemble_max_views` below the view count
/// gives the single fit; bad settings are refused by name.
#[test]
fn an_ensemble_is_the_mean_of_its_fits() {
    let dir = tempfile::tempdir().unwrap();
    let Setup {
        item,
        config,
        ck,
        refs,
        dev,
    } = untrained_one_item(dir.path());
    let generator = checkpoint::load_generator(&ck, &dev).unwrap();
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
    // `ensemble_max_views` below the views given: the single fit, byte for byte; at the
    // views given: the ensemble, byte for byte.
    assert_eq!(refs.len(), 2);
    infer.ensemble_max_views = Some(1);
    assert_eq!(infer.ensemble_fits(1), 3);
    let capped = fit_ensemble(&generator, &refs, grid, &infer, seed, &dev, quiet).unwrap();
    assert_eq!(capped.volume.data(), single.volume.data());
    assert_eq!(capped.iterations, single.iterations);
    assert_eq!(capped.psnr, single.psnr);
    infer.ensemble_max_views = Some(2);
    let kept = fit_ensemble(&generator, &refs, grid, &infer, seed, &dev, quiet).unwrap();
    assert_eq!(kept.volume.data(), three.volume.data());
    assert_eq!(kept.iterations, 18);
    infer.ensemble_max_views = None;

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
    let mut bad = config.clone();
    bad.infer.ensemble_max_views = Some(0);
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("infer.ensemble_max_views = 0"), "{e}");
}

/// w = 1 gives the baseline "SART-TV from the mean" (made by the baseline's own code), w = 0
/// the network's volume, w = ½ their voxel-wise midpoint; the recorded projection PSNR is
/// the blend's; a weight outside [0, 1] is refused by name.
#[test]
fn the_blend_runs_from_the_network_to_sart_tv_from_the_mean() {
    let dir = tempfile::tempdir().unwrap();
    let Setup {
        item,
        config,
        ck,
        refs,
        dev,
    } = untrained_one_item(dir.path());
    let grid = item.ct.as_ref().unwrap();
    let settings = SartTvSettings::default();
    let run = |w: f64| {
        let mut infer = config.infer.clone();
        infer.iterations = 6;
        infer.code_iterations = 3;
        infer.psnr_threshold = 99.0;
        infer.refine_iterations = settings.sweeps;
        infer.refine_tv_step = settings.tv_step;
        infer.refine_below_db = 200.0; // the sweeps from the network run too
        infer.mean_sweeps_weight = w;
        let generator = checkpoint::load_generator(&ck, &dev).unwrap();
        reconstruct(generator, &refs, grid, &infer, 5, &dev, |_, _| {}).unwrap()
    };
    let (r0, r1, half) = (run(0.0), run(1.0), run(0.5));
    let generator = checkpoint::load_generator(&ck, &dev).unwrap();
    let state = &generator.state;
    let baseline = SartTv::from_mean(generator.prior.clone())
        .reconstruct(&refs, grid, &state.density_scale)
        .unwrap();
    let max_diff = |a: &[f32], b: &[f32]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0f32, f32::max)
    };
    assert!(max_diff(r1.volume.data(), baseline.data()) < 1e-6);
    // The network's volume (after its own sweeps) differs from the classical one here.
    assert!(max_diff(r0.volume.data(), baseline.data()) > 1e-3);
    for ((&h, &a), &b) in half
        .volume
        .data()
        .iter()
        .zip(r0.volume.data())
        .zip(r1.volume.data())
    {
        assert!(
            (h - 0.5 * (a + b)).abs() < 1e-6,
            "{h} against ({a} + {b}) / 2"
        );
    }
    let psnr =
        projection_psnr(&half.volume, &state.density_scale, &refs, state.proj_scale).unwrap();
    assert_eq!(half.psnr, psnr);
    // The network-only volume reported beside it is the network's, not the blend.
    let net = half.network.as_ref().unwrap();
    assert_eq!(
        net.volume.data(),
        r0.network.as_ref().unwrap().volume.data()
    );

    let mut bad = config.clone();
    bad.infer.mean_sweeps_weight = 1.5;
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("infer.mean_sweeps_weight = 1.5"), "{e}");
    let mut bad = config.clone();
    bad.infer.mean_sweeps_weight = 0.3;
    bad.infer.refine_iterations = 0;
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("needs refine_iterations ≥ 1"), "{e}");
}
