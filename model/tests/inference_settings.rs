//! Inference settings beyond the single fit (`tiny` model): `[infer] ensemble` (several fits
//! from drawn starting codes, averaged) and `mean_sweeps_weight` (the final volume shrunk
//! towards SART-TV from the mean, its weight set by the fits' spread and the views'
//! projection PSNR).

mod common;

use std::path::{Path, PathBuf};
use tomograf_model::baseline::{Baseline, MeanVolume, SartTv, SartTvSettings};
use tomograf_model::checkpoint;
use tomograf_model::config::TrainConfig;
use tomograf_model::data::Item;
use tomograf_model::ensemble::{fit_ensemble, member_seed, starting_codes};
use tomograf_model::fit::{fit_network, fit_network_from, projection_psnr};
use tomograf_model::reconstruct::{Blend, Reference, reconstruct};
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

/// `config`'s inference cut short (6 iterations, 3 of them codes alone, no early stop),
/// with the data-consistency sweeps of SART-TV's defaults: what the blend tests run.
fn short_fit_with_sweeps(config: &TrainConfig) -> tomograf_model::config::InferConfig {
    let settings = SartTvSettings::default();
    let mut infer = config.infer.clone();
    infer.iterations = 6;
    infer.code_iterations = 3;
    infer.psnr_threshold = 99.0;
    infer.refine_iterations = settings.sweeps;
    infer.refine_tv_step = settings.tv_step;
    infer
}

