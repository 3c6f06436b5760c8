//! Feldkamp–Davis–Kress (FDK) filtered backprojection for a flat-panel cone beam on a
//! circular orbit (L. A. Feldkamp, L. C. Davis, J. W. Kress, "Practical cone-beam
//! algorithm", J. Opt. Soc. Am. A 1 (1984) 612; notation of Kak & Slaney, "Principles of
//! Computerized Tomographic Imaging", ch. 3.6).
//!
//! With the source at distance `D` = SAD from the isocentre and detector coordinates
//! `(a, b)` rescaled to a virtual detector through the isocentre (`a = Δu·SAD/SID` from
//! the principal point, where the central ray meets the panel):
//!
//! 1. **Cosine weighting**: `p'(a, b) = p(a, b) · D / sqrt(D² + a² + b²)`.
//! 2. **Ramp filtering** along detector rows: `q = τ · (h ∗ p')` with the band-limited
//!    discrete ramp kernel of Kak & Slaney (eq. 3.61: `h(0) = 1/4τ²`, `h(nτ) = −1/(nπτ)²`
//!    for odd `n`, 0 for even `n`; `τ` the virtual pixel pitch), applied by zero-padded
//!    FFT (`rustfft`, at least twice the row length, so the convolution is linear) and
//!    multiplied in frequency by a [`Window`].
//! 3. **Angular weighting** (see [`AngularWeighting`]): `½·Δβ_i` per view for full or
//!    sparse scans, Parker weights `w(β, γ)·Δβ` for short scans.
//! 4. **Voxel-driven backprojection** with the distance weight `(D / L)²`, `L` the
//!    distance from the source to the voxel along the central ray: each voxel centre is
//!    projected with the view's own geometry ([`tomograf_sim::geometry::View`]: the same
//!    pixel-(0, 0)-top-left convention the projector uses) and the filtered image is
//!    sampled bilinearly (0 outside the panel).
//!
//! The result is linear attenuation (mm⁻¹) when the images are line integrals.
//! FDK is exact only in the central plane of a full circular scan; with few views it
//! shows strong streaks — that is what it is kept for, as a baseline.
//!
//! Parallelism: filtering runs per view, backprojection per k-slice of the output; each
//! voxel sums its views in order, so results are bit-identical for any thread count.

use glam::DVec3;
use rayon::prelude::*;
use rustfft::FftPlanner;
use rustfft::num_complex::Complex;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use tomograf_sim::error::{Result, SimError};
use tomograf_sim::geometry::{Beam, Geometry, Pose, View, ViewBeam};
use tomograf_sim::render::Projection;
use tomograf_sim::volume::Volume;

/// Apodisation of the ramp filter, a function of the frequency `f` in cycles per sample
/// (Nyquist = 0.5), as in scikit-image's `iradon`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Window {
    /// Plain ramp (Ram-Lak): 1. Sharpest, noisiest.
    #[default]
    RamLak,
    /// Shepp–Logan: `sin(πf)/(πf)` (0.64 at Nyquist).
    SheppLogan,
    /// Cosine: `cos(πf)` (0 at Nyquist).
    Cosine,
    /// Hann: `½(1 + cos 2πf)` (0 at Nyquist). Smoothest.
    Hann,
}

impl Window {
    /// Gain at frequency `f` (cycles/sample, 0 ≤ f ≤ 0.5).
    pub fn gain(&self, f: f64) -> f64 {
        match self {
            Self::RamLak => 1.0,
            Self::SheppLogan => {
                if f == 0.0 {
                    1.0
                } else {
                    (PI * f).sin() / (PI * f)
                }
            }
            Self::Cosine => (PI * f).cos(),
            Self::Hann => 0.5 * (1.0 + (2.0 * PI * f).cos()),
        }
    }
}

