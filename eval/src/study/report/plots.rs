//! The report's plots: each metric over the view counts and over the realism levels or test
//! sets (points with ± 1 SD bars, no lines across categories), and the per-item SSIM
//! histograms (the paper's Fig. 4).

use super::super::render::Block;
use super::super::{Kind, Study, VIEWS, relative};
use super::{MEAN_SART, Metric, Stat, find};
use crate::figures::{
    Axes, BarSeries, COLOUR_NAMES, plot_categories, plot_histograms, plot_with_bars,
};
use anyhow::{Context, Result};

/// Named series of (x, mean, SD over the test items).
type Series = Vec<(String, Vec<(f64, f64, f64)>)>;

fn colours(series: &Series) -> String {
    series
        .iter()
        .enumerate()
        .map(|(i, (n, _))| format!("{} = {n}", COLOUR_NAMES[i % COLOUR_NAMES.len()]))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A plot of `series` over the view counts (`categories` `None`) or over the named test
/// sets, with ± 1 SD bars.
fn draw(
    study: &Study,
    file: &str,
    axes: &Axes,
    caption: String,
    series: Series,
    categories: Option<&[String]>,
) -> Result<Block> {
    let path = study.dir.join("figures").join(file);
    let named: Vec<BarSeries> = series
        .iter()
        .map(|(n, p)| (n.as_str(), p.clone()))
        .collect();
    match categories {
        Some(c) => plot_categories(&path, axes, c, &named)?,
        None => plot_with_bars(&path, axes, &named)?,
    }
    let (lo, hi) = series
        .iter()
        .flat_map(|(_, p)| p.iter().map(|q| q.1))
        .filter(|y| y.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
            (a.min(y), b.max(y))
        });
    Ok(Block::Image(
        relative(&study.dir, &path),
        format!(
            "{caption} Bars: ± 1 SD over the test items. Colours: {}. The means span {lo:.3} \
             to {hi:.3}.",
            colours(&series)
        ),
    ))
}

