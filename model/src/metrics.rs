//! Evaluation metrics (Methods 1.4): PSNR, 3D SSIM with the paper's constants, RMSE.
//!
//! Volumes are compared in the data set's normalised units ([0, 1] over the HU window),
//! so MAX_I = 1 and the SSIM dynamic range L = 1; RMSE in HU is the normalised RMSE times
//! the window width.

use crate::error::{Result, ensure};

fn check(a: &[f32], b: &[f32]) -> Result<()> {
    ensure!(
        a.len() == b.len() && !a.is_empty(),
        "cannot compare volumes of {} and {} voxels",
        a.len(),
        b.len()
    );
    Ok(())
}

/// Root-mean-square difference.
pub fn rmse(a: &[f32], b: &[f32]) -> Result<f64> {
    check(a, b)?;
    let s: f64 = a
        .iter()
        .zip(b)
        .map(|(&x, &y)| (f64::from(x) - f64::from(y)).powi(2))
        .sum();
    Ok((s / a.len() as f64).sqrt())
}

/// PSNR in dB with peak `max` (eq. 14): 20·log10(max / RMSE); +∞ for identical inputs.
pub fn psnr(a: &[f32], b: &[f32], max: f64) -> Result<f64> {
    Ok(20.0 * (max / rmse(a, b)?).log10())
}

/// Window side of [`ssim3d`] (scikit-image's default `win_size`).
pub const SSIM_WINDOW: usize = 7;

/// Mean 3D SSIM (eq. 15) over every 7×7×7 window lying inside the volume, c1 = (0.01 L)²,
/// c2 = (0.03 L)², sample (co)variances (N − 1), as scikit-image's
/// `structural_similarity(win_size=7, data_range=L)` without its padded border windows.
/// Volumes are `dims` with `i` fastest.
pub fn ssim3d(a: &[f32], b: &[f32], dims: [usize; 3], range: f64) -> Result<f64> {
    ssim3d_in(a, b, dims, range, None)
}

/// [`ssim3d`] averaged over the windows whose centre voxel is in `mask` (every window
/// when `None`); errors if no window's centre is.
pub fn ssim3d_in(
    a: &[f32],
    b: &[f32],
    dims: [usize; 3],
    range: f64,
    mask: Option<&[bool]>,
) -> Result<f64> {
    check(a, b)?;
    ensure!(
        mask.is_none_or(|m| m.len() == a.len()),
        "mask of {} voxels for volumes of {}",
        mask.map_or(0, <[bool]>::len),
        a.len()
    );
    let w = SSIM_WINDOW;
    ensure!(
        dims.iter().all(|&d| d >= w) && dims.iter().product::<usize>() == a.len(),
        "3D SSIM needs volumes of at least {w} voxels per side matching dims {dims:?}"
    );
    let (c1, c2) = ((0.01 * range).powi(2), (0.03 * range).powi(2));
    // Summed-volume tables of x, y, x², y², xy.
    let [nx, ny, nz] = dims;
    let (sx, sy, sz) = (nx + 1, ny + 1, nz + 1);
    let mut tables = vec![vec![0.0f64; sx * sy * sz]; 5];
    let at = |i: usize, j: usize, k: usize| i + sx * (j + sy * k);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let n = i + nx * (j + ny * k);
                let (x, y) = (f64::from(a[n]), f64::from(b[n]));
                let v = [x, y, x * x, y * y, x * y];
                for (t, val) in tables.iter_mut().zip(v) {
                    t[at(i + 1, j + 1, k + 1)] = val
                        + t[at(i, j + 1, k + 1)]
                        + t[at(i + 1, j, k + 1)]
                        + t[at(i + 1, j + 1, k)]
                        - t[at(i, j, k + 1)]
                        - t[at(i, j + 1, k)]
                        - t[at(i + 1, j, k)]
                        + t[at(i, j, k)];
                }
            }
        }
    }
    let boxsum = |t: &[f64], i: usize, j: usize, k: usize| {
        let (i1, j1, k1) = (i + w, j + w, k + w);
        t[at(i1, j1, k1)] - t[at(i, j1, k1)] - t[at(i1, j, k1)] - t[at(i1, j1, k)]
            + t[at(i, j, k1)]
            + t[at(i, j1, k)]
            + t[at(i1, j, k)]
            - t[at(i, j, k)]
    };
    let np = (w * w * w) as f64;
    let (mut total, mut count) = (0.0, 0usize);
    for k in 0..=nz - w {
        for j in 0..=ny - w {
            for i in 0..=nx - w {
                let centre = (i + w / 2) + nx * ((j + w / 2) + ny * (k + w / 2));
                if mask.is_some_and(|m| !m[centre]) {
                    continue;
                }
                let s: Vec<f64> = tables.iter().map(|t| boxsum(t, i, j, k)).collect();
                let (mx, my) = (s[0] / np, s[1] / np);
                let cov_norm = np / (np - 1.0);
                let vx = (s[2] / np - mx * mx) * cov_norm;
                let vy = (s[3] / np - my * my) * cov_norm;
                let vxy = (s[4] / np - mx * my) * cov_norm;
                total += ((2.0 * mx * my + c1) * (2.0 * vxy + c2))
                    / ((mx * mx + my * my + c1) * (vx + vy + c2));
                count += 1;
            }
        }
    }
    ensure!(count > 0, "no SSIM window is centred inside the mask");
    Ok(total / count as f64)
}

