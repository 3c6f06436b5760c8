//! The fast estimate: the same engine with few photons on a coarse grid, the grid then
//! smoothed by a Gaussian (σ in grid cells, weights renormalised at the borders) before
//! interpolation. Scatter is a low-frequency signal, so smoothing trades a small bias at
//! sharp scatter gradients (field edges) for most of the noise; docs/scatter.md gives its
//! error against the full Monte Carlo on held-out phantoms and its cost.

/// Smooths a row-major `rows × cols` grid in place with a separable Gaussian of standard
/// deviation `sigma` cells (0: unchanged), truncated at 3σ and renormalised at the borders
/// so that a constant stays constant.
pub fn smooth(values: &mut [f64], rows: usize, cols: usize, sigma: f64) {
    if sigma <= 0.0 || values.len() != rows * cols {
        return;
    }
    let radius = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f64> = (-radius..=radius)
        .map(|i| (-0.5 * (i as f64 / sigma).powi(2)).exp())
        .collect();
    let pass = |src: &[f64], n: usize, stride: usize, lines: usize, line_stride: usize| {
        let mut out = vec![0.0; src.len()];
        for l in 0..lines {
            for i in 0..n {
                let (mut s, mut w) = (0.0, 0.0);
                for (k, &kv) in kernel.iter().enumerate() {
                    let j = i as isize + k as isize - radius;
                    if j >= 0 && (j as usize) < n {
                        s += kv * src[l * line_stride + j as usize * stride];
                        w += kv;
                    }
                }
                out[l * line_stride + i * stride] = s / w;
            }
        }
        out
    };
    let along_rows = pass(values, cols, 1, rows, cols);
    let both = pass(&along_rows, rows, cols, cols, 1);
    values.copy_from_slice(&both);
}

#[cfg(test)]
mod tests {
    use super::smooth;

    #[test]
    fn smoothing_keeps_constants_and_sums_of_interior_impulses() {
        let mut c = vec![2.5; 7 * 5];
        smooth(&mut c, 7, 5, 1.3);
        assert!(c.iter().all(|v| (v - 2.5).abs() < 1e-12));
        let mut d = vec![0.0; 15 * 15];
        d[7 * 15 + 7] = 1.0;
        smooth(&mut d, 15, 15, 1.0);
        let sum: f64 = d.iter().sum();
        assert!((sum - 1.0).abs() < 1e-12, "{sum}");
        assert!(d[7 * 15 + 7] < 0.2 && d[7 * 15 + 8] > 0.05);
    }
}