/// How each view's share of the orbit is weighted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum AngularWeighting {
    /// Parker weights when the views form a monotonic short scan (an arc shorter than
    /// 360° but at least 180° plus the fan angle); angular gaps otherwise.
    #[default]
    Auto,
    /// Each view stands for the arc halfway to its neighbours on the circle
    /// (`Δβ_i = (β_{i+1} − β_{i−1})/2`, wrapping round; a single view gets 2π), and every
    /// ray counts ½ because a full circle measures it twice. Exact weighting for evenly
    /// spread full scans; for sparse or limited views it keeps the full-scan amplitude
    /// but cannot make up for the missing data.
    Gaps,
    /// Parker (1982) short-scan weights, generalised to arcs longer than 180° + fan
    /// angle by using the half-overscan `(arc − 180°)/2` in place of the half fan angle.
    /// Needs views in monotonic order, evenly spaced, over an arc ≥ 180° + fan angle.
    Parker,
}

/// FDK settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct FdkOptions {
    /// Ramp-filter window.
    pub window: Window,
    /// Angular weighting.
    pub weighting: AngularWeighting,
}

/// Per-view geometry for backprojection: four linear forms of the voxel index.
#[derive(Debug, Clone, Copy)]
struct Forms {
    /// `(constant, d/di, d/dj, d/dk)` of col·w, row·w, w and the central-ray distance.
    col: [f64; 4],
    row: [f64; 4],
    w: [f64; 4],
    dist: [f64; 4],
}

impl Forms {
    fn new(view: &View, source: DVec3, centre_dir: DVec3, grid: &Volume) -> Self {
        let (u, v) = (view.u, view.v);
        let n = u.cross(v);
        let (uu, uv, vv) = (u.dot(u), u.dot(v), v.dot(v));
        let det = uu * vv - uv * uv;
        // Dual vectors in the panel plane: ũ·u = 1, ũ·v = 0; ṽ·v = 1, ṽ·u = 0.
        let ud = (vv * u - uv * v) / det;
        let vd = (uu * v - uv * u) / det;
        let d = (view.detector_origin - source).dot(n);
        let so = source - view.detector_origin;
        // hit − O = (S − O) + d·(x − S)/(n·(x − S)); times w = n·(x − S) it is linear in x.
        let a_col = so.dot(ud) * n + d * ud;
        let a_row = so.dot(vd) * n + d * vd;
        let form = |a: DVec3| {
            let dir = grid.direction();
            let sp = grid.spacing();
            [
                a.dot(grid.origin() - source),
                a.dot(dir.x_axis) * sp.x,
                a.dot(dir.y_axis) * sp.y,
                a.dot(dir.z_axis) * sp.z,
            ]
        };
        Self {
            col: form(a_col),
            row: form(a_row),
            w: form(n),
            dist: form(centre_dir),
        }
    }
}

