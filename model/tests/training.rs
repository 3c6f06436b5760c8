//! Training and inference in the `tiny` configuration (release builds: a few seconds).

mod common;

use tomograf_model::baseline::MeanVolume;
use tomograf_model::checkpoint;
use tomograf_model::config::{RefineGate, TrainConfig, Tune};
use tomograf_model::data::Item;
use tomograf_model::field::{Codes, Tuned};
use tomograf_model::prior::CodeStats;
use tomograf_model::reconstruct::{Reference, reconstruct, render_volume};
use tomograf_model::refine::StartWeights;
use tomograf_model::train::{Trainer, projection_scale};
use tomograf_sim::Pose;

fn device() -> burn::tensor::Device {
    tomograf_model::backend::device("flex").unwrap()
}

fn mean_of(items: &[Item]) -> MeanVolume {
    MeanVolume::from_volumes(items.iter().filter_map(|i| i.ct.as_ref())).unwrap()
}

fn ids(items: &[Item]) -> Vec<String> {
    items.iter().map(|i| i.id.clone()).collect()
}

fn trainer(config: &TrainConfig, items: &[Item], scale: f64) -> Trainer {
    Trainer::new(config.clone(), scale, mean_of(items), ids(items), &device()).unwrap()
}

fn refs_of(item: &Item, views: &[usize]) -> Vec<Reference> {
    views
        .iter()
        .map(|&i| Reference {
            view: item.views[i],
            pose: item.poses[i],
            image: item.projection(i).to_vec(),
        })
        .collect()
}

/// Two distinct items (the dense sphere moved), the `tiny` config.
fn two_items() -> (Vec<Item>, TrainConfig, f64) {
    let items = vec![common::item(16, 4, 16, 0.0), common::item(16, 4, 16, -0.5)];
    let config = TrainConfig::load("tiny").unwrap();
    let scale = projection_scale(&items).unwrap();
    (items, config, scale)
}

#[test]
fn same_seed_same_run_and_resume_continues_exactly() {
    // `tiny` has a small adversarial weight, so D1, D2 and their optimisers are exercised.
    let (items, config, scale) = two_items();
    assert!(config.w_adversarial > 0.0);
    let dev = device();
    let run = |steps: usize| {
        let mut t = trainer(&config, &items, scale);
        (0..steps)
            .map(|_| t.step(&items).unwrap())
            .collect::<Vec<_>>()
    };
    let a = run(3);
    let b = run(3);
    assert_eq!(a, b, "same seed, same losses");
    assert!(
        a.iter()
            .all(|m| m.loss_d.is_finite() && m.loss_g.is_finite() && m.loss_d > 0.0)
    );

    // Save after 2 steps, load, take the third: identical to the unbroken run.
    let dir = tempfile::tempdir().unwrap();
    let ck = dir.path().join("checkpoint");
    let mut t = trainer(&config, &items, scale);
    t.step(&items).unwrap();
    t.step(&items).unwrap();
    checkpoint::save(&t, items[0].scale, &ck).unwrap();
    let (mut r, state) = checkpoint::load_trainer(&ck, &dev).unwrap();
    assert_eq!(state.iteration, 2);
    assert_eq!(
        r.step(&items).unwrap(),
        a[2],
        "resumed step equals the unbroken run's"
    );
    let m = checkpoint::load_mean(&ck).unwrap().unwrap();
    assert_eq!(m, mean_of(&items));

    // The same two steps from scratch write the same checkpoint bytes (parameter ids are
    // numbered, optimizer tensors sorted), and saving what was loaded changes nothing.
    let again = dir.path().join("again");
    let mut t2 = trainer(&config, &items, scale);
    t2.step(&items).unwrap();
    t2.step(&items).unwrap();
    checkpoint::save(&t2, items[0].scale, &again).unwrap();
    let resaved = dir.path().join("resaved");
    let (loaded, _) = checkpoint::load_trainer(&ck, &dev).unwrap();
    checkpoint::save(&loaded, items[0].scale, &resaved).unwrap();
    for name in [
        "generator.bpk",
        "codes.bpk",
        "codes.json",
        "d1.bpk",
        "d2.bpk",
        "opt_g.bpk",
        "opt_codes.bpk",
        "opt_d1.bpk",
        "opt_d2.bpk",
        "mean_volume.npy",
    ] {
        let bytes = std::fs::read(ck.join(name)).unwrap();
        assert!(
            bytes == std::fs::read(again.join(name)).unwrap(),
            "{name}: same seed, other bytes"
        );
        assert!(
            bytes == std::fs::read(resaved.join(name)).unwrap(),
            "{name}: changed by load + save"
        );
    }

    // Generator round trip: identical rendered volumes, bit for bit.
    let g = checkpoint::load_generator(&ck, &dev).unwrap();
    assert_eq!(g.codes.stats, t.code_stats());
    let ct = items[0].ct.as_ref().unwrap();
    let codes = || {
        Codes::new(
            (0..config.model.z_shape).map(|i| i as f32 * 0.1).collect(),
            vec![0.5; config.model.z_app],
            1,
            &dev,
        )
    };
    let stats = t.code_stats();
    let v1 = render_volume(
        &Tuned {
            field: t.field.clone(),
            codes: codes(),
        },
        &stats,
        &t.prior,
        ct,
        Pose::AP,
        &dev,
    )
    .unwrap();
    let v2 = render_volume(
        &Tuned {
            field: g.field,
            codes: codes(),
        },
        &g.codes.stats,
        &g.prior,
        ct,
        Pose::AP,
        &dev,
    )
    .unwrap();
    assert_eq!(v1.data(), v2.data());
}

