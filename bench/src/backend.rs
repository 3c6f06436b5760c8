//! `tomograf bench --model --backend NAME`: TomoGRAF on backend NAME (a GPU backend, as
//! compiled in with `--features tomograf-model/cuda` or `…/wgpu`) against the `flex` CPU
//! backend in the same run, interleaved:
//! * agreement: a checkpoint trained a few steps on flex is loaded on both backends; the
//!   same training steps (same batches, same seed) must give the same losses, and the same
//!   1-view reconstruction the same volume, up to floating-point reordering;
//! * speed: seconds per training step of `small` and of the paper's configuration (128³,
//!   8×256 field, adversarial training), and per whole 1-view reconstruction.

use anyhow::{Context, Result, ensure};
use std::fmt::Write as _;
use std::time::Instant;
use tomograf_model::config::TrainConfig;
use tomograf_model::data::Item;
use tomograf_model::reconstruct::reconstruct;
use tomograf_model::{backend, checkpoint};

use crate::model::{self, median, phantoms, tempfile_dir, trainer};

/// Seconds per step of `config` on each device, `steps` steps per measurement, `repeats`
/// interleaved measurements (median), after one warm-up step each.
fn step_seconds(
    config: &TrainConfig,
    items: &[Item],
    devices: [&tomograf_model::Device; 2],
    steps: usize,
    repeats: usize,
) -> Result<[f64; 2]> {
    let mut t = [
        trainer(config.clone(), items, devices[0])?,
        trainer(config.clone(), items, devices[1])?,
    ];
    let mut s: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    for trainer in &mut t {
        trainer.step(items)?;
    }
    for _ in 0..repeats {
        for k in 0..2 {
            let start = Instant::now();
            for _ in 0..steps {
                t[k].step(items)?;
            }
            s[k].push(start.elapsed().as_secs_f64() / steps as f64);
        }
    }
    let [a, b] = s;
    Ok([median(a), median(b)])
}

/// The markdown section comparing backend `name` with flex.
pub fn section(quick: bool, repeats: usize, name: &str) -> Result<String> {
    ensure!(
        name != "flex",
        "--backend flex is the baseline of the comparison: name another backend (compiled in: {})",
        backend::available().join(", ")
    );
    let gpu = backend::device(name)?;
    let cpu = backend::device("flex")?;
    let tmp = tempfile_dir()?;
    let (size, views) = if quick { (16, 10) } else { (64, 36) };
    let items = phantoms(&tmp.join("small"), 8, size, views)?;
    let config = TrainConfig::load(if quick { "tiny" } else { "small" })?;
    let label = config.name.clone();

    // Agreement: one checkpoint, trained 5 steps on flex, continued on both backends.
    let mut t = trainer(config.clone(), &items, &cpu)?;
    for _ in 0..5 {
        t.step(&items)?;
    }
    let ck = tmp.join("checkpoint");
    checkpoint::save(&t, items[0].scale, &ck)?;
    let (mut tc, _) = checkpoint::load_trainer(&ck, &cpu)?;
    let (mut tg, _) = checkpoint::load_trainer(&ck, &gpu)?;
    let agree_steps = 10;
    let mut worst_loss = 0.0f64;
    for _ in 0..agree_steps {
        let (a, b) = (tc.step(&items)?, tg.step(&items)?);
        worst_loss = worst_loss.max((a.loss_g - b.loss_g).abs() / a.loss_g.abs().max(1e-12));
    }
    // The same 1-view reconstruction on both.
    let item = &items[0];
    let refs = vec![model::ap_reference(item)?];
    let truth = item.ct.as_ref().context("bench item has no CT")?;
    let mut rec_s: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    let mut recs = Vec::new();
    for r in 0..repeats.clamp(1, 3) {
        for (k, dev) in [&cpu, &gpu].into_iter().enumerate() {
            let generator = checkpoint::load_generator(&ck, dev)?;
            let infer = generator.config.infer.clone();
            let start = Instant::now();
            let rec = reconstruct(generator, &refs, truth, &infer, 0, dev, |_, _| {})?;
            rec_s[k].push(start.elapsed().as_secs_f64());
            if r == 0 {
                recs.push(rec);
            }
        }
    }
    let (vc, vg) = (recs[0].volume.data(), recs[1].volume.data());
    let max_diff = vc
        .iter()
        .zip(vg)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    let range = vc.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    // Scored as `tomograf evaluate` scores (density clamped to [0, 1]).
    let pc = tomograf_model::metrics::score(item, &recs[0].volume)?.psnr;
    let pg = tomograf_model::metrics::score(item, &recs[1].volume)?.psnr;

    eprintln!(
        "agreement: loss {worst_loss:.2e}, density {max_diff:.2e}, PSNR flex {pc:.3} / {name} \
         {pg:.3}; reconstruction s: flex {:?}, {name} {:?}",
        rec_s[0], rec_s[1]
    );
    // Speed: training steps of `small` (or `tiny`) and of the paper's configuration.
    let steps = if quick { 2 } else { 10 };
    let small = step_seconds(&config, &items, [&cpu, &gpu], steps, repeats.max(1))?;
    eprintln!(
        "training step s ({label}): flex {:.4}, {name} {:.4}",
        small[0], small[1]
    );
    let paper = if quick {
        None
    } else {
        let big = phantoms(&tmp.join("paper"), 4, 128, 36)?;
        let paper = TrainConfig::load("paper")?;
        let p = step_seconds(&paper, &big, [&cpu, &gpu], 1, 2)?;
        eprintln!(
            "training step s (paper): flex {:.4}, {name} {:.4}",
            p[0], p[1]
        );
        Some(p)
    };
    let _ = std::fs::remove_dir_all(&tmp);

    let (ic, ig) = (median(rec_s[0].clone()), median(rec_s[1].clone()));
    let mut md = String::new();
    writeln!(
        md,
        "## TomoGRAF on `{name}` against `flex`\n\n\
         Both backends in one run, interleaved; {size}³ `lidc` phantoms. Agreement: a checkpoint \
         of `{label}` trained 5 steps on `flex`, loaded on both, then {agree_steps} more steps \
         (the same batches) and one 1-view reconstruction (AP, seed 0) on each.\n\n\
         | agreement | value |\n|---|---:|\n\
         | largest relative difference of the generator loss over {agree_steps} steps | {worst_loss:.2e} |\n\
         | largest difference of the reconstructed density (normalised; volume's largest {range:.3}) | {max_diff:.2e} |\n\
         | PSNR of the reconstruction, `flex` / `{name}` (dB) | {pc:.3} / {pg:.3} |\n\n\
         | what | `{name}` s | `flex` s | speed-up |\n|---|---:|---:|---:|\n\
         | training step, `{label}` ({size}³) | {:.4} | {:.4} | {:.2}× |\n\
         | 1-view reconstruction, `{label}` ({} iterations) | {ig:.2} | {ic:.2} | {:.2}× |",
        small[1],
        small[0],
        small[0] / small[1],
        recs[1].iterations,
        ic / ig,
    )?;
    if let Some(p) = paper {
        writeln!(
            md,
            "| training step, `paper` (128³, 8×256 field, D1 + D2) | {:.4} | {:.3} | {:.1}× |",
            p[1],
            p[0],
            p[0] / p[1]
        )?;
    }
    Ok(md)
}
