//! The AAPM TG-195 validation report (`tomograf validate tg195`): runs the cases through the energy-imparted tally
//! (`crate::validation::tg195`) and writes the comparison with the four codes as a
//! markdown table, a CSV and figures.

use crate::figures::{Axes, plot_deviations, plot_points};
use crate::validation::tg195::{self, Beam, Comparison};
use crate::validation::tg195_case3;
use anyhow::{Context, Result};
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;
use tomograf_datasets::atomic::write_atomic;
use tomograf_scene::Progress;

/// What to run and where (`tomograf validate tg195`'s flags).
#[derive(Debug, Clone)]
pub struct Validation {
    /// Output folder (tg195.md, tg195.csv, tg195-deviations.png, tg195-case42.png).
    pub output: PathBuf,
    /// Cases to run: "1", "2", "3", "4.2".
    pub cases: Vec<String>,
    /// Photons per Case 1 run (three runs per beam, four beams), per Case 2 run (four
    /// runs), per Case 3 run (four runs) and per Case 4.2 run (four runs; each scores all
    /// 36 angles).
    pub photons_case1: u64,
    pub photons_case2: u64,
    pub photons_case3: u64,
    pub photons_case42: u64,
    /// Random seed.
    pub seed: u64,
    /// Run only `cases` and keep the other cases' rows and seconds from the output
    /// folder's tg195.csv and tg195.md.
    pub update: bool,
}

/// The cases this validation runs, in report order.
const CASES: [&str; 4] = ["1", "2", "3", "4.2"];

/// One run of the validation: its label and how to make it.
type Job = (
    String,
    Box<dyn Fn() -> tomograf_sim::Result<Vec<Comparison>>>,
);

/// Redraws the figures from `dir`'s tg195.csv without running anything.
pub fn replot(dir: &Path, progress: &dyn Progress) -> Result<()> {
    let path = dir.join("tg195.csv");
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("--replot reads {}", path.display()))?;
    let rows = from_csv(&text).with_context(|| format!("reading {}", path.display()))?;
    figures(dir, &rows)?;
    progress.note(&format!(
        "redrew the figures of {} row(s) in {}",
        rows.len(),
        dir.display()
    ));
    Ok(())
}

/// Runs the cases, compares them with the four codes, and writes the table, the CSV and
/// the figures into `args.output` (prints the summary).
pub fn validate(args: &Validation, progress: &dyn Progress) -> Result<()> {
    for c in &args.cases {
        anyhow::ensure!(
            CASES.contains(&c.as_str()),
            "--cases: unknown case '{c}'; give 1, 2, 3 and/or 4.2"
        );
    }
    let want = |c: &str| args.cases.iter().any(|x| x == c);
    let seed = args.seed;
    let mut jobs: Vec<Job> = Vec::new();
    if want("1") {
        for beam in [
            Beam::Mono(30.0),
            Beam::Mono(100.0),
            Beam::Kvp(30),
            Beam::Kvp(100),
        ] {
            let n = args.photons_case1;
            jobs.push((
                format!("case 1, {}", beam.label()),
                Box::new(move || tg195::case1(beam, n, seed)),
            ));
        }
    }
    if want("2") {
        for beam in [Beam::Mono(56.4), Beam::Kvp(120)] {
            for tomo in [false, true] {
                let n = args.photons_case2;
                jobs.push((
                    format!(
                        "case 2, {} {}",
                        if tomo { "tomosynthesis" } else { "radiography" },
                        beam.label()
                    ),
                    Box::new(move || {
                        tg195::case2(beam, tomo, &[1, 2, 3, 4, 5, 6, 7, 8, 9], n, seed)
                    }),
                ));
            }
        }
    }
    if want("3") {
        for beam in [Beam::Mono(16.8), Beam::Kvp(30)] {
            for tomo in [false, true] {
                let n = args.photons_case3;
                jobs.push((
                    format!(
                        "case 3, {} {}",
                        if tomo { "tomosynthesis" } else { "radiography" },
                        beam.label()
                    ),
                    Box::new(move || tg195_case3::case3(beam, tomo, n, seed)),
                ));
            }
        }
    }
    if want("4.2") {
        for beam in [Beam::Mono(56.4), Beam::Kvp(120)] {
            for wide in [false, true] {
                let n = args.photons_case42;
                jobs.push((
                    format!(
                        "case 4.2, {} mm {}",
                        if wide { 80 } else { 10 },
                        beam.label()
                    ),
                    Box::new(move || tg195::case42(beam, wide, n, seed)),
                ));
            }
        }
    }
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("cannot create {}", args.output.display()))?;
    progress.start("run", jobs.len() as u64, 0);
    let start = Instant::now();
    let mut rows = Vec::new();
    let mut times = Vec::new();
    for (label, job) in &jobs {
        progress.set_message(label);
        let t = Instant::now();
        rows.extend(job().with_context(|| label.clone())?);
        times.push((label.clone(), t.elapsed().as_secs_f64()));
        progress.inc();
    }
    progress.finish();
    let total = start.elapsed().as_secs_f64();
    let ran: Vec<String> = CASES
        .iter()
        .filter(|c| want(c))
        .map(|c| {
            let n = match *c {
                "1" => args.photons_case1,
                "2" => args.photons_case2,
                "3" => args.photons_case3,
                _ => args.photons_case42,
            };
            format!("case {c} {n}")
        })
        .collect();
    let mut settings = format!(
        "photons per run: {}; seed {}; {} thread(s); {:.0} s in all",
        ran.join(", "),
        args.seed,
        rayon::current_num_threads(),
        total
    );
    if args.update {
        let kept = kept_from(&args.output, &want)?;
        if !kept.rows.is_empty() {
            let _ = write!(
                settings,
                ".\n\nKept from the previous run: case {} ({})",
                kept.cases.join(", "),
                kept.settings
            );
        }
        rows = kept.rows.into_iter().chain(rows).collect();
        rows.sort_by_key(|r| case_order(&r.case));
        times = kept.times.into_iter().chain(times).collect();
        times.sort_by_key(|(label, _)| case_order(label.trim_start_matches("case ")));
    }
    let md = table(&rows, &settings, &times);
    let text = csv(&rows);
    write_atomic(&args.output.join("tg195.md"), |w| {
        w.write_all(md.as_bytes())
    })?;
    write_atomic(&args.output.join("tg195.csv"), |w| {
        w.write_all(text.as_bytes())
    })?;
    figures(&args.output, &rows)?;
    print!("{}", summary(&rows));
    if let Some(w) = unresolved_warning(&rows) {
        progress.warn(&w);
    }
    progress.note(&format!("{settings}; written to {}", args.output.display()));
    Ok(())
}