/// Reconstructs linear attenuation (mm⁻¹) on the grid of `template` from line-integral
/// images taken by `geometry` (cone beam) at `poses` on a circular orbit (φ = 0 for every
/// pose, θ in any order). See the module docs for the algorithm.
///
/// Errors: no views, an image count or size that does not match, non-finite pixels, a
/// parallel beam, a pose with φ ≠ 0 (not a circular orbit), or Parker weighting asked of
/// views that are not a short scan.
pub fn fdk(
    projections: &[Projection],
    geometry: &Geometry,
    poses: &[Pose],
    options: &FdkOptions,
    template: &Volume,
) -> Result<Volume> {
    geometry.validate()?;
    let Beam::Cone { sad_mm, sid_mm } = geometry.beam else {
        return Err(SimError::InvalidGeometry(
            "FDK reconstructs cone-beam projections; this geometry is parallel-beam".into(),
        ));
    };
    if let Some((i, p)) = poses
        .iter()
        .enumerate()
        .find(|(_, p)| p.phi_deg.abs() > 1e-9)
    {
        return Err(SimError::InvalidGeometry(format!(
            "FDK needs a circular orbit (φ = 0 for every view), but view {i} has φ = {}°; use SART for arbitrary views",
            p.phi_deg
        )));
    }
    if projections.len() != poses.len() {
        return Err(SimError::InvalidProjections(format!(
            "{} projections were given for {} poses",
            projections.len(),
            poses.len()
        )));
    }
    let views = geometry.views(poses)?;
    super::check_projections(projections, &views)?;

    let det = geometry.detector;
    let iso = geometry.isocentre;
    let scale = sad_mm / sid_mm;
    let tau = det.pitch_u_mm * scale;
    let (r0, c0) = views[0]
        .project_point(iso)
        .ok_or_else(|| SimError::InvalidGeometry("the isocentre does not project".into()))?;
    let a_of = |c: usize| (c as f64 - c0) * det.pitch_u_mm * scale;
    let b_of = |r: usize| (r as f64 - r0) * det.pitch_v_mm * scale;
    let half_fan = (0..det.cols)
        .map(|c| (a_of(c).abs() / sad_mm).atan())
        .fold(0.0, f64::max)
        + (0.5 * tau / sad_mm).atan();
    let weights = angular_weights(poses, options.weighting, half_fan)?;

    // Ramp filter in frequency, zero-padded to a power of two ≥ 2·cols.
    let n_pad = (2 * det.cols).next_power_of_two();
    let mut planner = FftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(n_pad);
    let inv = planner.plan_fft_inverse(n_pad);
    let mut kernel: Vec<Complex<f64>> = (0..n_pad)
        .map(|k| {
            let n = if k < n_pad / 2 {
                k as i64
            } else {
                k as i64 - n_pad as i64
            };
            let h = if n == 0 {
                1.0 / (4.0 * tau * tau)
            } else if n % 2 != 0 {
                -1.0 / ((n as f64 * PI * tau).powi(2))
            } else {
                0.0
            };
            Complex::new(h, 0.0)
        })
        .collect();
    fwd.process(&mut kernel);
    let filter: Vec<f64> = (0..n_pad)
        .map(|k| {
            let f = k.min(n_pad - k) as f64 / n_pad as f64;
            tau * kernel[k].re * options.window.gain(f) / n_pad as f64
        })
        .collect();

    // Weighted, filtered images (f32, row-major).
    let cos_w: Vec<f64> = (0..det.rows * det.cols)
        .map(|p| {
            let (a, b) = (a_of(p % det.cols), b_of(p / det.cols));
            sad_mm / (sad_mm * sad_mm + a * a + b * b).sqrt()
        })
        .collect();
    let filtered: Vec<Vec<f32>> = projections
        .par_iter()
        .zip(weights.par_iter())
        .map(|(p, w)| {
            let mut out = vec![0.0f32; det.rows * det.cols];
            let mut buf = vec![Complex::new(0.0, 0.0); n_pad];
            for r in 0..det.rows {
                buf.fill(Complex::new(0.0, 0.0));
                for (c, b) in buf[..det.cols].iter_mut().enumerate() {
                    let i = r * det.cols + c;
                    b.re = f64::from(p.data[i]) * cos_w[i] * w.column(a_of(c), sad_mm);
                }
                fwd.process(&mut buf);
                for (x, f) in buf.iter_mut().zip(&filter) {
                    *x *= *f;
                }
                inv.process(&mut buf);
                for (o, b) in out[r * det.cols..(r + 1) * det.cols].iter_mut().zip(&buf) {
                    *o = (b.re * w.scalar) as f32;
                }
            }
            out
        })
        .collect();

    // Voxel-driven backprojection.
    let forms: Vec<Forms> = views
        .iter()
        .map(|v| {
            let ViewBeam::Cone { source } = v.beam else {
                unreachable!("cone geometry gives cone views")
            };
            Forms::new(v, source, (iso - source).normalize(), template)
        })
        .collect();
    let [nx, ny, _] = template.dims();
    let (rows, cols) = (det.rows, det.cols);
    let mut data = vec![0.0f32; template.len()];
    data.par_chunks_mut(nx * ny)
        .enumerate()
        .for_each(|(k, slice)| {
            let mut acc = vec![0.0f64; nx * ny];
            for (f, img) in forms.iter().zip(&filtered) {
                let at = |l: &[f64; 4], j: usize| l[0] + l[2] * j as f64 + l[3] * k as f64;
                for j in 0..ny {
                    let (c_j, r_j, w_j, d_j) =
                        (at(&f.col, j), at(&f.row, j), at(&f.w, j), at(&f.dist, j));
                    for i in 0..nx {
                        let fi = i as f64;
                        let w = w_j + f.w[1] * fi;
                        if w <= 0.0 {
                            continue;
                        }
                        let col = (c_j + f.col[1] * fi) / w;
                        let row = (r_j + f.row[1] * fi) / w;
                        let val = bilinear(img, rows, cols, row, col);
                        if val != 0.0 {
                            let l = d_j + f.dist[1] * fi;
                            let m = sad_mm / l;
                            acc[i + nx * j] += m * m * val;
                        }
                    }
                }
            }
            for (o, a) in slice.iter_mut().zip(&acc) {
                *o = *a as f32;
            }
        });
    super::on_grid(template, data)
}