#[test]
fn untrained_model_renders_the_mean_volume() {
    // The last layer starts at zero: density = the mean training volume, whatever the codes.
    let (items, config, scale) = two_items();
    let t = trainer(&config, &items, scale);
    let dev = device();
    let mean = mean_of(&items);
    let ct = items[0].ct.as_ref().unwrap();
    for fill in [0.0f32, 1.7] {
        let codes = Codes::new(
            vec![fill; config.model.z_shape],
            vec![-fill; config.model.z_app],
            1,
            &dev,
        );
        let v = render_volume(
            &Tuned {
                field: t.field.clone(),
                codes,
            },
            &CodeStats::standard(config.model.z_shape, config.model.z_app),
            &t.prior,
            ct,
            Pose::AP,
            &dev,
        )
        .unwrap();
        let worst = v
            .data()
            .iter()
            .zip(&mean.data)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(
            worst <= 1e-5,
            "untrained field differs from the mean by {worst}"
        );
    }
    // And the mean differs from each item, so the check above is not trivially true.
    let d: f32 = ct
        .data()
        .iter()
        .zip(&mean.data)
        .map(|(a, b)| (a - b).abs())
        .sum();
    assert!(d > 1.0, "{d}");
}

/// Trains `tiny` without adversarial terms, with volume-loss weight `w_volume`, on `items`
/// for `steps`; returns the trainer and the first and last 10 steps' mean volume L1.
fn overfit(items: &[Item], steps: usize, w_volume: f64) -> (Trainer, f64, f64) {
    let mut config = TrainConfig::load("tiny").unwrap();
    config.w_adversarial = 0.0;
    config.w_volume = w_volume;
    config.lr_g = 2e-3;
    config.lr_codes = 2e-2;
    let scale = projection_scale(items).unwrap();
    let mut t = trainer(&config, items, scale);
    let l1: Vec<f64> = (0..steps)
        .map(|_| t.step(items).unwrap().l1_volume)
        .collect();
    let first = l1[..10].iter().sum::<f64>() / 10.0;
    let last = l1[steps - 10..].iter().sum::<f64>() / 10.0;
    (t, first, last)
}

