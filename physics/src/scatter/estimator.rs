//! Forced detection (the point-detector estimator): at every real collision, the expected
//! signal that the next flight would deposit in each detector pixel of a coarse grid,
//!
//! `W · P(process) · p(cos θ) · A cos γ / d² · T(E′) · w(E′)`,
//!
//! with `p` the normalised angular density (sr⁻¹), `A cos γ / d²` the solid angle of one
//! detector pixel seen from the site, `T(E′)` the transmission from the site to the pixel
//! at the scattered energy (an exact Siddon trace of per-material mass thickness through
//! the composition) and `w(E′)` the detector's signal per incident photon. The coarse grid
//! is then bilinearly interpolated to every pixel. The estimate is unbiased for the grid
//! pixels; its variance grows as a site nears the detector (1/d²), which does not happen
//! for a patient separated from the panel.

use super::anti_scatter_grid::{GridTransmission, focus_slope};
use super::detection_grid::DetectionGrid;
use super::transport::{Collision, Medium};
use crate::detector::ExpectedImage;
use glam::DVec3;
use tomograf_sim::geometry::{View, ViewBeam};
use tomograf_sim::seed::frame_seed;

/// The detector's mean and second moment of signal per incident photon, per channel, on a
/// 1 keV grid (index k ↔ k + 1 keV).
#[derive(Debug, Clone, PartialEq)]
pub struct Response {
    /// `[channel][k]`.
    pub mean: Vec<Vec<f64>>,
    /// `[channel][k]`.
    pub second_moment: Vec<Vec<f64>>,
}

impl Response {
    /// Channels.
    pub fn channels(&self) -> usize {
        self.mean.len()
    }

    #[inline]
    fn at(table: &[f64], e: f64) -> f64 {
        let x = (e - 1.0).clamp(0.0, (table.len() - 1) as f64);
        let i = (x as usize).min(table.len().saturating_sub(2));
        let f = x - i as f64;
        if table.len() == 1 {
            return table[0];
        }
        table[i] * (1.0 - f) + table[i + 1] * f
    }
}

/// Which image a scored contribution belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Component {
    /// Photons scattered once, by Compton.
    SingleCompton = 0,
    /// Photons scattered once, by Rayleigh.
    SingleRayleigh = 1,
    /// Photons scattered more than once.
    Multiple = 2,
}

/// The coarse grid of scoring points on the detector.
#[derive(Debug, Clone)]
pub struct ScoreGrid {
    /// Grid rows and columns.
    pub rows: usize,
    /// Grid columns.
    pub cols: usize,
    points: Vec<DVec3>,
    /// Each point's (row, column) in the detector's pixel coordinates (fractional).
    coords: Vec<(f64, f64)>,
    normal: DVec3,
    area: f64,
    /// Unit column axis û (across the anti-scatter grid's strips).
    u_axis: DVec3,
    /// Slope of the focused anti-scatter strip at each point (0 for a parallel beam).
    focus: Vec<f64>,
}

impl ScoreGrid {
    /// A grid of at most `points` × `points` (clamped to the detector) spanning `view`'s
    /// pixel centres from corner to corner.
    pub fn new(view: &View, points: usize) -> Self {
        let rows = points.clamp(1, view.rows);
        let cols = points.clamp(1, view.cols);
        let at = |i: usize, n: usize, full: usize| {
            if n == 1 {
                (full as f64 - 1.0) * 0.5
            } else {
                i as f64 * (full as f64 - 1.0) / (n as f64 - 1.0)
            }
        };
        let mut coords = Vec::with_capacity(rows * cols);
        for i in 0..rows {
            for j in 0..cols {
                coords.push((at(i, rows, view.rows), at(j, cols, view.cols)));
            }
        }
        let points: Vec<DVec3> = coords
            .iter()
            .map(|&(r, c)| view.pixel_centre(r, c))
            .collect();
        let n = view.u.cross(view.v);
        let (normal, u_axis) = (n.normalize(), view.u.normalize());
        let focus = points
            .iter()
            .map(|&q| match view.beam {
                ViewBeam::Cone { source } => focus_slope(source, q, u_axis, normal),
                ViewBeam::Parallel { .. } => 0.0,
            })
            .collect();
        Self {
            rows,
            cols,
            points,
            coords,
            normal,
            area: n.length(),
            u_axis,
            focus,
        }
    }

    /// Number of scoring points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Bilinear interpolation of per-point values (row-major over the grid) to every pixel
    /// of a `rows × cols` detector.
    pub fn interpolate(&self, values: &[f64], rows: usize, cols: usize) -> Vec<f64> {
        let mut out = vec![0.0; rows * cols];
        for r in 0..rows {
            for c in 0..cols {
                out[r * cols + c] = self.value_at(values, r as f64, c as f64, rows, cols);
            }
        }
        out
    }

