//! Scatter across an orbit: each view's scatter fitted in gantry angle with its neighbours'.
//!
//! Scatter images change slowly as the gantry turns — they vary over centimetres on the
//! panel and over tens of degrees in angle — while a Monte Carlo run's noise is independent
//! from view to view (each view draws its own histories). So a view's scatter is estimated,
//! pixel by pixel, by a least-squares quadratic in angle through the raw images of every
//! view of the scene within `angular_window_deg` of it on the same orbit, evaluated at its
//! own angle (a Savitzky–Golay filter when the views are evenly spaced). The quadratic
//! follows the images' change with angle to second order, so the window can be wide; its
//! cost is none but memory (each view's raw image is made once and kept while neighbours
//! need it). Chosen and measured against a converged Monte Carlo in docs/scatter-speed.md.
//!
//! Views are on the same orbit when they have the same panel (pixels and pitch), their
//! columns (`v`, the panel's row step) run along one rotation axis, their sources sit at the
//! same height along it and at the same distance from the panel's centre; the angle between
//! two is the angle between their central rays about that axis. Views elsewhere (another
//! orbit, a tilted panel, a parallel beam) are left out of each other's fits.
//!
//! Determinism: a view's raw image depends on the seed and its index alone, and the fit's
//! weights on the geometry alone, so the bytes do not depend on the order views are rendered
//! in or on the thread count.

use super::engine::ScatterImages;
use crate::detector::ExpectedImage;
use glam::{DMat3, DVec3};
use std::sync::{Arc, Mutex};
use tomograf_sim::error::Result;
use tomograf_sim::geometry::{View, ViewBeam};

/// The widest window, degrees each side.
pub const MAX_WINDOW_DEG: f64 = 90.0;

/// Where a cone view looks from, for comparing it with others.
struct Pose {
    /// The rotation axis: the panel's row step, unit.
    axis: DVec3,
    /// The central ray (source → panel centre) across the axis, unit.
    across: DVec3,
    /// Source → panel-centre distance, mm.
    distance: f64,
    /// The source's height along the axis, mm.
    height: f64,
}

fn pose(view: &View) -> Option<Pose> {
    let ViewBeam::Cone { source } = view.beam else {
        return None;
    };
    let axis = view.v.try_normalize()?;
    let centre = view.pixel_centre(
        (view.rows as f64 - 1.0) / 2.0,
        (view.cols as f64 - 1.0) / 2.0,
    );
    let ray = centre - source;
    let across = (ray - ray.dot(axis) * axis).try_normalize()?;
    Some(Pose {
        axis,
        across,
        distance: ray.length(),
        height: source.dot(axis),
    })
}

/// The signed angle (degrees, right-handed about `a`'s axis) from view `a` to view `b` when
/// `b` lies on `a`'s orbit (same panel, axis, height and distance), else `None`.
pub fn angle_on_orbit(a: &View, b: &View) -> Option<f64> {
    let (pa, pb) = (pose(a)?, pose(b)?);
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-6 * x.abs().max(y.abs()).max(1.0);
    let same = a.rows == b.rows
        && a.cols == b.cols
        && close(a.u.length(), b.u.length())
        && close(a.v.length(), b.v.length())
        && pa.axis.dot(pb.axis) > 1.0 - 1e-9
        && close(pa.height, pb.height)
        && close(pa.distance, pb.distance);
    same.then(|| {
        pa.axis
            .dot(pa.across.cross(pb.across))
            .atan2(pa.across.dot(pb.across))
            .to_degrees()
    })
}

/// Weights `w` with `Σ w_j y(x_j) = y(0)` for every quadratic `y`: the least-squares
/// quadratic through samples at `offsets`, evaluated at 0 — a linear fit with two distinct
/// offsets, the mean with one. Sums to 1.
pub fn fit_weights(offsets: &[f64]) -> Vec<f64> {
    let scale = offsets
        .iter()
        .fold(0.0f64, |m, x| m.max(x.abs()))
        .max(1e-300);
    let xs: Vec<f64> = offsets.iter().map(|x| x / scale).collect();
    let mut distinct: Vec<f64> = Vec::new();
    for &x in &xs {
        if distinct.iter().all(|d| (d - x).abs() > 1e-9) {
            distinct.push(x);
        }
    }
    let order = distinct.len().min(3);
    let phi = |x: f64| DVec3::new(1.0, x, x * x);
    let n = xs.len() as f64;
    match order {
        3 => {
            let mut m = DMat3::ZERO;
            for &x in &xs {
                let p = phi(x);
                m += DMat3::from_cols(p * p.x, p * p.y, p * p.z);
            }
            // Row 0 of M⁻¹ (M is symmetric, so its column 0).
            let r = m.inverse().col(0);
            xs.iter().map(|&x| r.dot(phi(x))).collect()
        }
        2 => {
            let (sx, sxx) = xs.iter().fold((0.0, 0.0), |(a, b), &x| (a + x, b + x * x));
            let det = n * sxx - sx * sx;
            xs.iter().map(|&x| (sxx - sx * x) / det).collect()
        }
        _ => vec![1.0 / n; xs.len()],
    }
}