#[test]
fn auto_decoder_overfits_two_items_and_inference_finds_their_codes() {
    let (items, _, _) = two_items();
    let (t, first, last) = overfit(&items, 300, 1.0);
    // Paired supervision: the volume L1 at the sampled points falls below a third of where
    // it started (the mean volume's error). Without the volume term and with the projection
    // term alone it falls far less (checked below), so this can fail.
    assert!(last < first / 3.0, "volume L1 {first} → {last}");
    let (_, first_p, last_p) = overfit(&items, 300, 0.0);
    assert!(
        last_p > last * 1.5,
        "projection-only {first_p} → {last_p}, paired {last}"
    );

    // Inference from item 1's own projections moves its codes from the mean code towards
    // item 1's trained code, and away from item 0's (the mean code is equidistant from both).
    let dir = tempfile::tempdir().unwrap();
    let ck = dir.path().join("ck");
    checkpoint::save(&t, items[0].scale, &ck).unwrap();
    let dev = device();
    let generator = checkpoint::load_generator(&ck, &dev).unwrap();
    let table = generator.codes.clone();
    let mut infer = generator.config.infer.clone();
    infer.tune = Tune::Codes;
    infer.iterations = 60;
    infer.code_iterations = 60;
    infer.psnr_threshold = 99.0;
    let item = &items[1];
    let rec = reconstruct(
        generator,
        &refs_of(item, &[0, 1]),
        item.ct.as_ref().unwrap(),
        &infer,
        3,
        &dev,
        |_, _| {},
    )
    .unwrap();
    let whitened = |z: (&[f32], &[f32])| {
        let (a, b) = table.stats.whiten(z.0, z.1);
        a.into_iter().chain(b).collect::<Vec<f32>>()
    };
    let dist = |a: &[f32], b: &[f32]| -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| f64::from(x - y).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let fitted = whitened((&rec.codes.0, &rec.codes.1));
    let own = whitened(table.code_of(&item.id).unwrap());
    let other = whitened(table.code_of(&items[0].id).unwrap());
    let start = vec![0.0f32; own.len()];
    let (d_start, d_own, d_other) = (
        dist(&start, &own),
        dist(&fitted, &own),
        dist(&fitted, &other),
    );
    // Measured: 2.83 → 2.42 towards its own code, 3.58 from the other's (2.83 at the start).
    assert!(
        d_own < 0.9 * d_start && d_other > d_start && d_own < d_other,
        "whitened distances: start→own {d_start}, fitted→own {d_own}, fitted→other {d_other}"
    );
}

/// An untrained `tiny` model of one item (the mean of one volume is that volume, so the
/// model renders it), saved as `ck` in a temporary folder, and another item to fit (the
/// dense sphere moved).
fn one_item_checkpoint() -> (Item, Item, TrainConfig, tempfile::TempDir) {
    let item = common::item(16, 4, 16, 0.0);
    let items = std::slice::from_ref(&item);
    let config = TrainConfig::load("tiny").unwrap();
    let scale = projection_scale(items).unwrap();
    let t = trainer(&config, items, scale);
    let dir = tempfile::tempdir().unwrap();
    checkpoint::save(&t, item.scale, &dir.path().join("ck")).unwrap();
    (item, common::item(16, 4, 16, -0.5), config, dir)
}

#[test]
fn inference_loss_falls_when_fitting_one_volume() {
    // Gradients flow from the projection loss through the renderer into codes and field.
    let (item, other, config, dir) = one_item_checkpoint();
    let ck = dir.path().join("ck");
    let dev = device();
    let ct = item.ct.as_ref().unwrap();
    for tune in [Tune::CodesAndGenerator, Tune::Codes] {
        let mut infer = config.infer.clone();
        infer.tune = tune;
        infer.iterations = 40;
        infer.code_iterations = 10;
        infer.psnr_threshold = 99.0;
        let generator = checkpoint::load_generator(&ck, &dev).unwrap();
        let rec = reconstruct(
            generator,
            &refs_of(&other, &[0, 1]),
            ct,
            &infer,
            7,
            &dev,
            |_, _| {},
        )
        .unwrap();
        assert_eq!(rec.iterations, 40);
        assert_eq!(rec.psnr.len(), 2);
        let first: f64 = rec.losses[..5].iter().sum::<f64>() / 5.0;
        let last: f64 = rec.losses[35..].iter().sum::<f64>() / 5.0;
        assert!(last < first - 0.05, "{tune:?}: loss {first} → {last}");
        assert_eq!(rec.volume.dims(), ct.dims());
        assert!(rec.volume.data().iter().all(|v| v.is_finite()));
    }
    // A threshold reached at the first check stops there.
    let mut infer = config.infer.clone();
    infer.psnr_threshold = -100.0;
    infer.check_every = 3;
    let generator = checkpoint::load_generator(&ck, &dev).unwrap();
    let rec = reconstruct(
        generator,
        &refs_of(&other, &[0]),
        ct,
        &infer,
        7,
        &dev,
        |_, _| {},
    )
    .unwrap();
    assert_eq!(rec.iterations, 3);
}

