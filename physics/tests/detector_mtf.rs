//! Blur: the MTF measured from a slanted edge (ISO 12233-style) on the recorded image
//! against the configured PSF's analytic transfer function.
//!
//! Edge: point-sampled, slope 1/16 (3.58°) from the columns, so the rows sample 16 exact
//! sub-pixel phases; pixels are projected onto the edge normal and binned at 1/16 pixel
//! (one bin per phase: no bin averaging), the edge spread function differentiated and its
//! DFT taken at frequencies up to Nyquist (no window: the image is noise-free).
//!
//! Analytic: PSF transform × pixel aperture sinc, in 2-D at (ν cos α, −ν sin α), summed
//! over the aliases of the pixel sampling (Poisson summation):
//! K(fx, fy) = Σ_{jx, jy} [(1 − t)·G(f) + t·E(fx)E(fy)]·sinc(fx)·sinc(fy) at f + j,
//! G = exp(−2π²σ²f²), E(f) = 1/(1 + (2πLf)²), frequencies in cycles per pixel.
//! Tolerance 10⁻⁵ (absolute MTF) against the aliased sum: what is left is the ±5σ cut of
//! the Gaussian (< 6·10⁻⁷ of its mass), the f32 storage of the image (~10⁻⁷ after the DFT)
//! and the alias sum cut at |j| ≤ 60; measured worst differences are ≤ 2·10⁻⁷. Against
//! the continuous (un-aliased) G·sinc the tolerance is 2·10⁻³, for σ = 1.2 px where the
//! aliases add < 10⁻³ below Nyquist (measured 4.9·10⁻⁴).

use std::f64::consts::PI;
use tomograf_physics::detector::*;
use tomograf_sim::geometry::Detector;

const ROWS: usize = 256;
const COLS: usize = 160;
const SLOPE: f64 = 1.0 / 16.0;

/// Measured MTF at `freqs` (cycles per pixel along the edge normal).
fn slanted_edge_mtf(blur: Blur, freqs: &[f64]) -> Vec<f64> {
    let pitch = 0.1;
    let model = DetectorModel {
        blur: Blur {
            sigma_mm: blur.sigma_mm * pitch,
            tail_fraction: blur.tail_fraction,
            tail_length_mm: blur.tail_length_mm * pitch,
        },
        ..DetectorModel::ideal()
    };
    let c0 = 80.0 + 1.0 / 32.0;
    let mut img = ExpectedImage::zeros(&Detector::new(ROWS, COLS, pitch), 1);
    for r in 0..ROWS {
        for c in 0..COLS {
            let high = c as f64 - c0 - r as f64 * SLOPE > 0.0;
            let v = if high { 1000.0 } else { 100.0 };
            img.mean[r * COLS + c] = v;
            img.second_moment[r * COLS + c] = v;
        }
    }
    let raw = model.record(&img, 0).unwrap();
    // ESF: bin j holds the pixels at x = j/16 − 1/32 (x: column distance from the edge).
    let half = 60 * 16;
    let mut sum = vec![0.0; 2 * half];
    let mut count = vec![0usize; 2 * half];
    for r in 48..ROWS - 48 {
        for c in 0..COLS {
            let j = 16 * c as i64 - 16 * 80 - r as i64; // 16·x + 1/2
            if j >= -(half as i64) && j < half as i64 {
                let b = (j + half as i64) as usize;
                sum[b] += f64::from(raw[0].at(r, c));
                count[b] += 1;
            }
        }
    }
    assert!(
        count.iter().all(|&n| n > 0),
        "every phase bin must be filled"
    );
    let esf: Vec<f64> = sum.iter().zip(&count).map(|(s, &n)| s / n as f64).collect();
    let cos = 1.0 / (1.0 + SLOPE * SLOPE).sqrt();
    let lsf: Vec<(f64, f64)> = (0..esf.len() - 1)
        .map(|b| {
            // The jumps between bins b and b + 1 lie at x = (b − half + 1)/16.
            let jump_x = (b as f64 - half as f64 + 1.0) / 16.0;
            (jump_x * cos, esf[b + 1] - esf[b])
        })
        .collect();
    let dft = |nu: f64| {
        let (re, im) = lsf.iter().fold((0.0, 0.0), |(re, im), &(d, v)| {
            let ph = -2.0 * PI * nu * d;
            (re + v * ph.cos(), im + v * ph.sin())
        });
        (re * re + im * im).sqrt()
    };
    let dc = dft(0.0);
    freqs.iter().map(|&f| dft(f) / dc).collect()
}