/// The baseline "SART-TV from the mean" of the checkpoint in `ck`, made by the baseline's
/// own code.
fn sart_tv_from_mean(
    ck: &Path,
    refs: &[Reference],
    grid: &tomograf_sim::Volume,
    dev: &burn::tensor::Device,
) -> tomograf_sim::Volume {
    let generator = checkpoint::load_generator(ck, dev).unwrap();
    SartTv::from_mean(generator.prior.clone())
        .reconstruct(refs, grid, &generator.state.density_scale)
        .unwrap()
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
    // Its spread: each voxel's standard deviation across the three fits (root-mean-square
    // deviation from their mean), computed here in two passes; none for one fit.
    assert!(one.spread.is_none());
    let sd = three.spread.as_ref().expect("three fits have a spread");
    assert_eq!(sd.dims(), three.volume.dims());
    for (i, &v) in three.volume.data().iter().enumerate() {
        let want = fits.iter().map(|f| f64::from(f[i])).sum::<f64>() / 3.0;
        assert!(
            (f64::from(v) - want).abs() < 1e-6,
            "voxel {i}: {v} against {want}"
        );
        let var = fits
            .iter()
            .map(|f| (f64::from(f[i]) - want).powi(2))
            .sum::<f64>()
            / 3.0;
        assert!(
            (f64::from(sd.data()[i]) - var.sqrt()).abs() < 1e-5,
            "voxel {i}: spread {} against {}",
            sd.data()[i],
            var.sqrt()
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

/// With `mean_sweeps_spread` S and several fits, each voxel blends SART-TV from the mean in
/// with weight W × s² / (s² + S²), s its spread across the fits: where the fits agree the
/// network's volume stays, where they disagree it moves towards the classical one; with one
/// fit nothing is blended; a negative or NaN S is refused by name.
#[test]
fn the_spread_weighted_blend_moves_only_where_the_fits_disagree() {
    let dir = tempfile::tempdir().unwrap();
    let Setup {
        item,
        config,
        ck,
        refs,
        dev,
    } = untrained_one_item(dir.path());
    let grid = item.ct.as_ref().unwrap();
    let run = |w: f64, s: f64, fits: usize| {
        let mut infer = short_fit_with_sweeps(&config);
        infer.ensemble = fits;
        infer.mean_sweeps_weight = w;
        infer.mean_sweeps_spread = s;
        let generator = checkpoint::load_generator(&ck, &dev).unwrap();
        reconstruct(generator, &refs, grid, &infer, 5, &dev, |_, _| {}).unwrap()
    };
    let net = run(0.0, 0.0, 3);
    let sd = net.spread.as_ref().expect("three fits have a spread");
    let mut sorted: Vec<f32> = sd.data().to_vec();
    sorted.sort_by(f32::total_cmp);
    let big = sorted[sorted.len() / 2];
    assert!(big > 1e-4, "the fits agree everywhere: median spread {big}");
    let (w, s) = (0.8, f64::from(big));
    let blended = run(w, s, 3);
    let classical = sart_tv_from_mean(&ck, &refs, grid, &dev);
    let (mut moved_low, mut moved_high) = (0.0f64, 0.0f64);
    for (i, &b) in blended.volume.data().iter().enumerate() {
        let (n, c) = (net.volume.data()[i], classical.data()[i]);
        let v = f64::from(sd.data()[i]).powi(2);
        let wv = (w * v / (v + s * s)) as f32;
        let want = (1.0 - wv) * n + wv * c;
        assert!((b - want).abs() < 1e-6, "voxel {i}: {b} against {want}");
        let moved = f64::from((b - n).abs());
        if sd.data()[i] < big / 4.0 {
            moved_low = moved_low.max(moved / f64::from((c - n).abs()).max(1e-9));
        } else if sd.data()[i] > big * 4.0 {
            moved_high = moved_high.max(moved / f64::from((c - n).abs()).max(1e-9));
        }
    }
    // Where the spread is under a quarter of S the weight is under W / 17; above 4 S, over 16 W / 17.
    assert!(moved_low <= 0.8 / 17.0 + 1e-4, "{moved_low}");
    if sorted[sorted.len() - 1] > big * 4.0 {
        assert!(moved_high >= 0.8 * 16.0 / 17.0 - 1e-4, "{moved_high}");
    }
    // One fit: no spread, so nothing is blended (the constant weight is S = 0's).
    let single = run(w, s, 1);
    assert!(single.spread.is_none());
    assert_eq!(single.volume.data(), run(0.0, 0.0, 1).volume.data());

    for bad_s in [-0.1, f64::NAN] {
        let mut bad = config.clone();
        bad.infer.mean_sweeps_spread = bad_s;
        let e = bad.validate().unwrap_err().to_string();
        assert!(e.contains("infer.mean_sweeps_spread"), "{e}");
    }
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
    let run = |w: f64| {
        let mut infer = short_fit_with_sweeps(&config);
        infer.refine_below_db = 200.0; // the sweeps from the network run too
        infer.mean_sweeps_weight = w;
        let generator = checkpoint::load_generator(&ck, &dev).unwrap();
        reconstruct(generator, &refs, grid, &infer, 5, &dev, |_, _| {}).unwrap()
    };
    let (r0, r1, half) = (run(0.0), run(1.0), run(0.5));
    let generator = checkpoint::load_generator(&ck, &dev).unwrap();
    let state = &generator.state;
    let baseline = sart_tv_from_mean(&ck, &refs, grid, &dev);
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

/// `mean_sweeps_below_db` P with `mean_sweeps_weight_below` W2: when the views' mean
/// projection PSNR (the network volume's, what the blend sees) is below P the blend's W is
/// W2, otherwise W — each byte for byte the plain blend with that weight; with W = 0 the blend
/// runs only below P; the two settings come together or not at all; a W2 outside [0, 1] or a
/// NaN P is refused by name.
#[test]
fn the_blend_takes_its_other_weight_below_the_psnr_threshold() {
    let dir = tempfile::tempdir().unwrap();
    let Setup {
        item,
        config,
        ck,
        refs,
        dev,
    } = untrained_one_item(dir.path());
    let grid = item.ct.as_ref().unwrap();
    let run = |w: f64, below: Option<(f64, f64)>| {
        let mut infer = short_fit_with_sweeps(&config);
        infer.ensemble = 3;
        infer.mean_sweeps_spread = 0.02;
        infer.mean_sweeps_weight = w;
        infer.mean_sweeps_below_db = below.map(|b| b.0);
        infer.mean_sweeps_weight_below = below.map(|b| b.1);
        let generator = checkpoint::load_generator(&ck, &dev).unwrap();
        reconstruct(generator, &refs, grid, &infer, 5, &dev, |_, _| {}).unwrap()
    };
    let net = run(0.0, None);
    let p = net.psnr.iter().sum::<f64>() / net.psnr.len() as f64;
    assert!(p.is_finite(), "{:?}", net.psnr);
    let (plain_lo, plain_hi) = (run(0.2, None), run(0.9, None));
    assert_ne!(plain_lo.volume.data(), plain_hi.volume.data());
    let below = run(0.2, Some((p + 1.0, 0.9)));
    assert_eq!(below.volume.data(), plain_hi.volume.data());
    let above = run(0.2, Some((p - 1.0, 0.9)));
    assert_eq!(above.volume.data(), plain_lo.volume.data());
    assert_eq!(
        run(0.0, Some((p + 1.0, 0.9))).volume.data(),
        plain_hi.volume.data()
    );
    let off = run(0.0, Some((p - 1.0, 0.9)));
    assert_eq!(off.volume.data(), net.volume.data());
    // What ran is recorded: the weight and the PSNR that chose it (the unblended volume's).
    assert_eq!(net.blend, None);
    let blend = |weight| {
        Some(Blend {
            weight,
            views_psnr_db: p,
        })
    };
    assert_eq!(below.blend, blend(0.9));
    assert_eq!(above.blend, blend(0.2));
    assert_eq!(off.blend, None);

    let mut infer = config.infer.clone();
    infer.mean_sweeps_weight = 0.25;
    infer.mean_sweeps_below_db = Some(36.0);
    infer.mean_sweeps_weight_below = Some(1.0);
    assert_eq!(infer.mean_sweeps_weight_for(&[30.0, 41.0]), 1.0);
    assert_eq!(infer.mean_sweeps_weight_for(&[36.0]), 0.25);

    let mut bad = config.clone();
    bad.infer.mean_sweeps_below_db = Some(38.0);
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("go together"), "{e}");
    bad.infer.mean_sweeps_weight_below = Some(1.5);
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("infer.mean_sweeps_weight_below = 1.5"), "{e}");
    bad.infer.mean_sweeps_weight_below = Some(1.0);
    bad.infer.mean_sweeps_below_db = Some(f64::NAN);
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("infer.mean_sweeps_below_db = NaN"), "{e}");
    bad.infer.mean_sweeps_below_db = Some(38.0);
    bad.validate().unwrap();
}