#[test]
fn refinement_brings_the_network_volume_to_the_views() {
    // An untrained model renders its mean volume (the first item); the views are of another
    // one. SART-TV started from the network's volume must fit those views better and move
    // the volume towards the item they show; 0 sweeps, or a gate the network's projections
    // pass, must leave the network's volume.
    let (item, other, config, dir) = one_item_checkpoint();
    let ck = dir.path().join("ck");
    let dev = device();
    let truth = other.ct.as_ref().unwrap();
    let run_always = |refine: usize, below_db: f64, weight: f64, always: Option<usize>| {
        let mut infer = config.infer.clone();
        infer.refine_always_from_views = always;
        infer.refine_start_weight = weight;
        infer.tune = Tune::Codes;
        infer.iterations = 2;
        infer.lr_codes = 0.0;
        infer.psnr_threshold = 99.0;
        infer.refine_iterations = refine;
        infer.refine_below_db = below_db;
        let generator = checkpoint::load_generator(&ck, &dev).unwrap();
        reconstruct(
            generator,
            &refs_of(&other, &[0, 1]),
            truth,
            &infer,
            7,
            &dev,
            |_, _| {},
        )
        .unwrap()
    };
    let run_from =
        |refine: usize, below_db: f64, weight: f64| run_always(refine, below_db, weight, None);
    let run = |refine: usize, below_db: f64| run_from(refine, below_db, 1.0);
    let rmse = |v: &[f32]| {
        let s: f64 = v
            .iter()
            .zip(truth.data())
            .map(|(&a, &b)| f64::from(a - b).powi(2))
            .sum();
        (s / v.len() as f64).sqrt()
    };
    let (plain, refined) = (run(0, f64::INFINITY), run(10, f64::INFINITY));
    assert!(plain.network.is_none());
    let net = refined
        .network
        .as_ref()
        .expect("the network's volume is kept");
    assert!(net.refined);
    assert_eq!(net.volume.data(), plain.volume.data());
    assert_eq!(net.psnr, plain.psnr);
    // The start weight is used: from half the network's volume (the default) the sweeps
    // end elsewhere, still fitting the views better than the network alone.
    let half = run_from(10, f64::INFINITY, 0.5);
    assert_ne!(half.volume.data(), refined.volume.data());
    for (p, h) in plain.psnr.iter().zip(&half.psnr) {
        assert!(
            h > p,
            "projection PSNR {p} dB → {h} dB from half the volume"
        );
    }
    // Views the network explains (every view's PSNR above the gate) are not refined.
    let gated = run(10, -100.0);
    assert!(!gated.network.as_ref().unwrap().refined);
    assert_eq!(gated.volume.data(), plain.volume.data());
    // From `refine_always_from_views` views on they are, from the whole network volume
    // whatever the configured start weight (here ½); with fewer views the gate decides.
    let always = run_always(10, -100.0, 0.5, Some(2));
    assert!(always.network.as_ref().unwrap().refined);
    assert_eq!(always.volume.data(), refined.volume.data());
    let fewer = run_always(10, -100.0, 0.5, Some(3));
    assert!(!fewer.network.as_ref().unwrap().refined);
    assert_eq!(fewer.volume.data(), plain.volume.data());
    // With zero-rate codes and an untrained generator, no refinement = the mean volume.
    let mean = item.ct.as_ref().unwrap().data();
    let off = plain
        .volume
        .data()
        .iter()
        .zip(mean)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(
        off < 1e-5,
        "unrefined volume differs from the mean by {off}"
    );
    for (p, r) in plain.psnr.iter().zip(&refined.psnr) {
        assert!(
            *r > p + 3.0,
            "projection PSNR {p} dB → {r} dB after refinement"
        );
    }
    let (e0, e1) = (rmse(plain.volume.data()), rmse(refined.volume.data()));
    assert!(e1 < 0.8 * e0, "volume RMSE {e0} → {e1} after refinement");
    let eh = rmse(half.volume.data());
    assert!(
        eh < e0,
        "volume RMSE {e0} → {eh} after refinement from half the volume"
    );
}

/// Inference settings for the left-out-view tests: the one-item checkpoint's, codes only at
/// zero rate for two iterations (the network renders its mean volume), 5 sweeps, the start
/// chosen by left-out views among ½ × network, ½ + ½ and the mean.
fn held_out_infer(config: &TrainConfig) -> tomograf_model::config::InferConfig {
    let mut infer = config.infer.clone();
    infer.refine_start = tomograf_model::config::RefineStart::HeldOut;
    infer.refine_start_weight = 0.5;
    infer.refine_start_mean_weight = 0.0;
    infer.tune = Tune::Codes;
    infer.iterations = 2;
    infer.lr_codes = 0.0;
    infer.psnr_threshold = 99.0;
    infer.refine_iterations = 5;
    infer
}