/// The views within `window_deg` of view `index` on its orbit (itself included) and their
/// weights ([`fit_weights`] of their angles), in view order.
pub fn neighbours(views: &[View], index: usize, window_deg: f64) -> Vec<(usize, f64)> {
    let me = &views[index];
    let (ids, offsets): (Vec<usize>, Vec<f64>) = views
        .iter()
        .enumerate()
        .filter_map(|(j, v)| {
            let a = if j == index {
                0.0
            } else {
                angle_on_orbit(me, v)?
            };
            (a.abs() <= window_deg + 1e-9).then_some((j, a))
        })
        .unzip();
    ids.into_iter().zip(fit_weights(&offsets)).collect()
}

/// `Σ w·image` of every part's images (mean and second moment clamped at 0: a quadratic's
/// negative weights must not make a signal negative), the grid's standard error
/// `√(Σ w² se²)`.
pub fn combine(parts: &[(f64, &ScatterImages)]) -> ScatterImages {
    let sum = |pick: &dyn Fn(&ScatterImages) -> &ExpectedImage| {
        let mut out = pick(parts[0].1).clone();
        out.mean.iter_mut().for_each(|x| *x = 0.0);
        out.second_moment.iter_mut().for_each(|x| *x = 0.0);
        for (w, p) in parts {
            let im = pick(p);
            out.mean
                .iter_mut()
                .zip(&im.mean)
                .for_each(|(a, b)| *a += w * b);
            out.second_moment
                .iter_mut()
                .zip(&im.second_moment)
                .for_each(|(a, b)| *a += w * b);
        }
        out.mean.iter_mut().for_each(|x| *x = x.max(0.0));
        out.second_moment.iter_mut().for_each(|x| *x = x.max(0.0));
        out
    };
    let first = parts[0].1;
    let mut grid_mean = vec![0.0; first.grid_mean.len()];
    let mut variance = vec![0.0; first.grid_standard_error.len()];
    for (w, p) in parts {
        grid_mean
            .iter_mut()
            .zip(&p.grid_mean)
            .for_each(|(a, b)| *a += w * b);
        variance
            .iter_mut()
            .zip(&p.grid_standard_error)
            .for_each(|(a, b)| *a += w * w * b * b);
    }
    ScatterImages {
        single_compton: sum(&|s| &s.single_compton),
        single_rayleigh: sum(&|s| &s.single_rayleigh),
        multiple: sum(&|s| &s.multiple),
        grid: first.grid,
        grid_mean,
        grid_standard_error: variance.into_iter().map(f64::sqrt).collect(),
    }
}

/// A scene's views and the raw scatter images its renders have made, kept while neighbours
/// may still need them.
#[derive(Debug)]
pub struct OrbitScatter {
    views: Vec<View>,
    /// Each view's [`neighbours`] and their weights, found once.
    near: Vec<Vec<(usize, f64)>>,
    /// (view index, raw images), at most `capacity`.
    cache: Mutex<Vec<(usize, Arc<ScatterImages>)>>,
    capacity: usize,
}

impl OrbitScatter {
    /// The scene's `views` (in the order of their indices), fitted over `window_deg`.
    pub fn new(views: Vec<View>, window_deg: f64) -> Self {
        let near: Vec<_> = (0..views.len())
            .map(|i| neighbours(&views, i, window_deg))
            .collect();
        let capacity = near.iter().map(Vec::len).max().unwrap_or(1) * 2 + 1;
        Self {
            views,
            near,
            cache: Mutex::new(Vec::new()),
            capacity,
        }
    }

    /// The scene's view number `index`.
    pub fn view(&self, index: usize) -> View {
        self.views[index]
    }

    /// Whether `view` is this scene's view number `index`.
    pub fn holds(&self, index: usize, view: &View) -> bool {
        self.views.get(index) == Some(view)
    }