/// A warning when some figure has no finite, non-zero standard error: too few
/// photons reached it to say anything (its deviation in standard errors is ±inf or NaN).
fn unresolved_warning(rows: &[Comparison]) -> Option<String> {
    let bad: Vec<&Comparison> = rows
        .iter()
        .filter(|r| !(r.ours_se.is_finite() && r.ours_se > 0.0))
        .collect();
    let first = bad.first()?;
    Some(format!(
        "warning: {} of {} figures (first: case {}, {}) have no finite, non-zero standard \
         error: too few photons reached them to estimate one, so their deviations say \
         nothing; raise the photons of their case (--photons-case1 … --photons-case42)",
        bad.len(),
        rows.len(),
        first.case,
        first.quantity
    ))
}

/// What `--update` keeps from the previous run in the output folder.
struct Kept {
    rows: Vec<Comparison>,
    times: Vec<(String, f64)>,
    cases: Vec<String>,
    settings: String,
}

/// The case a row's `case` field (or a run's label without "case ") belongs to: "1",
/// "2" or "4.2".
fn case_id(case: &str) -> &str {
    case.split([' ', ',']).next().unwrap_or_default()
}

/// 0, 1, 2, 3 for cases 1, 2, 3, 4.2 (sorting is stable within a case).
fn case_order(case: &str) -> usize {
    CASES.iter().position(|c| *c == case_id(case)).unwrap_or(3)
}

/// The rows, seconds and settings of the cases not re-run, from `dir`'s tg195.csv and
/// tg195.md.
fn kept_from(dir: &std::path::Path, rerun: &dyn Fn(&str) -> bool) -> Result<Kept> {
    let csv_path = dir.join("tg195.csv");
    let md_path = dir.join("tg195.md");
    let read = |p: &std::path::Path| {
        std::fs::read_to_string(p)
            .with_context(|| format!("--update keeps the other cases from {}", p.display()))
    };
    let rows: Vec<Comparison> = from_csv(&read(&csv_path)?)
        .with_context(|| format!("reading {}", csv_path.display()))?
        .into_iter()
        .filter(|r| !rerun(case_id(&r.case)))
        .collect();
    let md = read(&md_path)?;
    let settings = md
        .lines()
        .find(|l| l.starts_with("photons per run:"))
        .unwrap_or("settings not recorded")
        .trim_end_matches('.')
        .to_string();
    let mut times = Vec::new();
    for line in md.lines().filter_map(|l| l.strip_prefix("* case ")) {
        let Some((label, secs)) = line.rsplit_once(": ") else {
            continue;
        };
        let Ok(t) = secs.trim_end_matches(" s").parse::<f64>() else {
            continue;
        };
        if !rerun(case_id(label)) {
            times.push((format!("case {label}"), t));
        }
    }
    let mut cases: Vec<String> = rows.iter().map(|r| case_id(&r.case).to_string()).collect();
    cases.dedup();
    Ok(Kept {
        rows,
        times,
        cases,
        settings,
    })
}

