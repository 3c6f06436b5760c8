//! PNG figures of `tomograf evaluate`, `tomograf train` and `tomograf study`: orthogonal
//! slices with a residual map, line plots and histograms (plotters, bitmap backend).
//!
//! Text is drawn with DejaVu Sans, shipped in `assets/fonts/` (its licence beside it) and
//! compiled in, so figures look the same on every machine. Series colours are fixed, in
//! order, by [`COLOUR_NAMES`]; plots carry a title, axis labels and a legend.

use anyhow::{Context, Result};
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use tomograf_model::data::Item;
use tomograf_sim::Volume;

/// Series colours, in order.
const COLOURS: [RGBColor; 8] = [
    BLUE,
    RED,
    GREEN,
    BLACK,
    MAGENTA,
    CYAN,
    RGBColor(255, 140, 0),
    RGBColor(128, 128, 128),
];

/// Names of [`COLOURS`], for captions.
pub const COLOUR_NAMES: [&str; 8] = [
    "blue", "red", "green", "black", "magenta", "cyan", "orange", "grey",
];

/// Three orthogonal mid-slices (axial, coronal, sagittal) of a volume `n³`, `i` fastest,
/// head up in coronal and sagittal.
fn slices(v: &Volume) -> [Vec<f32>; 3] {
    let [nx, ny, nz] = v.dims();
    let d = v.data();
    let at = |i: usize, j: usize, k: usize| d[i + nx * (j + ny * k)];
    let (mi, mj, mk) = (nx / 2, ny / 2, nz / 2);
    let axial = (0..ny)
        .flat_map(|j| (0..nx).map(move |i| (i, j)))
        .map(|(i, j)| at(i, j, mk))
        .collect();
    let coronal = (0..nz)
        .rev()
        .flat_map(|k| (0..nx).map(move |i| (i, k)))
        .map(|(i, k)| at(i, mj, k))
        .collect();
    let sagittal = (0..nz)
        .rev()
        .flat_map(|k| (0..ny).map(move |j| (j, k)))
        .map(|(j, k)| at(mi, j, k))
        .collect();
    [axial, coronal, sagittal]
}

/// `<stem>_slices.png` (rows: axial, coronal, sagittal; columns: ground truth, each of
/// `recons` in order, |first − truth| × 4; titled columns and a grey scale in HU over the
/// item's window) and
/// `<stem>_profile.png` (the row through the centre of the axial slice: truth, then
/// `recons` named by `names`, coloured as [`COLOUR_NAMES`]). Volumes that are not cubes
/// are skipped.
pub fn slices_and_profile(
    item: &Item,
    recons: &[&Volume],
    names: &[&str],
    stem: &Path,
) -> Result<()> {
    let gt = item.ct.as_ref().context("no ground truth")?;
    let [nx, ny, nz] = gt.dims();
    if nx != ny || ny != nz || recons.is_empty() {
        return Ok(());
    }
    let n = nx;
    let residual = Volume::new(
        gt.dims(),
        gt.spacing(),
        gt.origin(),
        gt.direction(),
        recons[0]
            .data()
            .iter()
            .zip(gt.data())
            .map(|(a, b)| ((a - b).abs() * 4.0).min(1.0))
            .collect(),
    )?;
    let mut columns = vec![gt];
    columns.extend(recons.iter().copied());
    columns.push(&residual);
    let cols: Vec<[Vec<f32>; 3]> = columns.iter().map(|v| slices(v)).collect();
    let mut titles = vec!["truth".to_string()];
    titles.extend(names.iter().map(|n| n.to_string()));
    titles.push(format!(
        "|{} − truth|",
        names.first().copied().unwrap_or("")
    ));
    draw_slices(
        &PathBuf::from(format!("{}_slices.png", stem.display())),
        &format!("Item {}: orthogonal mid-slices", item.id),
        &titles,
        &cols,
        n,
        (item.window.lo, item.window.hi),
    )?;
    let line = |v: &Volume| -> Vec<(f64, f64)> {
        let s = &slices(v)[0];
        (0..n)
            .map(|i| (i as f64, f64::from(s[(n / 2) * n + i])))
            .collect()
    };
    let mut series = vec![("truth", line(gt))];
    series.extend(recons.iter().zip(names).map(|(v, name)| (*name, line(v))));
    plot_lines(
        &PathBuf::from(format!("{}_profile.png", stem.display())),
        &Axes {
            title: "Line profile: middle row of the axial mid-slice",
            x: "voxel i",
            y: PROFILE_UNIT,
        },
        &series,
    )
}

