//! The search's decision: per method and view count the setting with the highest mean
//! PSNR over the validation items (the default on a tie), and the search as markdown.

use super::{
    BaselineSettings, Candidate, FDK, PCA_MAP, Row, SART_TV, SART_TV_FROM_MEAN, TOMOGRAF, Tuning,
    ViewSettings,
};
use anyhow::{Context, Result, bail};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use tomograf_model::baseline::SartTvSettings;
use tomograf_model::metrics::Scores;
use tomograf_model::pca::PcaSettings;
use tomograf_recon::Window;

/// The winner per method and view count (highest mean PSNR; on a tie the default, else the
/// first on the grid), and the search as markdown tables.
pub(super) fn choose(
    t: &Tuning,
    candidates: &[Candidate],
    rows: &[Row],
    items: usize,
    own: Option<SartTvSettings>,
) -> Result<(BaselineSettings, String)> {
    let mut md = format!(
        "# Baselines tuned on {} ({items} item(s)), training set {}\n\nMean over the \
         validation items; the chosen setting (highest mean PSNR) in bold, the default marked \
         \"(default)\"{}.\n",
        t.data.display(),
        t.train_data.display(),
        if own.is_some() {
            " (TomoGRAF's: the checkpoint's own sweeps; its network is the same in every row)"
        } else {
            ""
        }
    );
    let mut views = BTreeMap::new();
    let mut edges = Vec::new();
    // (method, views, default's PSNR, chosen setting, its PSNR) for the summary.
    let mut summary: Vec<(&str, usize, f64, String, f64)> = Vec::new();
    let defaults = ViewSettings::default();
    for &count in t.views {
        let mut chosen = defaults;
        let methods = [TOMOGRAF, SART_TV, SART_TV_FROM_MEAN, PCA_MAP, FDK];
        for method in methods
            .into_iter()
            .filter(|m| candidates.iter().any(|c| c.method() == *m))
        {
            let _ = write!(
                md,
                "\n## {method}, {count} view(s)\n\n| setting | PSNR (dB) | SSIM | body PSNR \
                 (dB) | body SSIM |\n|---|---:|---:|---:|---:|\n"
            );
            let mut table = Vec::new();
            for c in candidates.iter().filter(|c| c.method() == method) {
                let s: Vec<&Scores> = rows
                    .iter()
                    .filter(|r| r.views == count && r.method == method && r.setting == c.setting())
                    .map(|r| &r.scores)
                    .collect();
                if s.len() != items {
                    bail!(
                        "{method} ({}), {count} view(s): {} of {items} item(s) scored",
                        c.setting(),
                        s.len()
                    );
                }
                let m = |f: fn(&Scores) -> f64| s.iter().map(|x| f(x)).sum::<f64>() / items as f64;
                table.push((
                    *c,
                    [
                        m(|x| x.psnr),
                        m(|x| x.ssim),
                        m(|x| x.body_psnr),
                        m(|x| x.body_ssim),
                    ],
                ));
            }
            let is_default = |c: &Candidate| match *c {
                Candidate::SartTv(s) | Candidate::SartTvFromMean(s) => {
                    s == SartTvSettings::default()
                }
                Candidate::PcaMap(p) => p == PcaSettings::default(),
                Candidate::Fdk(w) => w == Window::default(),
                Candidate::Tomograf(s) => Some(s) == own,
            };
            // The highest mean PSNR; on a tie the default keeps its place (a search that
            // cannot tell the settings apart changes nothing), else the first on the grid.
            let top = table
                .iter()
                .map(|r| r.1[0])
                .fold(f64::NEG_INFINITY, f64::max);
            let best = table
                .iter()
                .position(|(c, v)| v[0] == top && is_default(c))
                .or_else(|| table.iter().position(|(_, v)| v[0] == top))
                .context("no setting scored")?;
            if let Some((_, d)) = table.iter().find(|(c, _)| is_default(c)) {
                summary.push((
                    method,
                    count,
                    d[0],
                    table[best].0.setting(),
                    table[best].1[0],
                ));
            }
            for (i, (c, v)) in table.iter().enumerate() {
                let is_default = is_default(c);
                let name = format!(
                    "{}{}",
                    c.setting(),
                    if is_default { " (default)" } else { "" }
                );
                let cell = match (i == best, t.grid.on_edge(c)) {
                    (true, true) => {
                        edges.push(format!("{method}, {count} view(s)"));
                        format!("**{name}** (on the grid's edge)")
                    }
                    (true, false) => format!("**{name}**"),
                    _ => name,
                };
                let _ = writeln!(
                    md,
                    "| {cell} | {:.2} | {:.3} | {:.2} | {:.3} |",
                    v[0], v[1], v[2], v[3]
                );
            }
            match table[best].0 {
                Candidate::SartTv(s) => chosen.sart_tv = s,
                Candidate::SartTvFromMean(s) => chosen.sart_tv_from_mean = s,
                Candidate::PcaMap(p) => chosen.pca_map = p,
                Candidate::Fdk(w) => chosen.fdk_window = w,
                Candidate::Tomograf(s) => chosen.tomograf_sweeps = Some(s),
            }
        }
        views.insert(count.to_string(), chosen);
    }
    let mut head = String::from(
        "\n## Summary\n\n| method | views | default: PSNR (dB) | chosen | PSNR (dB) | gain (dB) \
         |\n|---|---:|---:|---|---:|---:|\n",
    );
    for (method, count, d, chosen, p) in &summary {
        let _ = writeln!(
            head,
            "| {method} | {count} | {d:.2} | {chosen} | {p:.2} | {:+.2} |",
            p - d
        );
    }
    let at = md.find("\n## ").unwrap_or(md.len());
    md.insert_str(at, &head);
    if !edges.is_empty() {
        let _ = write!(
            md,
            "\nChosen on the grid's edge (a better setting may lie beyond it): {}.\n",
            edges.join("; ")
        );
        t.progress.note(&format!(
            "note: chosen on the grid's edge: {}",
            edges.join("; ")
        ));
    }
    Ok((
        BaselineSettings {
            tuned_on: format!(
                "{} ({items} validation item(s)); training set {}{}",
                t.data.display(),
                t.train_data.display(),
                t.checkpoint.map_or(String::new(), |c| format!(
                    "; TomoGRAF's sweeps for checkpoint {} (inference seed {})",
                    c.display(),
                    t.seed
                ))
            ),
            rule: "highest mean PSNR over the validation items, per method and view count (the \
                   default on a tie)"
                .into(),
            views,
        },
        md,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tuning::Grid;
    use std::path::Path;
    use tomograf_model::scatter_correction::ScatterCorrection;
    use tomograf_scene::Silent;

    #[test]
    fn a_flat_search_keeps_the_default() {
        let t = Tuning {
            data: Path::new("val"),
            split: None,
            items: None,
            train_data: Path::new("train"),
            views: &[1],
            scatter_correction: ScatterCorrection::None,
            checkpoint: None,
            seed: 0,
            backend: None,
            grid: Grid::Full,
            output: Path::new("out"),
            shard: (0, 1),
            progress: &Silent,
        };
        let sweeps = |sweeps, tv_step| SartTvSettings { sweeps, tv_step };
        let candidates = [
            Candidate::Tomograf(sweeps(5, 0.0)),
            Candidate::Tomograf(sweeps(20, 0.2)),
            Candidate::Tomograf(sweeps(40, 0.2)),
        ];
        let rows = |psnr: [f64; 3]| -> Vec<Row> {
            candidates
                .iter()
                .zip(psnr)
                .map(|(c, p)| Row {
                    item: "00000".into(),
                    views: 1,
                    method: c.method(),
                    setting: c.setting(),
                    scores: Scores {
                        psnr: p,
                        ssim: 0.5,
                        rmse_hu: 1.0,
                        body_psnr: p,
                        body_ssim: 0.5,
                        body_rmse_hu: 1.0,
                    },
                })
                .collect()
        };
        let pick = |psnr, own| {
            choose(&t, &candidates, &rows(psnr), 1, own)
                .unwrap()
                .0
                .views["1"]
                .tomograf_sweeps
        };
        let own = Some(sweeps(20, 0.2));
        // Every setting alike (the sweeps never ran): the checkpoint's own stays.
        assert_eq!(pick([26.0; 3], own), own);
        // Without a default among the best, the first best on the grid.
        assert_eq!(pick([26.0; 3], None), Some(sweeps(5, 0.0)));
        assert_eq!(pick([25.0, 26.0, 26.0], Some(sweeps(5, 0.0))), own);
        // A better setting wins over the default.
        assert_eq!(pick([26.0, 26.0, 26.5], own), Some(sweeps(40, 0.2)));
    }
}