/// `refine_start = "held-out"`: with views of the mean training volume itself (the
/// one-item model's mean) a start holding the whole mean predicts a left-out view better
/// than half the network's volume (the configured start), and is chosen; with one view the
/// configured start is used and nothing is left out.
#[test]
fn a_left_out_view_chooses_the_start_of_the_sweeps() {
    let (item, _, config, dir) = one_item_checkpoint();
    let ck = dir.path().join("ck");
    let dev = device();
    let truth = item.ct.as_ref().unwrap();
    let run_capped = |views: &[usize], max_views: usize| {
        let mut infer = held_out_infer(&config);
        infer.held_out_max_views = max_views;
        infer.refine_below_db = f64::INFINITY;
        let generator = checkpoint::load_generator(&ck, &dev).unwrap();
        reconstruct(
            generator,
            &refs_of(&item, views),
            truth,
            &infer,
            7,
            &dev,
            |_, _| {},
        )
        .unwrap()
    };
    let run = |views: &[usize]| run_capped(views, 2);
    let two = run(&[0, 1]);
    let net = two.network.as_ref().unwrap();
    let scores = net.held_out.as_ref().expect("left-out views scored");
    assert_eq!(scores.len(), 3);
    let scores: Vec<(StartWeights, f64)> = scores.iter().map(|&(w, db)| (w.unwrap(), db)).collect();
    assert_eq!((scores[0].0.network, scores[0].0.mean), (0.5, 0.0));
    let chosen = net.start.unwrap();
    assert_ne!((chosen.network, chosen.mean), (0.5, 0.0), "{scores:?}");
    // A start with the best score (½ + ½ and the mean alone both start from the truth
    // here, and both reach the scores' 200 dB floor).
    let top = scores.iter().map(|s| s.1).fold(f64::NEG_INFINITY, f64::max);
    assert!(
        scores.iter().any(|s| s.0 == chosen && s.1 == top),
        "{chosen:?} {scores:?}"
    );
    // The mean alone is the truth here: its left-out view is far better predicted than
    // from half the network's volume (which the kept view cannot complete).
    assert!(scores[2].1 > scores[0].1 + 3.0, "{scores:?}");
    // More views than `held_out_max_views`: the configured start, nothing left out.
    let capped = run_capped(&[0, 1], 1);
    let net = capped.network.as_ref().unwrap();
    assert!(net.held_out.is_none());
    let w = net.start.unwrap();
    assert_eq!((w.network, w.mean), (0.5, 0.0));
    let one = run(&[0]);
    let net = one.network.as_ref().unwrap();
    assert!(net.held_out.is_none());
    let w = net.start.unwrap();
    assert_eq!((w.network, w.mean), (0.5, 0.0));
}

/// `refine_gate = "held-out"`: views left out of the fit decide whether the sweeps run.
/// The untrained network renders its training item (the mean volume) whatever the views
/// show. The two views are opposed (0° and 180°), so the sweeps on one can predict the
/// other. With views of another item the projection gate, told every view is explained
/// (`refine_below_db` = −100 dB), keeps the sweeps from running; the left-out views see
/// that the unswept network volume predicts them worse than the sweeps and open it. With
/// views of the training item itself the unswept volume is the truth and is kept.
#[test]
fn left_out_views_decide_whether_the_sweeps_run() {
    let (item, other, config, dir) = one_item_checkpoint();
    let ck = dir.path().join("ck");
    let dev = device();
    let run = |shown: &Item, gate: RefineGate| {
        let mut infer = held_out_infer(&config);
        infer.refine_gate = gate;
        infer.held_out_max_views = 2;
        infer.refine_below_db = -100.0;
        let generator = checkpoint::load_generator(&ck, &dev).unwrap();
        let truth = shown.ct.as_ref().unwrap();
        reconstruct(
            generator,
            &refs_of(shown, &[0, 2]),
            truth,
            &infer,
            7,
            &dev,
            |_, _| {},
        )
        .unwrap()
    };
    // The projection gate: every view "explained", no sweeps, nothing left out.
    let shut = run(&other, RefineGate::Projection);
    let net = shut.network.as_ref().unwrap();
    assert!(!net.refined && net.held_out.is_none() && net.start.is_none());
    // The held-out gate on views of another item: some sweeps, the best-scored candidate.
    let open = run(&other, RefineGate::HeldOut);
    let net = open.network.as_ref().unwrap();
    let scores = net.held_out.as_ref().expect("left-out views scored");
    assert_eq!(scores.len(), 5, "{scores:?}");
    assert_eq!(scores[0].0, None);
    assert!(net.refined, "{scores:?}");
    let top = scores.iter().map(|s| s.1).fold(f64::NEG_INFINITY, f64::max);
    assert!(
        scores.iter().any(|s| s.0 == net.start && s.1 == top),
        "{:?} {scores:?}",
        net.start
    );
    assert!(scores[0].1 + 1.0 < top, "{scores:?}");
    assert_ne!(open.volume.data(), shut.volume.data());
    // On views of the training item the unswept network volume predicts the left-out views
    // best: no sweeps, the network's volume returned.
    let kept = run(&item, RefineGate::HeldOut);
    let net = kept.network.as_ref().unwrap();
    let scores = net.held_out.as_ref().expect("left-out views scored");
    assert!(!net.refined && net.start.is_none(), "{scores:?}");
    assert_eq!(kept.volume.data(), net.volume.data());
}

