//! The report's paired differences: TomoGRAF against the best baseline of each cell and, in
//! the realism gap, each model against the one trained on the first level, over the same test
//! items (mean ± the 95 % t-interval's half-width; bold where it excludes zero).

use super::super::render::Block;
use super::super::{Kind, Study, VIEWS};
use super::{Metric, Stat, find};
use crate::paired::Paired;

/// The baselines TomoGRAF is compared with: those of its model's cell (made from its
/// training set; `true`), then the classical ones.
const BASELINES: [(&str, bool); 5] = [
    ("mean training volume", true),
    ("PCA-MAP prior", true),
    ("SART-TV from the mean", true),
    ("FDK", false),
    ("SART-TV", false),
];

/// `a` − `b` in PSNR and SSIM, paired over their common items.
fn paired_psnr_ssim(a: &Stat, b: &Stat) -> (Option<Paired>, Option<Paired>) {
    let d = |m| Paired::of(&a.per_item(m), &b.per_item(m));
    (d(Metric::Psnr), d(Metric::Ssim))
}

/// Paired differences over the test items, with 95 % t-intervals: TomoGRAF against the best
/// baseline of each cell and, in the realism gap, each model against the first.
pub(super) fn paired_tables(study: &Study, stats: &[Stat]) -> Vec<Block> {
    let s = &study.settings;
    let cell = |p: Option<Paired>, digits: usize| p.map_or("—".into(), |p| p.format(digits));
    let (mut shown, mut resolved) = (0, 0);
    let mut count = |p: &Option<Paired>| {
        if let Some(p) = p {
            shown += 1;
            resolved += usize::from(p.resolved());
        }
    };
    let mut best_rows = Vec::new();
    for test in &s.test_sets {
        for v in VIEWS {
            for t in &s.train_sets {
                let Some(ours) = find(stats, Some(t), test, v, "TomoGRAF") else {
                    continue;
                };
                let best = BASELINES
                    .iter()
                    .filter_map(|(b, own)| find(stats, own.then_some(t.as_str()), test, v, b))
                    .max_by(|a, b| {
                        a.mean_std(Metric::Psnr)
                            .0
                            .total_cmp(&b.mean_std(Metric::Psnr).0)
                    });
                let Some(best) = best else { continue };
                let (psnr, ssim) = paired_psnr_ssim(ours, best);
                count(&psnr);
                count(&ssim);
                best_rows.push(vec![
                    format!("`{test}`"),
                    v.to_string(),
                    format!("`{t}`"),
                    best.method.clone(),
                    cell(psnr, 2),
                    cell(ssim, 3),
                    psnr.map_or(0, |p| p.n).to_string(),
                ]);
            }
        }
    }
    let mut b = vec![Block::Heading("Paired differences".into())];
    let mut level_rows = Vec::new();
    if s.kind == Kind::RealismGap && s.train_sets.len() > 1 {
        let first = &s.train_sets[0];
        for test in &s.test_sets {
            for v in VIEWS {
                let Some(base) = find(stats, Some(first), test, v, "TomoGRAF") else {
                    continue;
                };
                for t in &s.train_sets[1..] {
                    let Some(other) = find(stats, Some(t), test, v, "TomoGRAF") else {
                        continue;
                    };
                    let (psnr, ssim) = paired_psnr_ssim(other, base);
                    count(&psnr);
                    count(&ssim);
                    level_rows.push(vec![
                        format!("`{test}`"),
                        v.to_string(),
                        format!("`{t}` − `{first}`"),
                        cell(psnr, 2),
                        cell(ssim, 3),
                    ]);
                }
            }
        }
    }
    b.push(Block::Para(format!(
        "Differences paired over the test items (the same items in both), mean ± the \
         half-width of its 95 % t-interval; **bold**: the interval excludes zero (resolved). \
         {resolved} of the {shown} differences below are resolved; the others cannot be told \
         from the spread between items. {}",
        if study.pool.is_empty() {
            "One training run per model: the intervals cover the test items, not the training \
             seed (pool runs with other seeds with `--stage report --pool`)."
        } else {
            "Pooled over training seeds: the pairs of every seed are taken as one sample, so \
             the seeds' variation enters the spread (an effect shared by all items of one seed \
             would make the interval somewhat too narrow)."
        }
    )));
    b.push(Block::Table(
        [
            "test set",
            "views",
            "model",
            "best baseline (by mean PSNR)",
            "Δ PSNR (dB), TomoGRAF − baseline",
            "Δ SSIM",
            "items",
        ]
        .map(String::from)
        .to_vec(),
        best_rows,
    ));
    if !level_rows.is_empty() {
        b.push(Block::Para(
            "What training on a realism level buys: TomoGRAF trained on each level against \
             TomoGRAF trained on the first, on the same test items."
                .into(),
        ));
        b.push(Block::Table(
            ["test set", "views", "models", "Δ PSNR (dB)", "Δ SSIM"]
                .map(String::from)
                .to_vec(),
            level_rows,
        ));
    }
    b
}