/// The unit of the volumes' values in the figures (data sets store CTs normalised).
const PROFILE_UNIT: &str = "normalised value (HU window → 0…1)";

/// Title and axis labels of a plot.
pub struct Axes<'a> {
    pub title: &'a str,
    pub x: &'a str,
    pub y: &'a str,
}

/// A grid of slice tiles (`cols[c][r]`, `n × n`, values in [0, 1] = the HU window) with a
/// title, column titles, row labels and a grey-scale bar in HU; tiles drawn 3× enlarged. The
/// last column is a residual (|error| × 4 in window units): drawn in a colour scale of its
/// own (black → red → yellow → white), with its own bar in HU of error.
fn draw_slices(
    path: &Path,
    title: &str,
    titles: &[String],
    cols: &[[Vec<f32>; 3]],
    n: usize,
    window_hu: (f32, f32),
) -> Result<()> {
    font()?;
    let plot_err = |e: &dyn std::fmt::Display| anyhow::anyhow!("plot {}: {e}", path.display());
    let zoom = (192 / n.max(1)).max(1);
    let tile = n * zoom;
    let (gap, left, top, bar) = (8usize, 80usize, 56usize, 90usize);
    let w = left + cols.len() * (tile + gap) + 2 * bar;
    let h = top + 3 * (tile + gap) + 10;
    let root = BitMapBackend::new(path, (w as u32, h as u32)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| plot_err(&e))?;
    let text = |size: u32| ("sans-serif", size).into_font().color(&BLACK);
    root.draw_text(title, &text(18), (left as i32, 8))
        .map_err(|e| plot_err(&e))?;
    let grey = |v: f32| {
        let g = (v.clamp(0.0, 1.0) * 255.0).round() as u8;
        RGBColor(g, g, g)
    };
    // The residual's scale: black → red → yellow → white.
    let heat = |v: f32| {
        let v = v.clamp(0.0, 1.0) * 3.0;
        let ramp = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
        RGBColor(ramp(v), ramp(v - 1.0), ramp(v - 2.0))
    };
    let last = cols.len().saturating_sub(1);
    for (c, col) in cols.iter().enumerate() {
        let colour = |v: f32| if c == last { heat(v) } else { grey(v) };
        let x0 = left + c * (tile + gap);
        let mut t = titles.get(c).cloned().unwrap_or_default();
        if t.chars().count() > 26 {
            t = t.chars().take(25).collect::<String>() + "…";
        }
        root.draw_text(&t, &text(13), (x0 as i32, (top - 20) as i32))
            .map_err(|e| plot_err(&e))?;
        for (r, slice) in col.iter().enumerate() {
            let y0 = top + r * (tile + gap);
            for y in 0..tile {
                for x in 0..tile {
                    let v = slice[(y / zoom) * n + x / zoom];
                    root.draw_pixel(((x0 + x) as i32, (y0 + y) as i32), &colour(v))
                        .map_err(|e| plot_err(&e))?;
                }
            }
        }
    }
    for (r, name) in ["axial", "coronal", "sagittal"].iter().enumerate() {
        let y = top + r * (tile + gap) + tile / 2;
        root.draw_text(name, &text(14), (8, y as i32))
            .map_err(|e| plot_err(&e))?;
    }
    // The scales, bottom to top: the HU window in grey; the residual's |error| in HU (a
    // quarter of the window's width at the top: the column shows |error| × 4).
    let (lo, hi) = window_hu;
    // (name, colour of a value in [0, 1], the values at 0 and 1).
    type Scale<'a> = (&'a str, &'a dyn Fn(f32) -> RGBColor, f32, f32);
    let scales: [Scale; 2] = [
        ("HU", &grey, lo, hi),
        ("|error| HU", &heat, 0.0, (hi - lo) / 4.0),
    ];
    for (s, (name, colour, from, to)) in scales.iter().enumerate() {
        let bx = (left + cols.len() * (tile + gap) + 10 + s * bar) as i32;
        let (by0, by1) = (top as i32, (top + 3 * tile + 2 * gap) as i32);
        for y in by0..by1 {
            let v = 1.0 - (y - by0) as f32 / (by1 - by0 - 1).max(1) as f32;
            for x in bx..bx + 16 {
                root.draw_pixel((x, y), &colour(v))
                    .map_err(|e| plot_err(&e))?;
            }
        }
        for k in 0..=4 {
            let f = k as f32 / 4.0;
            let y = by1 - 1 - ((by1 - by0 - 1) as f32 * f) as i32;
            let label = format!("{:.0}", from + f * (to - from));
            root.draw_text(&label, &text(12), (bx + 20, y - 6))
                .map_err(|e| plot_err(&e))?;
        }
        root.draw_text(name, &text(13), (bx, by0 - 20))
            .map_err(|e| plot_err(&e))?;
    }
    root.present().map_err(|e| plot_err(&e))?;
    Ok(())
}

