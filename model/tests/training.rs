//! Training and inference in the `tiny` configuration (release builds: a few seconds).

mod common;

use tomograf_model::baseline::MeanVolume;
use tomograf_model::checkpoint;
use tomograf_model::config::{TrainConfig, Tune};
use tomograf_model::field::{Codes, Tuned};
use tomograf_model::reconstruct::{Reference, reconstruct, render_volume};
use tomograf_model::train::{Trainer, projection_scale};
use tomograf_sim::Pose;

fn device() -> burn::tensor::Device {
    tomograf_model::backend::device("flex").unwrap()
}

#[test]
fn same_seed_same_run_and_resume_continues_exactly() {
    let items = vec![common::item(16, 4, 16, 0.0), common::item(16, 4, 16, -0.2)];
    let config = TrainConfig::load("tiny").unwrap();
    let scale = projection_scale(&items).unwrap();
    let dev = device();
    let run = |steps: usize| {
        let mut t = Trainer::new(config.clone(), scale, &dev).unwrap();
        (0..steps)
            .map(|_| t.step(&items).unwrap())
            .collect::<Vec<_>>()
    };
    let a = run(3);
    let b = run(3);
    assert_eq!(a, b, "same seed, same losses");
    assert!(
        a.iter()
            .all(|m| m.loss_d.is_finite() && m.loss_g.is_finite())
    );

    // Save after 2 steps, load, take the third: identical to the unbroken run.
    let dir = tempfile::tempdir().unwrap();
    let ck = dir.path().join("checkpoint");
    let mut t = Trainer::new(config.clone(), scale, &dev).unwrap();
    t.step(&items).unwrap();
    t.step(&items).unwrap();
    let mean = MeanVolume::from_volumes(items.iter().filter_map(|i| i.ct.as_ref())).unwrap();
    checkpoint::save(&t, items[0].scale, Some(&mean), &ck).unwrap();
    let (mut r, state) = checkpoint::load_trainer(&ck, &dev).unwrap();
    assert_eq!(state.iteration, 2);
    assert_eq!(
        r.step(&items).unwrap(),
        a[2],
        "resumed step equals the unbroken run's"
    );
    let m = checkpoint::load_mean(&ck).unwrap().unwrap();
    assert_eq!((m.dims, &m.data), (mean.dims, &mean.data));

    // The same two steps from scratch write the same checkpoint bytes (parameter ids are
    // numbered, optimizer tensors sorted), and saving what was loaded changes nothing.
    let again = dir.path().join("again");
    let mut t2 = Trainer::new(config.clone(), scale, &dev).unwrap();
    t2.step(&items).unwrap();
    t2.step(&items).unwrap();
    checkpoint::save(&t2, items[0].scale, Some(&mean), &again).unwrap();
    let resaved = dir.path().join("resaved");
    let (loaded, _) = checkpoint::load_trainer(&ck, &dev).unwrap();
    checkpoint::save(&loaded, items[0].scale, Some(&mean), &resaved).unwrap();
    for name in [
        "generator.bpk",
        "d1.bpk",
        "d2.bpk",
        "opt_g.bpk",
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
    let (_, _, g) = checkpoint::load_generator(&ck, &dev).unwrap();
    let ct = items[0].ct.as_ref().unwrap();
    let codes = || {
        Codes::new(
            (0..config.model.z_shape).map(|i| i as f32 * 0.1).collect(),
            vec![0.5; config.model.z_app],
            1,
            &dev,
        )
    };
    let v1 = render_volume(
        &Tuned {
            field: t.field.clone(),
            codes: codes(),
        },
        ct,
        Pose::AP,
        &dev,
    )
    .unwrap();
    let v2 = render_volume(
        &Tuned {
            field: g,
            codes: codes(),
        },
        ct,
        Pose::AP,
        &dev,
    )
    .unwrap();
    assert_eq!(v1.data(), v2.data());
}

#[test]
fn inference_loss_falls_when_fitting_one_volume() {
    // Gradients flow from the projection loss through the renderer into codes and field.
    let item = common::item(16, 4, 16, 0.0);
    let mut config = TrainConfig::load("tiny").unwrap();
    config.infer.iterations = 40;
    config.infer.psnr_threshold = 99.0;
    let dev = device();
    let scale = projection_scale(std::slice::from_ref(&item)).unwrap();
    let t = Trainer::new(config.clone(), scale, &dev).unwrap();
    let refs: Vec<Reference> = (0..2)
        .map(|i| Reference {
            view: item.views[i],
            pose: item.poses[i],
            image: item.projection(i).to_vec(),
        })
        .collect();
    let ct = item.ct.as_ref().unwrap();
    for tune in [Tune::CodesAndGenerator, Tune::Codes] {
        let mut infer = config.infer.clone();
        infer.tune = tune;
        let rec = reconstruct(
            t.field.clone(),
            &config,
            scale,
            &item.scale,
            &refs,
            ct,
            &infer,
            7,
            &dev,
            |_, _| {},
        )
        .unwrap();
        assert_eq!(rec.iterations, 40);
        let first: f64 = rec.losses[..5].iter().sum::<f64>() / 5.0;
        let last: f64 = rec.losses[35..].iter().sum::<f64>() / 5.0;
        assert!(last < first - 0.1, "{tune:?}: loss {first} → {last}");
        assert_eq!(rec.volume.dims(), ct.dims());
        assert!(rec.volume.data().iter().all(|v| v.is_finite() && *v >= 0.0));
    }
}

#[test]
fn wrong_inputs_are_named() {
    let item = common::item(16, 2, 16, 0.0);
    let config = TrainConfig::load("tiny").unwrap();
    let dev = device();
    let t = Trainer::new(config.clone(), 1.0, &dev).unwrap();
    let ct = item.ct.as_ref().unwrap();
    let run = |refs: &[Reference]| {
        reconstruct(
            t.field.clone(),
            &config,
            1.0,
            &item.scale,
            refs,
            ct,
            &config.infer,
            0,
            &dev,
            |_, _| {},
        )
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
    assert!(Trainer::new(config.clone(), 0.0, &dev).is_err());
    let mut no_ct = item.clone();
    no_ct.ct = None;
    let mut t2 = Trainer::new(config, 1.0, &dev).unwrap();
    let e = t2.step(&[no_ct]).unwrap_err().to_string();
    assert!(e.contains("needs the ground-truth CT"), "{e}");
    let e = tomograf_model::data::load_item(std::path::Path::new("/nonexistent/item"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("item.json"), "{e}");
}