    /// Bilinear interpolation of per-point values at pixel coordinates `(r, c)`
    /// (fractional) of a `rows × cols` detector.
    pub fn value_at(&self, values: &[f64], r: f64, c: f64, rows: usize, cols: usize) -> f64 {
        let axis = |x: f64, n: usize, full: usize| -> (usize, usize, f64) {
            if n == 1 {
                return (0, 0, 0.0);
            }
            let g = x * (n as f64 - 1.0) / (full as f64 - 1.0);
            let i = (g.floor() as usize).min(n - 2);
            (i, i + 1, g - i as f64)
        };
        let (r0, r1, fr) = axis(r, self.rows, rows);
        let (c0, c1, fc) = axis(c, self.cols, cols);
        let v = |i: usize, j: usize| values[i * self.cols + j];
        (1.0 - fr) * ((1.0 - fc) * v(r0, c0) + fc * v(r0, c1))
            + fr * ((1.0 - fc) * v(r1, c0) + fc * v(r1, c1))
    }

    /// `values` of `other`'s points (row-major over `other`) at this grid's points, on a
    /// `rows × cols` detector.
    pub fn resample(
        &self,
        other: &ScoreGrid,
        values: &[f64],
        rows: usize,
        cols: usize,
    ) -> Vec<f64> {
        self.coords
            .iter()
            .map(|&(r, c)| other.value_at(values, r, c, rows, cols))
            .collect()
    }
}

/// Per-batch tallies: `[component][channel][point]` mean and second moment.
#[derive(Debug, Clone)]
pub struct Tally {
    pub(crate) mean: Vec<f64>,
    pub(crate) second: Vec<f64>,
    channels: usize,
    points: usize,
}

impl Tally {
    /// Zeros for `channels` × `points`.
    pub fn new(channels: usize, points: usize) -> Self {
        let n = 3 * channels * points;
        Self {
            mean: vec![0.0; n],
            second: vec![0.0; n],
            channels,
            points,
        }
    }

    /// Index of (component, channel, point).
    #[inline]
    pub fn index(&self, comp: usize, ch: usize, p: usize) -> usize {
        (comp * self.channels + ch) * self.points + p
    }

    /// Points per component and channel.
    pub fn points_len(&self) -> usize {
        self.points
    }

    /// Adds `other` element-wise.
    pub fn add(&mut self, other: &Tally) {
        self.mean
            .iter_mut()
            .zip(&other.mean)
            .for_each(|(a, b)| *a += b);
        self.second
            .iter_mut()
            .zip(&other.second)
            .for_each(|(a, b)| *a += b);
    }

    /// Scales component `comp` (every channel and point, mean and second moment) by `f`.
    pub fn scale_component(&mut self, comp: usize, f: f64) {
        for ch in 0..self.channels {
            let s = self.index(comp, ch, 0);
            for i in s..s + self.points {
                self.mean[i] *= f;
                self.second[i] *= f;
            }
        }
    }

    /// Channel 0's total (all components) at each point.
    pub fn total0(&self) -> Vec<f64> {
        self.channel0(&[0, 1, 2])
    }

    /// Channel 0's sum of `components` at each point.
    pub fn channel0(&self, components: &[usize]) -> Vec<f64> {
        (0..self.points)
            .map(|p| {
                components
                    .iter()
                    .map(|&c| self.mean[self.index(c, 0, p)])
                    .sum()
            })
            .collect()
    }
}

/// A check on the detection cells' bias, per batch: one scored path in `every` — chosen by
/// a hash of the batch's key and the path's count, so no random stream is touched and the
/// histories stay those of a run without it — is traced at full resolution as well, and
/// both channel-0 signals are summed per component. The run's sums give each component's
/// ratio full resolution / cells, by which its image is scaled: the cells' level error
/// (averaging μ over a cell lowers a path's expected transmission, Jensen) is removed;
/// its shape across the panel is not.
#[derive(Debug, Clone, Default)]
pub struct CellCheck {
    every: u64,
    key: u64,
    count: u64,
    /// Signal of the checked paths through the cells, per [`Component`].
    coarse: [f64; 3],
    /// The same paths traced at full resolution.
    fine: [f64; 3],
}

impl CellCheck {
    /// One path in `every` (≥ 1) checked, drawn by `key`.
    pub fn new(every: u64, key: u64) -> Self {
        Self {
            every: every.max(1),
            key,
            ..Self::default()
        }
    }

    /// Whether the next scored path is checked.
    #[inline]
    fn take(&mut self) -> bool {
        let h = frame_seed(self.key, self.count);
        self.count += 1;
        h.is_multiple_of(self.every)
    }

    /// Adds `other`'s sums.
    pub fn add(&mut self, other: &CellCheck) {
        for c in 0..3 {
            self.coarse[c] += other.coarse[c];
            self.fine[c] += other.fine[c];
        }
    }

    /// Each component's ratio full resolution / cells over the checked paths (1 where no
    /// checked path carried signal).
    pub fn ratios(&self) -> [f64; 3] {
        std::array::from_fn(|c| {
            let r = self.fine[c] / self.coarse[c];
            if self.coarse[c] > 0.0 && r.is_finite() {
                r
            } else {
                1.0
            }
        })
    }
}