#[test]
fn wrong_inputs_are_named() {
    let item = common::item(16, 2, 16, 0.0);
    let items = std::slice::from_ref(&item);
    let config = TrainConfig::load("tiny").unwrap();
    let dev = device();
    let t = trainer(&config, items, 1.0);
    let dir = tempfile::tempdir().unwrap();
    let ck = dir.path().join("ck");
    checkpoint::save(&t, item.scale, &ck).unwrap();
    let ct = item.ct.as_ref().unwrap();
    let run = |refs: &[Reference]| {
        let generator = checkpoint::load_generator(&ck, &dev).unwrap();
        reconstruct(generator, refs, ct, &config.infer, 0, &dev, |_, _| {})
            .unwrap_err()
            .to_string()
    };
    let e = run(&[]);
    assert!(e.contains("view count 0"), "{e}");
    let bad = Reference {
        view: item.views[0],
        pose: item.poses[0],
        image: vec![0.0; 10],
    };
    let e = run(&[bad]);
    assert!(
        e.contains("image has 10 values but its view's detector is 16×16"),
        "{e}"
    );
    assert!(Trainer::new(config.clone(), 0.0, mean_of(items), ids(items), &dev).is_err());
    // Encoding frequencies above the grid's Nyquist limit are refused by name.
    let mut fine = config.clone();
    fine.model.freq_x = 6;
    let e = Trainer::new(fine, 1.0, mean_of(items), ids(items), &dev)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("freq_x = 6") && e.contains("Nyquist"), "{e}");
    let mut no_ct = item.clone();
    no_ct.ct = None;
    let mut t2 = trainer(&config, items, 1.0);
    let e = t2.step(&[no_ct]).unwrap_err().to_string();
    assert!(e.contains("needs the ground-truth CT"), "{e}");
    // Resuming per-item codes on another data set is refused.
    let other = common::item(16, 2, 16, 0.3);
    let e = t2.step(&[other]).unwrap_err().to_string();
    assert!(
        e.contains("not the 1 items this model's codes were learned for"),
        "{e}"
    );
    let e = tomograf_model::data::load_item(std::path::Path::new("/nonexistent/item"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("item.json"), "{e}");

    // A checkpoint without its mean volume, and one whose generator is another preset's.
    let no_mean = dir.path().join("no_mean");
    checkpoint::save(&t, item.scale, &no_mean).unwrap();
    std::fs::remove_file(no_mean.join("mean_volume.npy")).unwrap();
    let e = checkpoint::load_generator(&no_mean, &dev)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("mean_volume.npy") && e.contains("missing"),
        "{e}"
    );
    let other_preset = dir.path().join("other_preset");
    checkpoint::save(&t, item.scale, &other_preset).unwrap();
    let small = TrainConfig::load("small").unwrap();
    std::fs::write(other_preset.join("config.toml"), small.to_toml()).unwrap();
    let e = checkpoint::load_generator(&other_preset, &dev)
        .unwrap_err()
        .to_string();
    assert!(e.contains("code statistics of sizes 8 + 8"), "{e}");
    let mut codes = std::fs::read_to_string(other_preset.join("codes.json")).unwrap();
    codes = codes.replace("\"stats\"", "\"unused\"");
    std::fs::write(other_preset.join("codes.json"), codes).unwrap();
    let e = checkpoint::load_generator(&other_preset, &dev)
        .unwrap_err()
        .to_string();
    assert!(e.contains("codes.json"), "{e}");
}