/// Bilinear sample of a row-major image at continuous `(row, col)` (pixel centres at
/// integers); pixels outside the image count as 0.
#[inline(always)]
fn bilinear(img: &[f32], rows: usize, cols: usize, row: f64, col: f64) -> f64 {
    if !(row > -1.0 && col > -1.0 && row < rows as f64 && col < cols as f64) {
        return 0.0;
    }
    let (r0, c0) = (row.floor(), col.floor());
    let (fr, fc) = (row - r0, col - c0);
    let (r0, c0) = (r0 as isize, c0 as isize);
    let px = |r: isize, c: isize| {
        if r < 0 || c < 0 || r >= rows as isize || c >= cols as isize {
            0.0
        } else {
            f64::from(img[r as usize * cols + c as usize])
        }
    };
    (1.0 - fr) * ((1.0 - fc) * px(r0, c0) + fc * px(r0, c0 + 1))
        + fr * ((1.0 - fc) * px(r0 + 1, c0) + fc * px(r0 + 1, c0 + 1))
}

/// One view's angular weight: a scalar, and Parker's per-column factor when it applies.
#[derive(Debug, Clone, Copy)]
struct ViewWeight {
    scalar: f64,
    /// `(β, half-overscan δ, rotation sense ±1)` for Parker weighting.
    parker: Option<(f64, f64, f64)>,
}

impl ViewWeight {
    /// Factor for the detector column at virtual coordinate `a` (mm).
    fn column(&self, a: f64, sad: f64) -> f64 {
        let Some((beta, delta, sense)) = self.parker else {
            return 1.0;
        };
        // Fan angle measured in the sense of rotation: a column to the right of the
        // principal point (+u) turns the ray clockwise seen from +z.
        let gamma = -sense * (a / sad).atan();
        parker(beta, gamma, delta)
    }
}

/// Parker's weight for fan angle `gamma` at orbit position `beta` of a scan over
/// `[0, π + 2δ]`; satisfies `w(β, γ) + w(β + π + 2γ, −γ) = 1`.
fn parker(beta: f64, gamma: f64, delta: f64) -> f64 {
    let s2 = |x: f64| x.sin().powi(2);
    if beta < 0.0 || beta > PI + 2.0 * delta {
        0.0
    } else if beta < 2.0 * (delta - gamma) {
        s2(PI / 4.0 * beta / (delta - gamma))
    } else if beta <= PI - 2.0 * gamma {
        1.0
    } else {
        s2(PI / 4.0 * (PI + 2.0 * delta - beta) / (delta + gamma))
    }
}