/// Registers the shipped font once (plotters looks fonts up by family name).
fn font() -> Result<()> {
    static REGISTERED: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            include_bytes!("../../assets/fonts/DejaVuSans.ttf"),
        )
        .is_ok()
    });
    anyhow::ensure!(
        ok,
        "the shipped font assets/fonts/DejaVuSans.ttf could not be read"
    );
    Ok(())
}

/// A line plot of named series (colours, in order, [`COLOUR_NAMES`]; a legend right of the
/// plot names the series with non-empty names); writes a PNG 400 px high. Non-finite points
/// are left out.
pub fn plot_lines(path: &Path, axes: &Axes, series: &[(&str, Vec<(f64, f64)>)]) -> Result<()> {
    draw(path, axes, &no_bars(series), XAxis::Numbers, Style::Lines)
}

/// As [`plot_lines`], with a dot at every point (for series of a few measured values).
pub fn plot_points(path: &Path, axes: &Axes, series: &[(&str, Vec<(f64, f64)>)]) -> Result<()> {
    draw(
        path,
        axes,
        &no_bars(series),
        XAxis::Numbers,
        Style::LinesAndPoints,
    )
}

/// One series with error bars: its name and points (x, y, the bar's half-height; 0 draws
/// no bar).
pub type BarSeries<'a> = (&'a str, Vec<(f64, f64, f64)>);

/// Measured values over an ordered numeric x (e.g. view counts): points joined by lines,
/// each with its error bar.
pub fn plot_with_bars(path: &Path, axes: &Axes, series: &[BarSeries]) -> Result<()> {
    draw(path, axes, series, XAxis::Numbers, Style::LinesAndPoints)
}

/// Measured values over named categories (x of a point = the category's index): the x axis
/// labelled with the names, the series side by side within each category, points with error
/// bars and no line from one category to the next.
pub fn plot_categories(
    path: &Path,
    axes: &Axes,
    categories: &[String],
    series: &[BarSeries],
) -> Result<()> {
    draw(
        path,
        axes,
        series,
        XAxis::Categories(categories),
        Style::Points,
    )
}

fn no_bars<'a>(series: &[(&'a str, Vec<(f64, f64)>)]) -> Vec<BarSeries<'a>> {
    series
        .iter()
        .map(|(n, s)| (*n, s.iter().map(|&(x, y)| (x, y, 0.0)).collect()))
        .collect()
}