pub(super) fn plots(study: &Study, stats: &[Stat]) -> Result<Vec<Block>> {
    let s = &study.settings;
    let mut b = vec![Block::Heading("Plots".into())];
    let point = |train: Option<&str>, test: &str, v: usize, method: &str, m: Metric| {
        find(stats, train, test, v, method).map(|st| st.mean_std(m))
    };
    let vs_views = |train: Option<&str>, test: &str, method: &str, m: Metric| {
        VIEWS
            .iter()
            .filter_map(|&v| point(train, test, v, method, m).map(|(y, e)| (v as f64, y, e)))
            .collect::<Vec<_>>()
    };
    let across = |f: &dyn Fn(&str) -> Option<(f64, f64)>| {
        s.test_sets
            .iter()
            .enumerate()
            .filter_map(|(i, t)| f(t).map(|(y, e)| (i as f64, y, e)))
            .collect::<Vec<_>>()
    };
    // The plots over the view counts show the last test set with scores (a partial report
    // may have none yet for the last sets).
    let last = s
        .test_sets
        .iter()
        .rev()
        .find(|t| {
            stats
                .iter()
                .any(|st| st.test == **t && !st.scores.is_empty())
        })
        .or(s.test_sets.last())
        .context("no test sets")?;
    for m in Metric::ALL {
        let mut series: Series = Vec::new();
        let caption = match s.kind {
            Kind::RealismGap => {
                for t in &s.train_sets {
                    series.push((
                        format!("TomoGRAF ← {t}"),
                        vs_views(Some(t), last, "TomoGRAF", m),
                    ));
                }
                // The strongest baseline, from the first model's mean volume.
                let first = &s.train_sets[0];
                series.push((
                    format!("{MEAN_SART} ← {first}"),
                    vs_views(Some(first), last, MEAN_SART, m),
                ));
                for c in ["FDK", "SART-TV"] {
                    series.push((c.into(), vs_views(None, last, c, m)));
                }
                format!(
                    "{} vs views (x axis: 1 to 10 views), tested on `{last}`.",
                    m.name()
                )
            }
            Kind::DomainShift => {
                let t = &s.train_sets[0];
                for test in &s.test_sets {
                    series.push((
                        format!("TomoGRAF on {test}"),
                        vs_views(Some(t), test, "TomoGRAF", m),
                    ));
                }
                format!(
                    "{} of TomoGRAF vs views (x axis: 1 to 10 views), per test set.",
                    m.name()
                )
            }
        };
        let title = format!("{} vs views", m.name());
        let axes = Axes {
            title: &title,
            x: "views",
            y: m.name(),
        };
        b.push(draw(
            study,
            &format!("{}_vs_views.png", m.file()),
            &axes,
            caption,
            series,
            None,
        )?);

        // The metric across the test sets.
        let mut series: Series = Vec::new();
        let (file, caption) = match s.kind {
            Kind::RealismGap => {
                let first = &s.train_sets[0];
                series.push((
                    format!("TomoGRAF ← {first}"),
                    across(&|t| point(Some(first), t, 1, "TomoGRAF", m)),
                ));
                series.push((
                    "TomoGRAF ← the level tested".into(),
                    across(&|t| {
                        s.train_sets
                            .iter()
                            .any(|x| x == t)
                            .then(|| point(Some(t), t, 1, "TomoGRAF", m))
                            .flatten()
                    }),
                ));
                series.push((
                    format!("{MEAN_SART} ← {first}"),
                    across(&|t| point(Some(first), t, 1, MEAN_SART, m)),
                ));
                for c in ["FDK", "SART-TV"] {
                    series.push((c.into(), across(&|t| point(None, t, 1, c, m))));
                }
                (
                    format!("{}_vs_level.png", m.file()),
                    format!("{} from 1 view vs the realism level tested on.", m.name()),
                )
            }
            Kind::DomainShift => {
                let t = s.train_sets[0].as_str();
                for v in VIEWS {
                    series.push((
                        format!("TomoGRAF, {v} view(s)"),
                        across(&|x| point(Some(t), x, v, "TomoGRAF", m)),
                    ));
                }
                for c in ["FDK", "SART-TV"] {
                    series.push((
                        format!("{c}, 10 views"),
                        across(&|x| point(None, x, 10, c, m)),
                    ));
                }
                (
                    format!("{}_vs_shift.png", m.file()),
                    format!("{} vs test set.", m.name()),
                )
            }
        };
        let (title, x) = match s.kind {
            Kind::RealismGap => (
                format!("{}, 1 view, vs realism level", m.name()),
                "level tested on",
            ),
            Kind::DomainShift => (format!("{} vs test set", m.name()), "test set"),
        };
        let axes = Axes {
            title: &title,
            x,
            y: m.name(),
        };
        b.push(draw(
            study,
            &file,
            &axes,
            caption,
            series,
            Some(&s.test_sets),
        )?);
    }

    // SSIM histograms over the test items, 1 view (the paper's Fig. 4).
    let values = |train: Option<&str>, test: &str, method: &str| {
        find(stats, train, test, 1, method)
            .map(|st| st.scores.iter().map(|x| x.ssim).collect::<Vec<_>>())
            .unwrap_or_default()
    };
    let mut series: Vec<(String, Vec<f64>)> = Vec::new();
    let caption = match s.kind {
        Kind::RealismGap => {
            for t in &s.train_sets {
                series.push((format!("TomoGRAF ← {t}"), values(Some(t), last, "TomoGRAF")));
            }
            for c in ["FDK", "SART-TV"] {
                series.push((c.into(), values(None, last, c)));
            }
            format!(
                "Histogram of the per-phantom SSIM from 1 view, tested on `{last}` (20 bins on [0, 1]; fraction of phantoms)."
            )
        }
        Kind::DomainShift => {
            for test in &s.test_sets {
                series.push((
                    format!("TomoGRAF on {test}"),
                    values(Some(&s.train_sets[0]), test, "TomoGRAF"),
                ));
            }
            "Histogram of TomoGRAF's per-phantom SSIM from 1 view per test set (20 bins on [0, 1]; fraction of phantoms).".into()
        }
    };
    let path = study.dir.join("figures").join("ssim_histogram.png");
    let named: Vec<(&str, Vec<f64>)> = series
        .iter()
        .map(|(n, v)| (n.as_str(), v.clone()))
        .collect();
    let title = match s.kind {
        Kind::RealismGap => format!("Per-phantom SSIM from 1 view, tested on {last}"),
        Kind::DomainShift => "TomoGRAF's per-phantom SSIM from 1 view".to_string(),
    };
    let axes = Axes {
        title: &title,
        x: "SSIM",
        y: "fraction of phantoms",
    };
    plot_histograms(&path, &axes, &named, 0.0, 1.0, 20)?;
    let names: Series = series
        .iter()
        .map(|(n, _)| (n.clone(), Vec::new()))
        .collect();
    b.push(Block::Image(
        relative(&study.dir, &path),
        format!("{caption} Colours: {}.", colours(&names)),
    ));
    Ok(b)
}