fn sinc(x: f64) -> f64 {
    if x == 0.0 {
        1.0
    } else {
        (PI * x).sin() / (PI * x)
    }
}

/// Continuous PSF × aperture transfer at (fx, fy), cycles per pixel; blur in pixels.
fn continuous(b: Blur, fx: f64, fy: f64) -> f64 {
    let g = (-2.0 * PI * PI * b.sigma_mm.powi(2) * (fx * fx + fy * fy)).exp();
    let e = |f: f64| 1.0 / (1.0 + (2.0 * PI * b.tail_length_mm * f).powi(2));
    let psf = (1.0 - b.tail_fraction) * g
        + if b.tail_fraction > 0.0 {
            b.tail_fraction * e(fx) * e(fy)
        } else {
            0.0
        };
    psf * sinc(fx) * sinc(fy)
}

fn analytic(b: Blur, nu: f64, aliased: bool) -> f64 {
    let cos = 1.0 / (1.0 + SLOPE * SLOPE).sqrt();
    let (fx, fy) = (nu * cos, -nu * cos * SLOPE);
    if !aliased {
        return continuous(b, fx, fy).abs();
    }
    let j = 60;
    let mut s = 0.0;
    for jx in -j..=j {
        for jy in -j..=j {
            s += continuous(b, fx + f64::from(jx), fy + f64::from(jy));
        }
    }
    s.abs()
}

fn freqs() -> Vec<f64> {
    (0..=50).map(|i| f64::from(i) * 0.01).collect()
}

fn compare(b: Blur, aliased: bool, tol: f64) -> f64 {
    let f = freqs();
    let m = slanted_edge_mtf(b, &f);
    let mut worst: f64 = 0.0;
    let mut at_nyquist = 0.0;
    for (nu, got) in f.iter().zip(&m) {
        let want = analytic(b, *nu, aliased);
        worst = worst.max((got - want).abs());
        at_nyquist = *got;
        assert!(
            (got - want).abs() < tol,
            "{b:?}: MTF at {nu} cycles/pixel is {got}, analytic {want}"
        );
    }
    eprintln!("{b:?} aliased={aliased}: worst |ΔMTF| {worst:.1e}, MTF(Nyquist) {at_nyquist:.4}");
    worst
}

#[test]
fn gaussian_psf_mtf_is_gaussian_times_aperture_sinc() {
    // σ = 1.2 px: the aliases add < 10⁻³ below Nyquist, so the plain continuous
    // G·sinc must match too.
    let b = Blur::gaussian(1.2);
    compare(b, true, 1e-5);
    compare(b, false, 2e-3);
}

#[test]
fn narrow_gaussian_mtf_shows_the_predicted_aliasing() {
    // σ = 0.4 px: well below a pixel the sampled kernel's MTF is the aliased sum.
    let b = Blur::gaussian(0.4);
    compare(b, true, 1e-5);
    let f = [0.5];
    let at_nyquist = slanted_edge_mtf(b, &f)[0];
    assert!((at_nyquist - analytic(b, 0.5, false)).abs() > 0.05);
}

#[test]
fn gaussian_core_with_exponential_tail() {
    let b = Blur {
        sigma_mm: 0.8,
        tail_fraction: 0.15,
        tail_length_mm: 4.0,
    };
    compare(b, true, 1e-5);
}

#[test]
fn no_blur_is_an_all_pass_filter() {
    let f = freqs();
    for m in slanted_edge_mtf(Blur::none(), &f) {
        assert!((m - 1.0).abs() < 1e-6, "{m}");
    }
}