/// Angular weights per view.
fn angular_weights(
    poses: &[Pose],
    mode: AngularWeighting,
    half_fan: f64,
) -> Result<Vec<ViewWeight>> {
    let theta: Vec<f64> = poses.iter().map(|p| p.theta_deg.to_radians()).collect();
    let n = theta.len();
    let short = short_scan(&theta);
    let use_parker = match mode {
        AngularWeighting::Gaps => false,
        AngularWeighting::Parker => {
            let Some((span, _)) = short else {
                return Err(SimError::InvalidGeometry(
                    "Parker weighting needs at least 3 views in monotonic order, evenly spaced, over an arc shorter than 360°".into(),
                ));
            };
            if span < PI + 2.0 * half_fan - 1e-9 {
                return Err(SimError::InvalidGeometry(format!(
                    "Parker weighting needs an arc of at least 180° + fan angle ({:.2}°); the views span {:.2}°",
                    (PI + 2.0 * half_fan).to_degrees(),
                    span.to_degrees()
                )));
            }
            true
        }
        AngularWeighting::Auto => short.is_some_and(|(span, _)| span >= PI + 2.0 * half_fan),
    };
    if use_parker {
        let (span, sense) = short.expect("checked above");
        let step = span / (n - 1) as f64;
        let delta = (span - PI) / 2.0;
        return Ok(theta
            .iter()
            .map(|t| ViewWeight {
                scalar: step,
                parker: Some((sense * (t - theta[0]), delta, sense)),
            })
            .collect());
    }
    // Gaps on the circle: sort positions in [0, 2π).
    let pos: Vec<f64> = theta.iter().map(|t| t.rem_euclid(2.0 * PI)).collect();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| pos[a].total_cmp(&pos[b]).then(a.cmp(&b)));
    let mut w = vec![0.0; n];
    for (m, &i) in order.iter().enumerate() {
        let next = order[(m + 1) % n];
        let prev = order[(m + n - 1) % n];
        let gap_next = (pos[next] - pos[i]).rem_euclid(2.0 * PI);
        let gap_prev = (pos[i] - pos[prev]).rem_euclid(2.0 * PI);
        // A single view (or coincident neighbours wrapping round) spans the whole circle.
        let gap_next = if n == 1 { 2.0 * PI } else { gap_next };
        let gap_prev = if n == 1 { 2.0 * PI } else { gap_prev };
        w[i] = 0.5 * (gap_next + gap_prev) / 2.0;
    }
    Ok(w.into_iter()
        .map(|scalar| ViewWeight {
            scalar,
            parker: None,
        })
        .collect())
}

/// `(span, rotation sense)` when the angles are ≥ 3, strictly monotonic, evenly spaced
/// (to 1 %) and cover less than the full circle (span + one step < 360°).
fn short_scan(theta: &[f64]) -> Option<(f64, f64)> {
    let n = theta.len();
    if n < 3 {
        return None;
    }
    let span = theta[n - 1] - theta[0];
    let sense = span.signum();
    let step = span / (n - 1) as f64;
    let even = theta
        .windows(2)
        .all(|w| ((w[1] - w[0]) - step).abs() <= 0.01 * step.abs());
    (even && step != 0.0 && span.abs() + step.abs() < 2.0 * PI - 1e-9)
        .then_some((span.abs(), sense))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Parker's weights of a ray and its conjugate add to 1 (the property that makes a
    /// short scan count every ray once), checked on a grid of (β, γ).
    #[test]
    fn parker_weights_are_complementary() {
        let delta = 0.2;
        for bi in 0..=50 {
            let beta = (PI + 2.0 * delta) * bi as f64 / 50.0;
            for gi in -10..=10 {
                let gamma = delta * gi as f64 / 10.0 * 0.999;
                let conj = beta + PI + 2.0 * gamma;
                let (w1, w2) = (parker(beta, gamma, delta), parker(conj, -gamma, delta));
                let back = parker(beta - PI + 2.0 * gamma, -gamma, delta);
                // The conjugate lies either later (β + π + 2γ) or earlier (β − π + 2γ).
                let sum = w1 + if conj <= PI + 2.0 * delta { w2 } else { back };
                assert!((sum - 1.0).abs() < 1e-12, "β {beta} γ {gamma}: {sum}");
            }
        }
    }

    #[test]
    fn full_scan_gaps_are_uniform_and_sparse_sum_to_a_circle() {
        let poses: Vec<Pose> = (0..8).map(|i| Pose::new(45.0 * i as f64, 0.0)).collect();
        let w = angular_weights(&poses, AngularWeighting::Auto, 0.1).unwrap();
        for x in &w {
            assert!((x.scalar - 0.5 * PI / 4.0).abs() < 1e-12 && x.parker.is_none());
        }
        let poses = [Pose::new(0.0, 0.0), Pose::new(90.0, 0.0)];
        let w = angular_weights(&poses, AngularWeighting::Auto, 0.1).unwrap();
        assert!((w[0].scalar + w[1].scalar - PI).abs() < 1e-12);
        let one = angular_weights(&[Pose::AP], AngularWeighting::Auto, 0.1).unwrap();
        assert!((one[0].scalar - PI).abs() < 1e-12);
    }
}
