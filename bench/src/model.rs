//! `tomograf bench --model`: seconds per training and inference iteration of TomoGRAF on
//! this machine, each against a baseline measured in the same run, interleaved:
//! * training: a `small` step (paired supervision, no discriminators) against a
//!   `small-gan` step (the paper's adversarial training, D1 and D2 updated every step);
//! * inference: a whole 1-view reconstruction with the `small` settings (code phase, then
//!   generator tuning, full-volume checks) against SART-TV from the same view.
//!
//! The data are made here (`lidc` phantoms, 64³, 36 views) in a temporary folder; weights
//! are untrained (the cost of an iteration does not depend on them).

use anyhow::{Context, Result};
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;
use tomograf_model::baseline::{Baseline, MeanVolume, SartTv};
use tomograf_model::config::TrainConfig;
use tomograf_model::data::Item;
use tomograf_model::reconstruct::{Reference, reconstruct};
use tomograf_model::train::{Trainer, projection_scale};
use tomograf_model::{backend, checkpoint, data};

pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

pub fn trainer(
    config: TrainConfig,
    items: &[Item],
    device: &tomograf_model::Device,
) -> Result<Trainer> {
    let mean = MeanVolume::from_volumes(items.iter().filter_map(|i| i.ct.as_ref()))?;
    let ids = items.iter().map(|i| i.id.clone()).collect();
    Ok(Trainer::new(
        config,
        projection_scale(items)?,
        mean,
        ids,
        device,
    )?)
}

/// The markdown section: `repeats` interleaved measurements of each (fewer and smaller
/// with `quick`).
pub fn section(quick: bool, repeats: usize) -> Result<String> {
    let tmp = tempfile_dir()?;
    let size = if quick { 16 } else { 64 };
    let views = if quick { 10 } else { 36 };
    let items = phantoms(&tmp, 8, size, views)?;
    let device = backend::device(backend::default_name())?;
    // `--quick`: `tiny` against `tiny` trained as the paper does (random codes, hinge only).
    let (ca, cb) = if quick {
        let a = TrainConfig::load("tiny")?;
        let mut b = a.clone();
        b.name = "tiny, paper's training".into();
        b.codes = tomograf_model::config::CodeMode::Random;
        (b.w_volume, b.w_projection, b.w_adversarial) = (0.0, 0.0, 1.0);
        (a, b)
    } else {
        (TrainConfig::load("small")?, TrainConfig::load("small-gan")?)
    };
    let (a, b) = (ca.name.clone(), cb.name.clone());
    let mut ta = trainer(ca, &items, &device)?;
    let mut tb = trainer(cb, &items, &device)?;
    ta.step(&items)?; // warm-up
    tb.step(&items)?;
    let steps = if quick { 2 } else { 10 };
    let (mut sa, mut sb) = (Vec::new(), Vec::new());
    for _ in 0..repeats.max(1) {
        let t = Instant::now();
        for _ in 0..steps {
            ta.step(&items)?;
        }
        sa.push(t.elapsed().as_secs_f64() / steps as f64);
        let t = Instant::now();
        for _ in 0..steps {
            tb.step(&items)?;
        }
        sb.push(t.elapsed().as_secs_f64() / steps as f64);
    }
    // Inference: the `a` model saved and loaded as a user's checkpoint would be.
    let ck = tmp.join("checkpoint");
    checkpoint::save(&ta, items[0].scale, &ck)?;
    let item = &items[0];
    let refs = vec![ap_reference(item)?];
    let grid = item.ct.as_ref().context("bench item has no CT")?;
    let (mut ia, mut ib, mut iters) = (Vec::new(), Vec::new(), 0);
    let sart = SartTv::from_zero();
    for _ in 0..repeats.clamp(1, 3) {
        let generator = checkpoint::load_generator(&ck, &device)?;
        let infer = generator.config.infer.clone();
        let t = Instant::now();
        let rec = reconstruct(generator, &refs, grid, &infer, 0, &device, |_, _| {})?;
        ia.push(t.elapsed().as_secs_f64());
        iters = rec.iterations;
        let t = Instant::now();
        sart.reconstruct(&refs, grid, &item.scale)?;
        ib.push(t.elapsed().as_secs_f64());
    }
    let _ = std::fs::remove_dir_all(&tmp);
    let (ma, mb, mi, ms) = (median(sa), median(sb), median(ia), median(ib));
    let mut md = String::new();
    writeln!(
        md,
        "## TomoGRAF: seconds per iteration\n\n\
         {} interleaved measurements of {steps} training steps each (median), and {} of a whole \
         1-view reconstruction; {size}³ volumes, {size}² projections, 8 `lidc` phantoms, backend \
         `{}`.\n\n\
         | what | seconds | baseline (same run) | seconds | ratio |\n|---|---:|---|---:|---:|\n\
         | training step, `{a}` | {ma:.3} | training step, `{b}` | {mb:.3} | {:.2} |\n\
         | 1-view inference, `{a}` ({iters} iterations: {:.3} s each) | {mi:.2} | SART-TV, 20 \
         iterations | {ms:.2} | {:.2} |\n",
        repeats.max(1),
        repeats.clamp(1, 3),
        backend::default_name(),
        ma / mb,
        mi / iters.max(1) as f64,
        mi / ms
    )?;
    Ok(md)
}

/// The AP view of a bench item, as a 1-view reconstruction's reference.
pub fn ap_reference(item: &Item) -> Result<Reference> {
    let ap = item
        .find_pose(tomograf_sim::Pose::AP)
        .context("the bench data set has no AP view")?;
    Ok(Reference {
        view: item.views[ap],
        pose: item.poses[ap],
        image: item.projection(ap).to_vec(),
    })
}

/// A `lidc` data set of `phantoms` items, `size`³ with `views` views, made in `dir`.
pub fn phantoms(dir: &Path, phantoms: usize, size: usize, views: usize) -> Result<Vec<Item>> {
    tomograf_scene::dataset::DatasetJob::phantoms(
        dir.to_path_buf(),
        (0, phantoms),
        tomograf_datasets::anatomy::Profile::LidcCropped,
        false,
        (size, views),
        "train",
        None,
    )?
    .run(|_, _| {})?;
    Ok(data::load_dataset(dir, None)?)
}

pub fn tempfile_dir() -> Result<std::path::PathBuf> {
    let p = std::env::temp_dir().join(format!("tomograf-bench-model-{}", std::process::id()));
    if p.exists() {
        std::fs::remove_dir_all(&p)?;
    }
    Ok(p)
}
