//! X-ray ray sampling (Methods 1.2.1): patches v = (u, s) of M×M rays at continuous pixel
//! coordinates, Q stratified samples per ray.
//!
//! Rays come from sim's [`View::ray`] and are clipped with sim's [`GridRay::clip`], so the
//! model and sim cannot disagree about geometry: pixel (0, 0) is top-left in the beam's-eye
//! view, rows run down, the world frame is LPS in mm.

use crate::error::{Result, ensure};
use rand::Rng;
use tomograf_sim::{GridRay, View, Volume};

/// A patch: centre `(row, col)` in continuous pixel coordinates, scale `s` (pixels between
/// neighbouring rays) and side `size` (M).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Patch {
    /// Centre row (continuous; pixel centres at integers).
    pub row: f64,
    /// Centre column.
    pub col: f64,
    /// Pixels between neighbouring rays (s ≥ 1).
    pub scale: f64,
    /// Rays per side (M).
    pub size: usize,
}

impl Patch {
    /// The paper's draw: s ~ U[1, S] with S = min(H, W)/M, centre uniform over the positions
    /// that keep the whole patch on the detector.
    pub fn random(rng: &mut impl Rng, rows: usize, cols: usize, size: usize) -> Result<Self> {
        ensure!(
            rows >= size && cols >= size && size > 0,
            "patch of {size}×{size} rays does not fit a {rows}×{cols} detector"
        );
        let max_scale = (rows.min(cols) as f64 / size as f64).max(1.0);
        let scale = rng.random_range(1.0..=max_scale);
        let half = 0.5 * scale * (size as f64 - 1.0);
        let pick = |rng: &mut dyn rand::RngCore, n: usize| {
            let (lo, hi) = (half, n as f64 - 1.0 - half);
            if hi > lo {
                lo + (hi - lo) * (rng.next_u32() as f64 / u32::MAX as f64)
            } else {
                0.5 * (n as f64 - 1.0)
            }
        };
        let row = pick(rng, rows);
        let col = pick(rng, cols);
        Ok(Self {
            row,
            col,
            scale,
            size,
        })
    }

    /// A patch of `size`×`size` rays spanning the whole detector (s = min(H, W)/M, one ray
    /// per s×s block of pixels), its centre jittered by up to ±s/2 so that successive draws
    /// cover every pixel; coarse rays over the whole image, for fitting global codes.
    pub fn spanning(rng: &mut impl Rng, rows: usize, cols: usize, size: usize) -> Result<Self> {
        ensure!(
            rows >= size && cols >= size && size > 0,
            "patch of {size}×{size} rays does not fit a {rows}×{cols} detector"
        );
        let scale = rows.min(cols) as f64 / size as f64;
        let mut jitter = || scale * (rng.random::<f64>() - 0.5);
        Ok(Self {
            row: 0.5 * (rows as f64 - 1.0) + jitter(),
            col: 0.5 * (cols as f64 - 1.0) + jitter(),
            scale,
            size,
        })
    }

    /// Continuous `(row, col)` of the patch's rays, row-major.
    pub fn pixels(&self) -> Vec<(f64, f64)> {
        let h = 0.5 * (self.size as f64 - 1.0);
        let mut v = Vec::with_capacity(self.size * self.size);
        for i in 0..self.size {
            for j in 0..self.size {
                v.push((
                    self.row + self.scale * (i as f64 - h),
                    self.col + self.scale * (j as f64 - h),
                ));
            }
        }
        v
    }
}

/// Every pixel centre of a `rows × cols` detector, row-major.
pub fn full_image(rows: usize, cols: usize) -> Vec<(f64, f64)> {
    (0..rows)
        .flat_map(|r| (0..cols).map(move |c| (r as f64, c as f64)))
        .collect()
}

/// Sample points of a set of rays.
#[derive(Debug, Clone)]
pub struct RaySamples {
    /// Rays R.
    pub rays: usize,
    /// Samples per ray Q.
    pub samples: usize,
    /// `R·Q` sample points in grid coordinates (voxel `(i,j,k)` is `[i, i+1)³`), ray-major.
    pub grid: Vec<[f64; 3]>,
    /// Interval length Δs per ray, mm (0 for rays that miss the volume).
    pub step_mm: Vec<f32>,
}