/// The agreement targets of the issue: Case 1 ratios within 1 % of the codes' mean,
/// everything of Cases 2, 3 and 4.2 within 2 % or inside the codes' range.
fn target(r: &Comparison) -> Option<f64> {
    if r.case.starts_with("1 ") {
        r.quantity.starts_with("ratio").then_some(1.0)
    } else {
        Some(2.0)
    }
}

fn verdict(r: &Comparison) -> &'static str {
    match target(r) {
        None => "(unit uncertain)",
        Some(t) if r.agrees(t) => "yes",
        Some(_) => "**no**",
    }
}

fn table(rows: &[Comparison], settings: &str, times: &[(String, f64)]) -> String {
    let codes = tg195::codes();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# TG-195: tomograf against EGSnrc, Geant4, MCNP and Penelope\n\n{settings}.\n\n\
         Case 1: air kerma at 100 cm per source photon in the transcription's convention \
         (Σ E·μen/ρ·Φ / 100) and its HVL/QVL ratios; Cases 2, 3 and 4.2: energy imparted, eV per \
         source photon. \"±\": one standard error. \"target\": within 1 % (Case 1 ratios) \
         or 2 % (Cases 2, 3, 4.2) of the codes' mean, or inside their range.\n"
    );
    let _ = writeln!(
        s,
        "| case | quantity | tomograf | {} | codes' mean | codes' range | deviation (%) | deviation (SE) | target |",
        codes.join(" | ")
    );
    let _ = writeln!(
        s,
        "|---|---|---:|{}---:|---|---:|---:|---|",
        "---:|".repeat(4)
    );
    for r in rows {
        let (lo, hi) = r.reference.range();
        let c: Vec<String> = r
            .reference
            .codes
            .iter()
            .map(|v| v.map_or("—".into(), num))
            .collect();
        let _ = writeln!(
            s,
            "| {} | {} | {} ± {} | {} | {} | {}–{} | {:+.2} | {:+.1} | {} |",
            r.case,
            r.quantity,
            num(r.ours),
            num(r.ours_se),
            c.join(" | "),
            num(r.reference.mean()),
            num(lo),
            num(hi),
            r.deviation_percent(),
            r.deviation_se(),
            verdict(r)
        );
    }
    let _ = writeln!(s, "\n{}", summary(rows));
    let _ = writeln!(s, "Seconds per run:\n");
    for (label, t) in times {
        let _ = writeln!(s, "* {label}: {t:.1} s");
    }
    s
}

/// Four significant digits (more for small ratios' differences to show).
fn num(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let digits = (5 - v.abs().log10().floor() as i32).max(0) as usize;
    format!("{v:.digits$}")
}

fn summary(rows: &[Comparison]) -> String {
    let judged: Vec<&Comparison> = rows.iter().filter(|r| target(r).is_some()).collect();
    let ok = judged.iter().filter(|r| verdict(r) == "yes").count();
    let worst = judged
        .iter()
        .max_by(|a, b| {
            a.deviation_percent()
                .abs()
                .total_cmp(&b.deviation_percent().abs())
        })
        .map(|r| format!("{} {}: {:+.2} %", r.case, r.quantity, r.deviation_percent()))
        .unwrap_or_default();
    format!(
        "{ok} of {} judged rows meet the target; largest deviation from the codes' mean: {worst}\n",
        judged.len()
    )
}

fn csv(rows: &[Comparison]) -> String {
    let mut s = String::from(
        "case,quantity,ours,ours_se,egsnrc,geant4,mcnp,penelope,codes_mean,codes_min,codes_max,deviation_percent,deviation_se\n",
    );
    for r in rows {
        let (lo, hi) = r.reference.range();
        let c: Vec<String> = r
            .reference
            .codes
            .iter()
            .map(|v| v.map_or(String::new(), |v| v.to_string()))
            .collect();
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{}",
            r.case,
            r.quantity.replace(',', ";"),
            r.ours,
            r.ours_se,
            c.join(","),
            r.reference.mean(),
            lo,
            hi,
            r.deviation_percent(),
            r.deviation_se()
        );
    }
    s
}

