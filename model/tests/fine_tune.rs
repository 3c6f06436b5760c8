//! Fine-tuning a checkpoint on other items ([`checkpoint::load_trainer_for`]): the
//! networks and their optimiser states come from the checkpoint, the codes and the mean
//! volume from the new items, and the iteration count goes on.

mod common;

use tomograf_model::baseline::MeanVolume;
use tomograf_model::checkpoint;
use tomograf_model::config::TrainConfig;
use tomograf_model::data::Item;
use tomograf_model::render::DensityScale;
use tomograf_model::train::{Trainer, projection_scale};

fn device() -> burn::tensor::Device {
    tomograf_model::backend::device("flex").unwrap()
}

fn mean_of(items: &[Item]) -> MeanVolume {
    MeanVolume::from_volumes(items.iter().filter_map(|i| i.ct.as_ref())).unwrap()
}

fn ids(items: &[Item]) -> Vec<String> {
    items.iter().map(|i| i.id.clone()).collect()
}

fn digests(items: &[Item]) -> Vec<String> {
    items.iter().map(Item::content_sha256).collect()
}

#[test]
fn fine_tuning_starts_from_the_checkpoints_networks_with_the_new_items_codes_and_mean() {
    let dev = device();
    let config = TrainConfig::load("tiny").unwrap();
    let old = vec![common::item(16, 4, 16, 0.0), common::item(16, 4, 16, -0.5)];
    let mut new = vec![
        common::item(16, 4, 16, 0.3),
        common::item(16, 4, 16, 0.6),
        common::item(16, 4, 16, -0.2),
    ];
    for (i, item) in new.iter_mut().enumerate() {
        item.id = format!("new-{i}");
    }
    let scale = projection_scale(&old).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let ck = dir.path().join("checkpoint");
    let mut t = Trainer::new(config.clone(), scale, mean_of(&old), ids(&old), &dev).unwrap();
    for _ in 0..3 {
        t.step(&old).unwrap();
    }
    checkpoint::save(&t, old[0].scale, &ck).unwrap();

    let (mut f, kept) = checkpoint::load_trainer_for(
        &ck,
        None,
        mean_of(&new),
        new[0].scale,
        ids(&new),
        digests(&new),
        &dev,
    )
    .unwrap();
    assert_eq!(kept, 0, "other items get fresh codes");
    assert_eq!(f.iteration, 3, "the iteration count goes on");
    assert_eq!(f.proj_scale, scale, "the checkpoint's projection scale");
    // Saved as loaded: the networks and their optimisers are the checkpoint's, byte for
    // byte; the codes are a fresh run's on the new items; the mean is the new items'.
    let saved = dir.path().join("fine");
    checkpoint::save(&f, new[0].scale, &saved).unwrap();
    let mut fresh = Trainer::new(config.clone(), scale, mean_of(&new), ids(&new), &dev).unwrap();
    fresh.item_sha256 = digests(&new);
    let fresh_dir = dir.path().join("fresh");
    checkpoint::save(&fresh, new[0].scale, &fresh_dir).unwrap();
    let bytes = |d: &std::path::Path, name: &str| std::fs::read(d.join(name)).unwrap();
    for name in [
        "generator.bpk",
        "d1.bpk",
        "d2.bpk",
        "opt_g.bpk",
        "opt_d1.bpk",
        "opt_d2.bpk",
    ] {
        assert!(
            bytes(&saved, name) == bytes(&ck, name),
            "{name}: not the checkpoint's"
        );
        assert!(
            bytes(&saved, name) != bytes(&fresh_dir, name),
            "{name}: a fresh run's (the test cannot tell them apart)"
        );
    }
    for name in [
        "codes.bpk",
        "codes.json",
        "opt_codes.bpk",
        "mean_volume.npy",
    ] {
        assert!(
            bytes(&saved, name) == bytes(&fresh_dir, name),
            "{name}: not a fresh run's on the new items"
        );
    }
    assert_eq!(
        checkpoint::load_mean(&saved).unwrap().unwrap(),
        mean_of(&new)
    );
    assert_ne!(mean_of(&new), mean_of(&old), "the test needs two means");
    // It trains on the new items (and refuses the old ones: their codes are gone).
    let m = f.step(&new).unwrap();
    assert_eq!(m.iteration, 4);
    assert!(m.loss_g.is_finite());
    let e = f.step(&old).unwrap_err().to_string();
    assert!(e.contains("are not the 3 items"), "{e}");

    // Another seed draws other codes.
    let (seeded, _) = checkpoint::load_trainer_for(
        &ck,
        Some(99),
        mean_of(&new),
        new[0].scale,
        ids(&new),
        digests(&new),
        &dev,
    )
    .unwrap();
    let seeded_dir = dir.path().join("seeded");
    checkpoint::save(&seeded, new[0].scale, &seeded_dir).unwrap();
    assert!(bytes(&seeded_dir, "codes.bpk") != bytes(&saved, "codes.bpk"));
    assert!(bytes(&seeded_dir, "generator.bpk") == bytes(&ck, "generator.bpk"));

    // Items in other units (another HU window) are refused, naming both scales.
    let other = DensityScale {
        mu_per_unit: new[0].scale.mu_per_unit * 2.0,
        ..new[0].scale
    };
    let e = checkpoint::load_trainer_for(
        &ck,
        None,
        mean_of(&new),
        other,
        ids(&new),
        digests(&new),
        &dev,
    )
    .err()
    .expect("another density scale is refused")
    .to_string();
    assert!(
        e.contains("density scale") && e.contains("made alike"),
        "{e}"
    );
}