impl RaySamples {
    /// Points normalised to [−1, 1] over the grid box (`2g/n − 1`), flattened `R·Q·3`.
    pub fn normalised(&self, dims: [usize; 3]) -> Vec<f32> {
        let mut out = Vec::with_capacity(self.grid.len() * 3);
        for g in &self.grid {
            for a in 0..3 {
                out.push((2.0 * g[a] / dims[a] as f64 - 1.0) as f32);
            }
        }
        out
    }
}

/// Samples the rays of `view` through `pixels`, clipped to the box of `grid` (only its
/// geometry is used), with `q` samples each: stratified (one uniform draw per interval)
/// when `rng` is given, at interval midpoints otherwise (the midpoint rule sim's trilinear
/// marcher uses).
pub fn sample_rays(
    view: &View,
    grid: &Volume,
    pixels: &[(f64, f64)],
    q: usize,
    mut rng: Option<&mut dyn rand::RngCore>,
) -> Result<RaySamples> {
    ensure!(q > 0, "samples per ray must be > 0");
    view.validate()?;
    let dims = grid.dims();
    let centre = [
        dims[0] as f64 / 2.0,
        dims[1] as f64 / 2.0,
        dims[2] as f64 / 2.0,
    ];
    let mut pts = Vec::with_capacity(pixels.len() * q);
    let mut step = Vec::with_capacity(pixels.len());
    for &(r, c) in pixels {
        match GridRay::clip(grid, &view.ray(r, c)) {
            Some(gr) if gr.length() > 0.0 => {
                let h = gr.length() / q as f64;
                for k in 0..q {
                    let f = match rng.as_deref_mut() {
                        Some(rng) => rng.next_u32() as f64 / (u32::MAX as f64 + 1.0),
                        None => 0.5,
                    };
                    let mut g = gr.at(gr.t_enter + (k as f64 + f) * h);
                    for a in 0..3 {
                        g[a] = g[a].clamp(0.0, dims[a] as f64);
                    }
                    pts.push(g);
                }
                step.push(h as f32);
            }
            _ => {
                pts.extend(std::iter::repeat_n(centre, q));
                step.push(0.0);
            }
        }
    }
    Ok(RaySamples {
        rays: pixels.len(),
        samples: q,
        grid: pts,
        step_mm: step,
    })
}

/// Bilinear interpolation of a `rows × cols` row-major image at continuous `(row, col)`
/// (pixel centres at integers; clamped at the edges).
pub fn bilinear(image: &[f32], rows: usize, cols: usize, row: f64, col: f64) -> f32 {
    let r = row.clamp(0.0, (rows - 1) as f64);
    let c = col.clamp(0.0, (cols - 1) as f64);
    let (r0, c0) = (r.floor() as usize, c.floor() as usize);
    let (r1, c1) = ((r0 + 1).min(rows - 1), (c0 + 1).min(cols - 1));
    let (fr, fc) = (r - r0 as f64, c - c0 as f64);
    let at = |i: usize, j: usize| f64::from(image[i * cols + j]);
    let top = at(r0, c0) + fc * (at(r0, c1) - at(r0, c0));
    let bottom = at(r1, c0) + fc * (at(r1, c1) - at(r1, c0));
    (top + fr * (bottom - top)) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn random_patches_stay_on_the_detector() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        for _ in 0..200 {
            let p = Patch::random(&mut rng, 64, 48, 16).unwrap();
            assert!(p.scale >= 1.0 && p.scale <= 3.0);
            for (r, c) in p.pixels() {
                assert!((-1e-9..=63.0 + 1e-9).contains(&r), "{r}");
                assert!((-1e-9..=47.0 + 1e-9).contains(&c), "{c}");
            }
        }
        assert!(Patch::random(&mut rng, 8, 8, 16).is_err());
    }

    #[test]
    fn bilinear_hits_pixel_centres_and_midpoints() {
        let img = [0.0, 1.0, 2.0, 3.0];
        assert_eq!(bilinear(&img, 2, 2, 1.0, 0.0), 2.0);
        assert_eq!(bilinear(&img, 2, 2, 0.5, 0.5), 1.5);
    }
}