/// The comparisons written by [`csv`].
fn from_csv(text: &str) -> Result<Vec<Comparison>> {
    let mut rows = Vec::new();
    for (n, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        anyhow::ensure!(
            f.len() == 13,
            "line {}: {} fields, expected 13",
            n + 1,
            f.len()
        );
        let num = |s: &str| -> Result<f64> {
            s.parse()
                .with_context(|| format!("line {}: '{s}' is not a number", n + 1))
        };
        let mut codes = [None; 4];
        for (c, slot) in codes.iter_mut().enumerate() {
            if !f[4 + c].is_empty() {
                *slot = Some(num(f[4 + c])?);
            }
        }
        rows.push(Comparison {
            case: f[0].to_string(),
            quantity: f[1].replace(';', ","),
            ours: num(f[2])?,
            ours_se: num(f[3])?,
            reference: crate::validation::reference::Reference {
                key: vec![f[1].to_string()],
                codes,
            },
        });
    }
    Ok(rows)
}

fn figures(dir: &std::path::Path, rows: &[Comparison]) -> Result<()> {
    let judged: Vec<&Comparison> = rows
        .iter()
        .filter(|r| target(r).is_some() && !r.case.starts_with("4.2"))
        .collect();
    if !judged.is_empty() {
        let points: Vec<(f64, f64, f64, f64, f64)> = judged
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let m = r.reference.mean();
                let (lo, hi) = r.reference.range();
                (
                    i as f64,
                    r.deviation_percent(),
                    200.0 * r.ours_se / m,
                    (lo / m - 1.0) * 100.0,
                    (hi / m - 1.0) * 100.0,
                )
            })
            .collect();
        // Which comparisons each case holds, in table order (e.g. "0–7 case 1").
        let mut spans: Vec<(&str, usize, usize)> = Vec::new();
        for (i, r) in judged.iter().enumerate() {
            let c = case_id(&r.case);
            match spans.last_mut() {
                Some((last, _, end)) if *last == c => *end = i,
                _ => spans.push((c, i, i)),
            }
        }
        let what = |c: &str| match c {
            "1" => "HVL/QVL ratios",
            "2" => "box and VOIs",
            "3" => "breast and VOIs",
            _ => "rows",
        };
        let x = format!(
            "comparison: {} (tg195.md order)",
            spans
                .iter()
                .map(|(c, a, b)| format!("{a}–{b} case {c} {}", what(c)))
                .collect::<Vec<_>>()
                .join(", ")
        );
        let cases: Vec<&str> = spans.iter().map(|(c, _, _)| *c).collect();
        let title = format!(
            "TG-195 case{} {}: tomograf vs the codes' mean",
            if cases.len() > 1 { "s" } else { "" },
            cases.join(", ")
        );
        plot_deviations(
            &dir.join("tg195-deviations.png"),
            &Axes {
                title: &title,
                x: &x,
                y: "deviation from the codes' mean (%)",
            },
            &points,
        )?;
    }
    let c42: Vec<&Comparison> = rows
        .iter()
        .filter(|r| r.case.starts_with("4.2") && r.quantity.ends_with('°'))
        .collect();
    if !c42.is_empty() {
        let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
        for r in &c42 {
            let angle: f64 = r
                .quantity
                .trim_start_matches("Periphery ")
                .trim_end_matches('°')
                .parse()
                .unwrap_or(f64::NAN);
            let name = r.case.trim_start_matches("4.2 ").to_string();
            let point = (angle, r.deviation_percent());
            match series.iter_mut().find(|(n, _)| *n == name) {
                Some((_, s)) => s.push(point),
                None => series.push((name, vec![point])),
            }
        }
        let named: Vec<(&str, Vec<(f64, f64)>)> = series
            .iter()
            .map(|(n, s)| (n.as_str(), s.clone()))
            .collect();
        plot_points(
            &dir.join("tg195-case42.png"),
            &Axes {
                title: "TG-195 case 4.2, peripheral cylinder: tomograf vs the codes' mean",
                x: "source angle (degrees); behind the phantom (100-260) the cylinder gets < 6 eV per photon",
                y: "deviation from the codes' mean (%)",
            },
            &named,
        )?;
    }
    Ok(())
}