    /// View `index`'s scatter fitted over its neighbours, whose raw images `raw(j)` makes
    /// (`None` when scatter is not modelled).
    pub fn images(
        &self,
        index: usize,
        raw: impl Fn(usize) -> Result<Option<ScatterImages>>,
    ) -> Result<Option<ScatterImages>> {
        let near = &self.near[index];
        let mut parts = Vec::with_capacity(near.len());
        for &(j, w) in near {
            let cached = {
                let cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
                cache.iter().find(|(k, _)| *k == j).map(|(_, s)| s.clone())
            };
            let images = match cached {
                Some(s) => s,
                None => {
                    let Some(s) = raw(j)? else {
                        return Ok(None);
                    };
                    let s = Arc::new(s);
                    let mut cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
                    if !cache.iter().any(|(k, _)| *k == j) {
                        if cache.len() >= self.capacity {
                            // Drop the view farthest (in index, round the orbit) from this one.
                            let n = self.views.len();
                            let far = |k: usize| {
                                let d = k.abs_diff(index);
                                d.min(n - d)
                            };
                            if let Some(at) = (0..cache.len()).max_by_key(|&i| far(cache[i].0)) {
                                cache.swap_remove(at);
                            }
                        }
                        cache.push((j, s.clone()));
                    }
                    s
                }
            };
            parts.push((w, images));
        }
        let refs: Vec<(f64, &ScatterImages)> = parts.iter().map(|(w, s)| (*w, &**s)).collect();
        Ok(Some(combine(&refs)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tomograf_sim::geometry::{Beam, Detector, Geometry, Pose};

    fn geometry(pitch_mm: f64) -> Geometry {
        Geometry {
            beam: Beam::Cone {
                sad_mm: 1000.0,
                sid_mm: 1500.0,
            },
            detector: Detector::new(24, 32, pitch_mm),
            isocentre: DVec3::ZERO,
        }
    }

    fn orbit(views: usize, step_deg: f64) -> Vec<View> {
        let g = geometry(2.0);
        (0..views)
            .map(|k| g.view(Pose::new(k as f64 * step_deg, 0.0)).unwrap())
            .collect()
    }

    /// The weights reproduce any quadratic at 0 exactly, for even, uneven and one-sided
    /// offsets, and fall back to a line and a mean.
    #[test]
    fn the_fit_is_exact_on_quadratics() {
        let q = |x: f64| 3.0 - 2.0 * x + 0.5 * x * x;
        for offsets in [
            vec![-10.0, -5.0, 0.0, 5.0, 10.0],
            vec![0.0, 5.0, 10.0, 15.0],
            vec![-7.0, -1.0, 0.0, 0.0, 2.5, 30.0],
        ] {
            let w = fit_weights(&offsets);
            let at0: f64 = w.iter().zip(&offsets).map(|(w, &x)| w * q(x)).sum();
            assert!((at0 - q(0.0)).abs() < 1e-9, "{offsets:?}: {at0}");
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
        // Symmetric 5-point Savitzky–Golay (−3, 12, 17, 12, −3)/35.
        let w = fit_weights(&[-2.0, -1.0, 0.0, 1.0, 2.0]);
        for (a, b) in w.iter().zip([-3.0, 12.0, 17.0, 12.0, -3.0]) {
            assert!((a - b / 35.0).abs() < 1e-12, "{w:?}");
        }
        let line = fit_weights(&[0.0, 4.0]);
        assert!((line[0] - 1.0).abs() < 1e-12 && line[1].abs() < 1e-12);
        assert_eq!(fit_weights(&[0.0, 0.0]), vec![0.5, 0.5]);
    }

    /// On a closed 72-view orbit a 25° window takes the 11 views from −25° to +25°, wrapping
    /// round; views on another panel or another orbit are left out.
    #[test]
    fn neighbours_lie_within_the_window_on_the_same_orbit() {
        let views = orbit(72, 5.0);
        let near = neighbours(&views, 0, 25.0);
        let ids: Vec<usize> = near.iter().map(|n| n.0).collect();
        assert_eq!(ids, vec![0, 1, 2, 3, 4, 5, 67, 68, 69, 70, 71]);
        let a = angle_on_orbit(&views[0], &views[71]).unwrap();
        assert!((a.abs() - 5.0).abs() < 1e-9, "{a}");
        assert!((angle_on_orbit(&views[0], &views[1]).unwrap() + a).abs() < 1e-9);
        let other = geometry(2.5).view(Pose::new(5.0, 0.0)).unwrap();
        assert!(angle_on_orbit(&views[0], &other).is_none());
        let tilted = geometry(2.0).view(Pose::new(5.0, 10.0)).unwrap();
        assert!(angle_on_orbit(&views[0], &tilted).is_none());
        assert_eq!(neighbours(&views, 0, 0.0), vec![(0, 1.0)]);
    }
}
