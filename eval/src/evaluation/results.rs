//! An evaluation's scores: one row per item, view count and method; the one definition of
//! a results row as CSV (`items/<id>.csv` at full precision, `results.csv` at the report's),
//! and the merge of an evaluation folder's items into `results.csv` and `results.md`.

use super::{Job, item_path};
use anyhow::{Context, Result, bail};
use std::fmt::Write as _;
use std::path::Path;
use tomograf_datasets::atomic::write_atomic;
use tomograf_model::metrics::{Scores, mean_std};

/// One score: an item, a view count, a method.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    pub item: String,
    pub views: usize,
    pub method: String,
    pub scores: Scores,
    pub iterations: usize,
    pub seconds: f64,
}

/// The method name of TomoGRAF's network volume before its data-consistency sweeps (a row
/// only when the checkpoint's inference runs them); "TomoGRAF" is the final volume.
pub const NETWORK_ONLY: &str = "TomoGRAF (network only)";

const ITEM_HEADER: &str =
    "item,views,method,psnr_db,ssim,rmse_hu,iterations,seconds,body_psnr_db,body_ssim,body_rmse_hu";

pub(super) fn write_rows(path: &Path, rows: &[Row]) -> Result<()> {
    let text = csv_text(rows, ITEM_DIGITS);
    write_atomic(path, |w| std::io::Write::write_all(w, text.as_bytes()))?;
    Ok(())
}

/// Decimals of PSNR, SSIM, RMSE, seconds, body PSNR, body SSIM and body RMSE in an item's
/// CSV (read back when a run resumes, so kept close to full precision).
const ITEM_DIGITS: [usize; 7] = [6, 6, 4, 3, 6, 6, 4];
/// The same in `results.csv` (the report's precision).
const REPORT_DIGITS: [usize; 7] = [4, 5, 2, 2, 4, 5, 2];

/// The score rows as CSV under [`ITEM_HEADER`], with `digits` decimals per real column
/// (the one definition of a results row).
fn csv_text(rows: &[Row], digits: [usize; 7]) -> String {
    let d = digits;
    let mut text = format!("{ITEM_HEADER}\n");
    for r in rows {
        let s = &r.scores;
        let _ = writeln!(
            text,
            "{},{},{},{:.*},{:.*},{:.*},{},{:.*},{:.*},{:.*},{:.*}",
            r.item,
            r.views,
            r.method,
            d[0],
            s.psnr,
            d[1],
            s.ssim,
            d[2],
            s.rmse_hu,
            r.iterations,
            d[3],
            r.seconds,
            d[4],
            s.body_psnr,
            d[5],
            s.body_ssim,
            d[6],
            s.body_rmse_hu
        );
    }
    text
}

fn parse_rows(path: &Path) -> Result<Vec<Row>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut rows = Vec::new();
    for (n, line) in text.lines().enumerate().skip(1) {
        let bad = || anyhow::anyhow!("{} line {}: not a score row", path.display(), n + 1);
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 8 && f.len() != 11 {
            return Err(bad());
        }
        let num = |i: usize| f[i].parse::<f64>().map_err(|_| bad());
        let body = |i: usize| if f.len() == 11 { num(i) } else { Ok(f64::NAN) };
        rows.push(Row {
            item: f[0].into(),
            views: f[1].parse().map_err(|_| bad())?,
            method: f[2].into(),
            scores: Scores {
                psnr: num(3)?,
                ssim: num(4)?,
                rmse_hu: num(5)?,
                body_psnr: body(8)?,
                body_ssim: body(9)?,
                body_rmse_hu: body(10)?,
            },
            iterations: f[6].parse().map_err(|_| bad())?,
            seconds: num(7)?,
        });
    }
    Ok(rows)
}

/// Every score of an evaluation folder, in the job's item order; an error naming the items
/// no shard has scored yet, unless `partial` (then the scored items only).
pub fn load_rows(output: &Path, partial: bool) -> Result<Vec<Row>> {
    let path = output.join("job.json");
    let job: Job = serde_json::from_slice(
        &std::fs::read(&path).with_context(|| format!("cannot read {}", path.display()))?,
    )
    .with_context(|| format!("{} is not an evaluation's job.json", path.display()))?;
    let missing: Vec<&str> = job
        .items
        .iter()
        .filter(|id| !item_path(output, id).exists())
        .map(String::as_str)
        .collect();
    if !missing.is_empty() && !partial {
        bail!(
            "{}: {} of {} item(s) not scored yet ({}); run the missing shards first",
            output.display(),
            missing.len(),
            job.items.len(),
            missing.join(", ")
        );
    }
    let mut rows = Vec::new();
    for id in job
        .items
        .iter()
        .filter(|id| !missing.contains(&id.as_str()))
    {
        rows.extend(parse_rows(&item_path(output, id))?);
    }
    Ok(rows)
}

/// Mean ± std per (views, method) of `rows`, in order of first appearance.
pub fn summarise(rows: &[Row]) -> Vec<(usize, String, Vec<Scores>)> {
    let mut table: Vec<(usize, String, Vec<Scores>)> = Vec::new();
    for r in rows {
        match table
            .iter_mut()
            .find(|(v, m, _)| *v == r.views && *m == r.method)
        {
            Some(e) => e.2.push(r.scores),
            None => table.push((r.views, r.method.clone(), vec![r.scores])),
        }
    }
    table.sort_by_key(|(v, _, _)| *v);
    table
}

