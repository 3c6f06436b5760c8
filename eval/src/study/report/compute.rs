//! The report's compute table: what a study cost, from the times its stages recorded — each
//! model's training (its `metrics.csv` logs one iteration's seconds every `log_every`
//! iterations: their mean × the iterations trained) and each evaluation (the seconds every
//! scored method took on every item, as `items/<id>.csv` records them). The data stage and
//! the baselines' search on validation record no times and are not counted.

use super::super::render::Block;
use super::super::{Study, VIEWS};
use crate::evaluation::{NETWORK_ONLY, Row};
use std::path::{Path, PathBuf};

/// Iterations trained and the estimated wall-clock seconds of a training run, from its
/// `metrics.csv` (`iteration,seconds,…`; `None` without one or without rows).
pub(super) fn training_seconds(metrics: &Path) -> Option<(usize, f64)> {
    let text = std::fs::read_to_string(metrics).ok()?;
    let mut last = 0usize;
    let (mut sum, mut n) = (0.0, 0usize);
    for line in text.lines().skip(1) {
        let mut cols = line.split(',');
        let (Some(it), Some(secs)) = (cols.next(), cols.next()) else {
            continue;
        };
        let (Ok(it), Ok(secs)) = (it.parse::<usize>(), secs.parse::<f64>()) else {
            continue;
        };
        last = last.max(it);
        sum += secs;
        n += 1;
    }
    (n > 0).then(|| (last, sum / n as f64 * last as f64))
}

/// A time as a cell: seconds, and minutes or hours to read it by. (Every row that reports a
/// time says "seconds": a resumed study's report differs from an uninterrupted one's in
/// those lines only, as `tests/soak.rs` checks.)
fn time(seconds: f64) -> String {
    if seconds >= 5400.0 {
        format!("{seconds:.0} seconds ({:.1} h)", seconds / 3600.0)
    } else {
        format!("{seconds:.0} seconds ({:.1} min)", seconds / 60.0)
    }
}

/// The compute table over the study folders `roots` (one, or the pooled runs), given the
/// scored rows of every (test set, train set) cell.
pub(super) fn compute_table(
    study: &Study,
    roots: &[PathBuf],
    cells: &[(String, Option<&str>, Vec<Row>)],
) -> Vec<Block> {
    let s = &study.settings;
    let mut rows = Vec::new();
    let mut total = 0.0;
    for train in &s.train_sets {
        let (mut its, mut secs, mut runs) = (0usize, 0.0, 0usize);
        for root in roots {
            if let Some((i, t)) =
                training_seconds(&root.join("models").join(train).join("metrics.csv"))
            {
                (its, secs, runs) = (its + i, secs + t, runs + 1);
            }
        }
        if runs > 0 {
            total += secs;
            rows.push(vec![
                format!("training `{train}`"),
                format!("{runs} run(s), {its} iterations"),
                time(secs),
            ]);
        }
    }
    for test in &s.test_sets {
        let cell_rows = cells.iter().filter(|(t, _, _)| t == test);
        let (mut secs, mut n) = (0.0, 0usize);
        for (_, _, scored) in cell_rows {
            // The network-only row's time is part of TomoGRAF's own.
            let own = scored.iter().filter(|r| r.method != NETWORK_ONLY);
            secs += own.clone().map(|r| r.seconds).sum::<f64>();
            n += own.count();
        }
        if n > 0 {
            total += secs;
            rows.push(vec![
                format!("evaluation on `{test}`"),
                format!("{n} scores (items × {} view counts × methods)", VIEWS.len()),
                time(secs),
            ]);
        }
    }
    if rows.is_empty() {
        return Vec::new();
    }
    rows.push(vec!["total counted".into(), String::new(), time(total)]);
    vec![
        Block::Heading("Compute".into()),
        Block::Para(format!(
            "Wall-clock times{} as the stages recorded them on the machine that ran them (all \
             its cores unless `--threads` said otherwise; a stage that shared the machine with \
             other jobs reads long): training, one sampled iteration's seconds every few \
             iterations × the iterations trained; evaluation, the seconds each scored method \
             took on each item (TomoGRAF's include its network's). The data stage and the baselines' search on validation are \
             not counted.",
            if roots.len() > 1 {
                format!(", summed over the {} pooled runs,", roots.len())
            } else {
                String::new()
            }
        )),
        Block::Table(
            ["stage", "what", "wall-clock time"]
                .map(String::from)
                .to_vec(),
            rows,
        ),
    ]
}

#[cfg(test)]
mod tests {
    use super::training_seconds;

    /// Iterations from the last row, time as the sampled iterations' mean × iterations.
    #[test]
    fn training_time_is_the_sampled_mean_times_the_iterations() {
        let dir = std::env::temp_dir().join(format!("compute-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let m = dir.join("metrics.csv");
        std::fs::write(
            &m,
            "iteration,seconds,loss_d\n10,0.5,1\n20,0.7,1\n30,0.6,1\nbad,row\n",
        )
        .unwrap();
        let (its, secs) = training_seconds(&m).unwrap();
        assert_eq!(its, 30);
        assert!((secs - 0.6 * 30.0).abs() < 1e-9, "{secs}");
        std::fs::write(&m, "iteration,seconds\n").unwrap();
        assert_eq!(training_seconds(&m), None);
        assert_eq!(training_seconds(&dir.join("none.csv")), None);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