/// Scores the expected detector signal of the scatter at collision `c` (photon weight
/// `weight`, `order` scatters so far, travelling along `dir`) into `tally`, through the
/// anti-scatter grid `anti` when there is one; the paths to the points traced through
/// `detection` (`None`: the medium's full-resolution composition); with a `check` (and
/// cells), the paths it draws are also traced at full resolution and summed into it.
#[allow(clippy::too_many_arguments)]
pub fn score(
    medium: &Medium,
    detection: Option<&DetectionGrid>,
    grid: &ScoreGrid,
    response: &Response,
    anti: Option<&GridTransmission>,
    c: &Collision,
    dir: DVec3,
    weight: f64,
    order: u32,
    tally: &mut Tally,
    subset: Option<(usize, usize)>,
    mut check: Option<&mut CellCheck>,
) {
    let (comp_c, comp_r) = if order == 0 {
        (
            Component::SingleCompton as usize,
            Component::SingleRayleigh as usize,
        )
    } else {
        (Component::Multiple as usize, Component::Multiple as usize)
    };
    let norms = medium.angular_norms(c);
    // Rayleigh keeps the energy: its μ/ρ are the same towards every point.
    let rayleigh_mu = medium.attenuations(c.energy_kev);
    // A subset: the points whose (row, column) parities are `subset`'s, each scored ×4
    // (every point is in the subset with probability ¼).
    let weight = if subset.is_some() {
        4.0 * weight
    } else {
        weight
    };
    for (p, &q) in grid.points.iter().enumerate() {
        if let Some((pr, pc)) = subset
            && ((p / grid.cols) % 2 != pr || (p % grid.cols) % 2 != pc)
        {
            continue;
        }
        let to = q - c.position;
        let d2 = to.length_squared();
        let dist = d2.sqrt();
        let w = to / dist;
        let solid = grid.area * w.dot(grid.normal).abs() / d2;
        let mu = dir.dot(w).clamp(-1.0, 1.0);
        let paths = match detection {
            Some(g) => g.paths(c.position, q),
            None => medium.paths(c.position, q),
        };
        let (pc, ec) = medium.compton_towards(c, &norms, mu);
        let pr = medium.rayleigh_towards(c, &norms, mu);
        // Everything but the transmission (its factor order kept: the bytes without a check
        // are those of the engine before it).
        let gc = weight * c.p_compton * pc * solid;
        let gr = weight * c.p_rayleigh * pr * solid;
        let (mut ac, mut ar) = (1.0, 1.0);
        if let Some(a) = anti {
            let (u, n, f) = (grid.u_axis, grid.normal, grid.focus[p]);
            ac = a.towards(w, u, n, f, ec);
            ar = a.towards(w, u, n, f, c.energy_kev);
        }
        let mut vc = gc * medium.transmission(&paths, ec);
        let mut vr = gr * medium.transmission_with(&paths, &rayleigh_mu);
        if anti.is_some() {
            vc *= ac;
            vr *= ar;
        }
        if detection.is_some()
            && let Some(k) = check.as_deref_mut()
            && k.take()
        {
            // The same path at full resolution: only the transmissions differ.
            let fine = medium.paths(c.position, q);
            let m1 = &response.mean[0];
            let (rc, rr) = (Response::at(m1, ec), Response::at(m1, c.energy_kev));
            k.coarse[comp_c] += vc * rc;
            k.coarse[comp_r] += vr * rr;
            k.fine[comp_c] += gc * medium.transmission(&fine, ec) * ac * rc;
            k.fine[comp_r] += gr * medium.transmission_with(&fine, &rayleigh_mu) * ar * rr;
        }
        for ch in 0..response.channels() {
            let (m1, m2) = (&response.mean[ch], &response.second_moment[ch]);
            let ic = tally.index(comp_c, ch, p);
            tally.mean[ic] += vc * Response::at(m1, ec);
            tally.second[ic] += vc * Response::at(m2, ec);
            let ir = tally.index(comp_r, ch, p);
            tally.mean[ir] += vr * Response::at(m1, c.energy_kev);
            tally.second[ir] += vr * Response::at(m2, c.energy_kev);
        }
    }
}

/// Fills `image` (fine grid) from a tally's component `comp` by interpolation.
pub fn to_image(grid: &ScoreGrid, tally: &Tally, comp: usize, image: &mut ExpectedImage) {
    let n = image.rows * image.cols;
    for ch in 0..image.channels {
        let s = tally.index(comp, ch, 0);
        let m = grid.interpolate(&tally.mean[s..s + grid.len()], image.rows, image.cols);
        let m2 = grid.interpolate(&tally.second[s..s + grid.len()], image.rows, image.cols);
        image.mean[ch * n..(ch + 1) * n].copy_from_slice(&m);
        image.second_moment[ch * n..(ch + 1) * n].copy_from_slice(&m2);
    }
}