/// Fine-tuned on the very items it learned its codes on (same ids, same content digests),
/// a checkpoint keeps those codes and their optimiser state; a checkpoint without digests,
/// or one item's content changed under its id, gets fresh codes.
#[test]
fn the_same_items_keep_their_learned_codes() {
    let dev = device();
    let config = TrainConfig::load("tiny").unwrap();
    let items = vec![common::item(16, 4, 16, 0.0), common::item(16, 4, 16, -0.5)];
    let scale = projection_scale(&items).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let bytes = |d: &std::path::Path, name: &str| std::fs::read(d.join(name)).unwrap();
    let load = |ck: &std::path::Path, items: &[Item]| {
        checkpoint::load_trainer_for(
            ck,
            None,
            mean_of(items),
            items[0].scale,
            ids(items),
            digests(items),
            &dev,
        )
        .unwrap()
    };
    let saved_as_loaded = |t: &Trainer, name: &str| {
        let d = dir.path().join(name);
        checkpoint::save(t, items[0].scale, &d).unwrap();
        d
    };
    let mut t = Trainer::new(config.clone(), scale, mean_of(&items), ids(&items), &dev).unwrap();
    for _ in 0..3 {
        t.step(&items).unwrap();
    }
    // Without recorded digests: fresh codes.
    let bare = saved_as_loaded(&t, "bare");
    let (f, kept) = load(&bare, &items);
    assert_eq!(kept, 0);
    let fresh = saved_as_loaded(&f, "fresh");
    assert!(bytes(&fresh, "codes.bpk") != bytes(&bare, "codes.bpk"));

    t.item_sha256 = digests(&items);
    let ck = saved_as_loaded(&t, "checkpoint");
    let (f, kept) = load(&ck, &items);
    assert_eq!(kept, 2, "the same items keep their codes");
    let again = saved_as_loaded(&f, "again");
    for name in ["codes.bpk", "opt_codes.bpk", "codes.json", "generator.bpk"] {
        assert!(bytes(&again, name) == bytes(&ck, name), "{name}");
    }

    // One item's projections changed under the same id: that item gets a fresh code (the
    // fresh run's row), the other keeps its learned one; the code optimiser starts afresh.
    let mut changed = items.clone();
    changed[1].projections[7] += 0.25;
    assert_eq!(ids(&changed), ids(&items));
    let (f, kept) = load(&ck, &changed);
    assert_eq!(kept, 1, "an item whose content changed gets a fresh code");
    let redrawn = saved_as_loaded(&f, "redrawn");
    let table = |d: &std::path::Path| checkpoint::read_code_table(d).unwrap();
    let (redrawn, learned, fresh) = (table(&redrawn), table(&ck), table(&fresh));
    assert_eq!(redrawn.shape[0], learned.shape[0]);
    assert_eq!(redrawn.app[0], learned.app[0]);
    assert_eq!(redrawn.shape[1], fresh.shape[1]);
    assert_ne!(redrawn.shape[1], learned.shape[1]);
}

/// Fine-tuned on its items with others added (a training set grown by new phantoms), a
/// checkpoint keeps the learned codes of the items it knows — found by content, wherever
/// they now stand — and draws fresh ones for the new items.
#[test]
fn added_items_get_fresh_codes_and_known_ones_keep_theirs() {
    let dev = device();
    let config = TrainConfig::load("tiny").unwrap();
    let items = vec![common::item(16, 4, 16, 0.0), common::item(16, 4, 16, -0.5)];
    let scale = projection_scale(&items).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut t = Trainer::new(config.clone(), scale, mean_of(&items), ids(&items), &dev).unwrap();
    for _ in 0..3 {
        t.step(&items).unwrap();
    }
    t.item_sha256 = digests(&items);
    let ck = dir.path().join("checkpoint");
    checkpoint::save(&t, items[0].scale, &ck).unwrap();
    // A new item first, then the two known ones renumbered.
    let mut grown = vec![
        common::item(16, 4, 16, 0.4),
        items[1].clone(),
        items[0].clone(),
    ];
    for (i, item) in grown.iter_mut().enumerate() {
        item.id = format!("{i:05}");
    }
    let (mut f, kept) = checkpoint::load_trainer_for(
        &ck,
        None,
        mean_of(&grown),
        grown[0].scale,
        ids(&grown),
        digests(&grown),
        &dev,
    )
    .unwrap();
    assert_eq!(kept, 2);
    let saved = dir.path().join("grown");
    checkpoint::save(&f, grown[0].scale, &saved).unwrap();
    let (now, learned) = (
        checkpoint::read_code_table(&saved).unwrap(),
        checkpoint::read_code_table(&ck).unwrap(),
    );
    assert_eq!(
        (&now.shape[1], &now.app[2]),
        (&learned.shape[1], &learned.app[0])
    );
    assert!(now.shape[0] != learned.shape[0] && now.shape[0] != learned.shape[1]);
    // A fresh run on the grown set draws the same code for the new item.
    let fresh = Trainer::new(config, scale, mean_of(&grown), ids(&grown), &dev).unwrap();
    let fresh_dir = dir.path().join("fresh");
    checkpoint::save(&fresh, grown[0].scale, &fresh_dir).unwrap();
    assert_eq!(
        now.shape[0],
        checkpoint::read_code_table(&fresh_dir).unwrap().shape[0]
    );
    // It trains on the grown set.
    assert!(f.step(&grown).unwrap().loss_g.is_finite());
}