/// Root-mean-square difference over the voxels in `mask`; errors if the mask is empty.
pub fn rmse_in(a: &[f32], b: &[f32], mask: &[bool]) -> Result<f64> {
    check(a, b)?;
    ensure!(
        mask.len() == a.len(),
        "mask of {} voxels for volumes of {}",
        mask.len(),
        a.len()
    );
    let (mut s, mut n) = (0.0f64, 0usize);
    for ((&x, &y), _) in a.iter().zip(b).zip(mask).filter(|(_, m)| **m) {
        s += (f64::from(x) - f64::from(y)).powi(2);
        n += 1;
    }
    ensure!(n > 0, "the mask holds no voxel");
    Ok((s / n as f64).sqrt())
}

/// Mean and sample standard deviation (0 for a single value).
pub fn mean_std(v: &[f64]) -> (f64, f64) {
    if v.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let m = v.iter().sum::<f64>() / v.len() as f64;
    if v.len() < 2 {
        return (m, 0.0);
    }
    let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64;
    (m, var.sqrt())
}

/// The body mask's threshold, HU: voxels whose ground truth is above it are "body".
pub const BODY_HU: f32 = -900.0;

/// Metrics of one reconstruction: over the whole volume, and inside the body (voxels whose
/// ground truth is above [`BODY_HU`]; SSIM over the windows centred there), since air
/// dominates whole-volume figures. PSNR in dB, RMSE in HU. Body figures are NaN in score
/// files written before they existed.
#[derive(Debug, Clone, Copy)]
pub struct Scores {
    pub psnr: f64,
    pub ssim: f64,
    pub rmse_hu: f64,
    pub body_psnr: f64,
    pub body_ssim: f64,
    pub body_rmse_hu: f64,
}

impl PartialEq for Scores {
    /// Equal bit for bit in the body figures (so NaN equals NaN: files written before them).
    fn eq(&self, o: &Self) -> bool {
        let body = |s: &Self| [s.body_psnr, s.body_ssim, s.body_rmse_hu].map(f64::to_bits);
        (self.psnr, self.ssim, self.rmse_hu) == (o.psnr, o.ssim, o.rmse_hu) && body(self) == body(o)
    }
}