/// Writes `results.csv` (every score) and `results.md` (mean ± std per view count and
/// method) from the items' scores ([`load_rows`]); returns the markdown and the scores.
pub fn merge(output: &Path, partial: bool) -> Result<(String, Vec<Row>)> {
    let rows = load_rows(output, partial)?;
    let csv = csv_text(&rows, REPORT_DIGITS);
    write_atomic(&output.join("results.csv"), |w| {
        std::io::Write::write_all(w, csv.as_bytes())
    })?;
    let mut md = "| views | method | PSNR (dB) | SSIM | RMSE (HU) | body PSNR (dB) | body SSIM | \
                  body RMSE (HU) |\n|---:|---|---:|---:|---:|---:|---:|---:|\n"
        .to_string();
    for (v, m, s) in summarise(&rows) {
        let f = |g: fn(&Scores) -> f64| mean_std(&s.iter().map(g).collect::<Vec<_>>());
        let (p, ps) = f(|s| s.psnr);
        let (q, qs) = f(|s| s.ssim);
        let (r, rs) = f(|s| s.rmse_hu);
        let (bp, bps) = f(|s| s.body_psnr);
        let (bq, bqs) = f(|s| s.body_ssim);
        let (br, brs) = f(|s| s.body_rmse_hu);
        let _ = writeln!(
            md,
            "| {v} | {m} | {p:.2} ± {ps:.2} | {q:.3} ± {qs:.3} | {r:.1} ± {rs:.1} | \
             {bp:.2} ± {bps:.2} | {bq:.3} ± {bqs:.3} | {br:.1} ± {brs:.1} |"
        );
    }
    let model: Vec<&Row> = rows.iter().filter(|r| r.method == "TomoGRAF").collect();
    let items = rows
        .iter()
        .map(|r| &r.item)
        .collect::<std::collections::BTreeSet<_>>()
        .len();
    let _ = write!(md, "\n{items} test item(s)");
    if !model.is_empty() {
        let spi: Vec<f64> = model
            .iter()
            .map(|r| r.seconds / r.iterations.max(1) as f64)
            .collect();
        let its: Vec<f64> = model.iter().map(|r| r.iterations as f64).collect();
        let _ = write!(
            md,
            "; inference: {:.0} iterations on average, {:.3} s per iteration (including \
             loading and the final volume rendering)",
            mean_std(&its).0,
            mean_std(&spi).0
        );
    }
    md.push_str(".\n");
    if let Some(t) = paired_table(&rows) {
        let _ = write!(
            md,
            "\nTomoGRAF minus each method, paired over the test items: mean difference ± \
             the half-width of its 95 % t-interval, **bold** where the interval excludes \
             zero (a difference the items resolve).\n\n{t}"
        );
    }
    write_atomic(&output.join("results.md"), |w| {
        std::io::Write::write_all(w, md.as_bytes())
    })?;
    Ok((md, rows))
}

/// TomoGRAF minus every other method in PSNR, SSIM, body PSNR and body SSIM, paired over
/// the items ([`crate::paired::table`]); `None` below two items or without TomoGRAF.
fn paired_table(rows: &[Row]) -> Option<String> {
    let of = |g: fn(&Scores) -> f64| -> Vec<crate::paired::Score> {
        rows.iter()
            .map(|r| (r.views, r.method.as_str(), r.item.as_str(), g(&r.scores)))
            .collect()
    };
    crate::paired::table(
        "TomoGRAF",
        &[
            ("PSNR (dB)", of(|s| s.psnr)),
            ("SSIM", of(|s| s.ssim)),
            ("body PSNR (dB)", of(|s| s.body_psnr)),
            ("body SSIM", of(|s| s.body_ssim)),
        ],
        &[2, 3, 2, 3],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One row written at both precisions: the bytes the two writers this replaced gave
    /// (their format strings, `{:.6},{:.6},{:.4},{},{:.3},{:.6},{:.6},{:.4}` and
    /// `{:.4},{:.5},{:.2},{},{:.2},{:.4},{:.5},{:.2}`, applied by hand), and the item CSV
    /// read back.
    #[test]
    fn a_results_row_has_one_writer_at_two_precisions() {
        let row = Row {
            item: "00003".into(),
            views: 2,
            method: "TomoGRAF".into(),
            scores: Scores {
                psnr: 21.123_456_789,
                ssim: 0.487_654_321,
                rmse_hu: 123.456_789,
                body_psnr: 20.5,
                body_ssim: 0.5,
                body_rmse_hu: 99.999_99,
            },
            iterations: 150,
            seconds: 12.345_678,
        };
        let rows = [row];
        let item = csv_text(&rows, ITEM_DIGITS);
        assert_eq!(
            item.lines().nth(1).unwrap(),
            "00003,2,TomoGRAF,21.123457,0.487654,123.4568,150,12.346,20.500000,0.500000,100.0000"
        );
        assert_eq!(
            csv_text(&rows, REPORT_DIGITS).lines().nth(1).unwrap(),
            "00003,2,TomoGRAF,21.1235,0.48765,123.46,150,12.35,20.5000,0.50000,100.00"
        );
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("00003.csv");
        write_rows(&path, &rows).unwrap();
        let back = parse_rows(&path).unwrap();
        assert_eq!(back.len(), 1);
        assert_eq!(back[0].iterations, 150);
        assert!((back[0].scores.psnr - 21.123_457).abs() < 1e-9);
    }
}