/// A numeric tick's label: at most 4 decimals, trailing zeros dropped (1, 2, 5, 10 for view
/// counts; 0.3, not 0.30000000000000004, for a tick summed from steps of 0.1).
fn tick_label(x: f64) -> String {
    let s = format!("{x:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

#[derive(Clone, Copy)]
enum XAxis<'a> {
    Numbers,
    Categories(&'a [String]),
}

#[derive(Clone, Copy, PartialEq)]
enum Style {
    Lines,
    LinesAndPoints,
    Points,
}

fn draw(path: &Path, axes: &Axes, series: &[BarSeries], x_axis: XAxis, style: Style) -> Result<()> {
    font()?;
    let finite = |&(x, y, e): &(f64, f64, f64)| x.is_finite() && y.is_finite() && e.is_finite();
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in series
        .iter()
        .flat_map(|(_, s)| s.iter())
        .filter(|p| finite(p))
    {
        x0 = x0.min(p.0);
        x1 = x1.max(p.0);
        y0 = y0.min(p.1 - p.2);
        y1 = y1.max(p.1 + p.2);
    }
    // Categories: each on its own tick, with room for the series side by side.
    let groups = series.len().max(1) as f64;
    if let XAxis::Categories(c) = x_axis {
        (x0, x1) = (-0.5, c.len().max(1) as f64 - 0.5);
    }
    // Numbers: series with error bars dodged by 1 % of the x range each, so bars at the
    // same x (every method at one view count) stay apart; lines and bare points are not.
    let dodge = if style != Style::Lines && series.iter().any(|(_, s)| s.iter().any(|p| p.2 > 0.0))
    {
        0.01 * (x1 - x0)
    } else {
        0.0
    };
    if let XAxis::Numbers = x_axis {
        let room = groups / 2.0 * dodge;
        (x0, x1) = (x0 - room, x1 + room);
    }
    let offset = |k: usize| match x_axis {
        XAxis::Numbers => (k as f64 - (groups - 1.0) / 2.0) * dodge,
        XAxis::Categories(_) => (k as f64 - (groups - 1.0) / 2.0) * 0.6 / groups,
    };
    if x0 >= x1 {
        x1 = x0 + 1.0;
    }
    if y0 >= y1 {
        y1 = y0 + 1.0;
    }
    // A margin of 5 % so points on the range's edges stay visible.
    let pad = 0.05 * (y1 - y0);
    let (y0, y1) = (y0 - pad, y1 + pad);
    anyhow::ensure!(
        (y1 - y0).is_finite() && (x1 - x0).is_finite(),
        "plot {}: the values span more than a number holds (y {y0:e} to {y1:e})",
        path.display()
    );
    let plot_err = |e: &dyn std::fmt::Display| anyhow::anyhow!("plot {}: {e}", path.display());
    let named: Vec<(usize, &str)> = series
        .iter()
        .enumerate()
        .filter(|(_, (n, _))| !n.is_empty())
        .map(|(k, (n, _))| (k, *n))
        .collect();
    // The legend in a column of its own, right of the plot, never over the data.
    let legend_width = if named.is_empty() {
        0
    } else {
        40 + 7 * named
            .iter()
            .map(|(_, n)| n.chars().count())
            .max()
            .unwrap_or(0) as u32
    };
    let root = BitMapBackend::new(path, (640 + legend_width, 400)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| plot_err(&e))?;
    let (plot_area, legend_area) = root.split_horizontally(640);
    let mut chart = ChartBuilder::on(&plot_area)
        .margin(10)
        .caption(axes.title, ("sans-serif", 18))
        .x_label_area_size(36)
        .y_label_area_size(56)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| plot_err(&e))?;
    let category = |x: &f64| match x_axis {
        XAxis::Categories(c) => {
            let i = x.round();
            if (x - i).abs() < 1e-6 && i >= 0.0 {
                c.get(i as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        }
        XAxis::Numbers => tick_label(*x),
    };
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(axes.x)
        .y_desc(axes.y)
        .label_style(("sans-serif", 12))
        .axis_desc_style(("sans-serif", 14))
        .light_line_style(WHITE.mix(0.0));
    match x_axis {
        XAxis::Categories(c) => mesh.x_labels(c.len() * 2 + 1).x_label_formatter(&category),
        XAxis::Numbers => mesh.x_label_formatter(&category),
    };
    mesh.draw().map_err(|e| plot_err(&e))?;
    for (k, (_, s)) in series.iter().enumerate() {
        let colour = COLOURS[k % COLOURS.len()];
        let dx = offset(k);
        let pts: Vec<(f64, f64, f64)> = s
            .iter()
            .filter(|p| finite(p))
            .map(|&(x, y, e)| (x + dx, y, e))
            .collect();
        if style != Style::Points {
            chart
                .draw_series(LineSeries::new(
                    pts.iter().map(|&(x, y, _)| (x, y)),
                    colour.stroke_width(2),
                ))
                .map_err(|e| plot_err(&e))?;
        }
        if style != Style::Lines {
            chart
                .draw_series(
                    pts.iter()
                        .map(|&(x, y, _)| Circle::new((x, y), 4, colour.filled())),
                )
                .map_err(|e| plot_err(&e))?;
        }
        chart
            .draw_series(pts.iter().filter(|p| p.2 > 0.0).map(|&(x, y, e)| {
                ErrorBar::new_vertical(x, y - e, y, y + e, colour.stroke_width(1), 8)
            }))
            .map_err(|e| plot_err(&e))?;
    }
    for (row, (k, name)) in named.iter().enumerate() {
        let colour = COLOURS[k % COLOURS.len()];
        let y = 40 + 20 * row as i32;
        legend_area
            .draw(&PathElement::new(
                vec![(6, y), (26, y)],
                colour.stroke_width(2),
            ))
            .map_err(|e| plot_err(&e))?;
        if style != Style::Lines {
            legend_area
                .draw(&Circle::new((16, y), 4, colour.filled()))
                .map_err(|e| plot_err(&e))?;
        }
        legend_area
            .draw_text(
                name,
                &("sans-serif", 12).into_text_style(&legend_area),
                (32, y - 7),
            )
            .map_err(|e| plot_err(&e))?;
    }
    root.present().map_err(|e| plot_err(&e))?;
    Ok(())
}

/// Histograms of `series` (values in `[lo, hi]`, `bins` equal bins) drawn as step outlines
/// in one plot, coloured as [`plot_lines`]; y is the fraction of each series per bin.
pub fn plot_histograms(
    path: &Path,
    axes: &Axes,
    series: &[(&str, Vec<f64>)],
    lo: f64,
    hi: f64,
    bins: usize,
) -> Result<()> {
    let width = (hi - lo) / bins as f64;
    let steps: Vec<(&str, Vec<(f64, f64)>)> = series
        .iter()
        .map(|(name, values)| {
            let mut counts = vec![0usize; bins];
            for &v in values.iter().filter(|v| v.is_finite()) {
                let b = (((v - lo) / width).floor().max(0.0) as usize).min(bins - 1);
                counts[b] += 1;
            }
            let total = values.len().max(1) as f64;
            let mut pts = vec![(lo, 0.0)];
            for (b, &c) in counts.iter().enumerate() {
                let f = c as f64 / total;
                pts.push((lo + b as f64 * width, f));
                pts.push((lo + (b + 1) as f64 * width, f));
            }
            pts.push((hi, 0.0));
            (*name, pts)
        })
        .collect();
    plot_lines(path, axes, &steps)
}

/// The largest deviation [`plot_deviations`] draws, % (larger ones at the edge).
pub const DEVIATION_LIMIT: f64 = 100.0;

/// Deviations with error bars: for each row `(x, y, half-width of our error bar, codes'
/// lowest, codes' highest)` (all in %), our value as a dot with its bar and the codes'
/// range as a grey bar beside it, with the 0 and ±2 % lines; writes a 800×420 PNG.
pub fn plot_deviations(path: &Path, axes: &Axes, rows: &[(f64, f64, f64, f64, f64)]) -> Result<()> {
    font()?;
    let plot_err = |e: &dyn std::fmt::Display| anyhow::anyhow!("plot {}: {e}", path.display());
    // Deviations beyond ±100 % (a run of very few histories) are drawn at the edge: the
    // range stays finite and readable (plotters' tick search does not end on an infinite
    // or astronomically wide range).
    let clip = |v: f64| {
        if v.is_finite() {
            v.clamp(-DEVIATION_LIMIT, DEVIATION_LIMIT)
        } else {
            0.0
        }
    };
    let rows: Vec<(f64, f64, f64, f64, f64)> = rows
        .iter()
        .filter(|r| r.0.is_finite())
        .map(|&(x, y, e, lo, hi)| {
            let e = if e.is_finite() {
                e.min(2.0 * DEVIATION_LIMIT)
            } else {
                0.0
            };
            (x, clip(y), e, clip(lo), clip(hi))
        })
        .collect();
    let (mut y0, mut y1) = (-2.5f64, 2.5f64);
    for &(_, y, e, lo, hi) in &rows {
        y0 = y0.min(y - e).min(lo).max(-DEVIATION_LIMIT);
        y1 = y1.max(y + e).max(hi).min(DEVIATION_LIMIT);
    }
    let pad = 0.05 * (y1 - y0);
    let n = rows.len() as f64;
    let root = BitMapBackend::new(path, (800, 420)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| plot_err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .margin(10)
        .caption(axes.title, ("sans-serif", 18))
        .x_label_area_size(36)
        .y_label_area_size(56)
        .build_cartesian_2d(-1.0..n, (y0 - pad)..(y1 + pad))
        .map_err(|e| plot_err(&e))?;
    chart
        .configure_mesh()
        .x_desc(axes.x)
        .y_desc(axes.y)
        .label_style(("sans-serif", 12))
        .axis_desc_style(("sans-serif", 14))
        .light_line_style(WHITE.mix(0.0))
        .draw()
        .map_err(|e| plot_err(&e))?;
    for (y, style) in [
        (0.0, BLACK.stroke_width(1)),
        (2.0, RGBColor(160, 160, 160).stroke_width(1)),
        (-2.0, RGBColor(160, 160, 160).stroke_width(1)),
    ] {
        chart
            .draw_series(LineSeries::new([(-1.0, y), (n, y)], style))
            .map_err(|e| plot_err(&e))?;
    }
    let grey = RGBColor(150, 150, 150);
    chart
        .draw_series(rows.iter().map(|&(x, _, _, lo, hi)| {
            Rectangle::new([(x + 0.15, lo), (x + 0.35, hi)], grey.filled())
        }))
        .map_err(|e| plot_err(&e))?
        .label("codes' range (EGSnrc, Geant4, MCNP, Penelope)")
        .legend(move |(x, y)| Rectangle::new([(x, y - 4), (x + 12, y + 4)], grey.filled()));
    let blue = COLOURS[0];
    chart
        .draw_series(rows.iter().map(|&(x, y, e, _, _)| {
            PathElement::new(vec![(x, y - e), (x, y + e)], blue.stroke_width(2))
        }))
        .map_err(|e| plot_err(&e))?;
    chart
        .draw_series(
            rows.iter()
                .map(|&(x, y, _, _, _)| Circle::new((x, y), 4, blue.filled())),
        )
        .map_err(|e| plot_err(&e))?
        .label("tomograf ± 2 standard errors")
        .legend(move |(x, y)| Circle::new((x + 6, y), 4, blue.filled()));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 12))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| plot_err(&e))?;
    root.present().map_err(|e| plot_err(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    /// Numeric ticks read as a person writes them, whatever float sum plotters made them from.
    #[test]
    fn tick_labels_are_short() {
        for (x, want) in [
            (1.0, "1"),
            (10.0, "10"),
            (0.30000000000000004, "0.3"),
            (0.7999999999999999, "0.8"),
            (0.25, "0.25"),
            (-0.0, "0"),
            (-1.5, "-1.5"),
            (1e-6, "0"),
        ] {
            assert_eq!(super::tick_label(x), want, "{x}");
        }
    }
}