/// Scores `volume` (normalised units, as the model reconstructs) against `item`'s ground
/// truth. The reconstruction is clamped to [0, 1] first, as the ground truth is.
pub fn score(item: &crate::data::Item, volume: &tomograf_sim::Volume) -> Result<Scores> {
    let Some(gt) = item.ct.as_ref() else {
        return Err(crate::error::ModelError::Invalid(format!(
            "item {} has no ground-truth CT",
            item.id
        )));
    };
    let width = f64::from(item.window.hi - item.window.lo);
    // The model's density is unbounded above; the ground truth is clamped to [0, 1].
    let v: Vec<f32> = volume.data().iter().map(|x| x.clamp(0.0, 1.0)).collect();
    let body = (BODY_HU - item.window.lo) / (item.window.hi - item.window.lo);
    let mask: Vec<bool> = gt.data().iter().map(|&x| x > body).collect();
    ensure!(
        mask.iter().any(|&m| m),
        "the ground truth of item {} has no voxel above {BODY_HU} HU (no body to score)",
        item.id
    );
    let body_rmse = rmse_in(&v, gt.data(), &mask)?;
    Ok(Scores {
        psnr: psnr(&v, gt.data(), 1.0)?,
        ssim: ssim3d(&v, gt.data(), gt.dims(), 1.0)?,
        rmse_hu: rmse(&v, gt.data())? * width,
        body_psnr: -20.0 * body_rmse.log10(),
        body_ssim: ssim3d_in(&v, gt.data(), gt.dims(), 1.0, Some(&mask))?,
        body_rmse_hu: body_rmse * width,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Direct SSIM of one window, computed without summed tables.
    fn window_ssim(a: &[f32], b: &[f32], dims: [usize; 3], o: [usize; 3]) -> f64 {
        let w = SSIM_WINDOW;
        let mut xs = Vec::new();
        let mut ys = Vec::new();
        for k in 0..w {
            for j in 0..w {
                for i in 0..w {
                    let n = (o[0] + i) + dims[0] * ((o[1] + j) + dims[1] * (o[2] + k));
                    xs.push(f64::from(a[n]));
                    ys.push(f64::from(b[n]));
                }
            }
        }
        let n = xs.len() as f64;
        let mx = xs.iter().sum::<f64>() / n;
        let my = ys.iter().sum::<f64>() / n;
        let vx = xs.iter().map(|x| (x - mx).powi(2)).sum::<f64>() / (n - 1.0);
        let vy = ys.iter().map(|y| (y - my).powi(2)).sum::<f64>() / (n - 1.0);
        let cxy = xs
            .iter()
            .zip(&ys)
            .map(|(x, y)| (x - mx) * (y - my))
            .sum::<f64>()
            / (n - 1.0);
        let (c1, c2) = (1e-4, 9e-4);
        ((2.0 * mx * my + c1) * (2.0 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))
    }

    #[test]
    fn ssim_matches_direct_window_sums_and_metrics_their_definitions() {
        let dims = [9, 8, 7];
        let n = 9 * 8 * 7;
        let a: Vec<f32> = (0..n).map(|i| ((i * 37 % 101) as f32) / 101.0).collect();
        let b: Vec<f32> = (0..n).map(|i| ((i * 53 % 89) as f32) / 89.0).collect();
        let mut direct = 0.0;
        let mut count = 0;
        for k in 0..1 {
            for j in 0..2 {
                for i in 0..3 {
                    direct += window_ssim(&a, &b, dims, [i, j, k]);
                    count += 1;
                }
            }
        }
        let fast = ssim3d(&a, &b, dims, 1.0).unwrap();
        assert!((fast - direct / count as f64).abs() < 1e-9, "{fast}");
        assert!((ssim3d(&a, &a, dims, 1.0).unwrap() - 1.0).abs() < 1e-12);
        // PSNR of a constant offset 0.1 with peak 1: 20 dB exactly.
        let c: Vec<f32> = a.iter().map(|x| x + 0.1).collect();
        assert!((psnr(&a, &c, 1.0).unwrap() - 20.0).abs() < 1e-4);
        assert!(rmse(&a, &b[..10]).is_err());
        assert_eq!(mean_std(&[1.0, 3.0]), (2.0, 2f64.sqrt()));
        // Masks: all-true is the unmasked metric; one window's centre gives that window.
        let all = vec![true; n];
        assert_eq!(ssim3d_in(&a, &b, dims, 1.0, Some(&all)).unwrap(), fast);
        assert_eq!(rmse_in(&a, &b, &all).unwrap(), rmse(&a, &b).unwrap());
        let mut one = vec![false; n];
        one[(2 + 3) + 9 * ((1 + 3) + 8 * 3)] = true;
        let w = ssim3d_in(&a, &b, dims, 1.0, Some(&one)).unwrap();
        assert!(
            (w - window_ssim(&a, &b, dims, [2, 1, 0])).abs() < 1e-9,
            "{w}"
        );
        assert!(
            (rmse_in(&a, &b, &one).unwrap()
                - (f64::from(a[(5) + 9 * (4 + 8 * 3)]) - f64::from(b[(5) + 9 * (4 + 8 * 3)]))
                    .abs())
            .abs()
                < 1e-12
        );
        assert!(ssim3d_in(&a, &b, dims, 1.0, Some(&vec![false; n])).is_err());
    }
}
