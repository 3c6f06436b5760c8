//! Several fits of the network to the same views, averaged (`[infer] ensemble`).
//!
//! A fit to one or two views is underdetermined: many volumes explain the views, and the
//! one a fit lands on depends on where its code starts and on its ray draws. Where the
//! views pin the volume down the fits agree; inside the body, where they do not, each fit
//! fills in the prior's anatomy its own way. Their voxel-wise mean keeps what they share
//! and averages away what they do not (the mean of draws approximates the posterior
//! mean, which minimises the expected squared error). Projection is linear, so the mean of
//! volumes that explain the views explains them as well as the fits do on average.
//!
//! Where they disagree is recorded too: each voxel's standard deviation across the fits
//! (`Fit::spread`), what `[infer] mean_sweeps_spread` weighs the blend with SART-TV from the
//! mean by ([`crate::reconstruct`]).
//!
//! The first fit is the single fit (mean code, `seed`): with `ensemble = 1` nothing
//! changes. Fit `k ≥ 1` starts from whitened codes drawn from N(0, `ensemble_code_sd`²)
//! (the training codes' Gaussian, its spread scaled) with seed `seed + k` for its rays.

use crate::checkpoint::Generator;
use crate::config::InferConfig;
use crate::error::Result;
use crate::fit::{Fit, fit_network, fit_network_from, projection_psnr};
use crate::reference::Reference;
use burn::tensor::Device;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tomograf_sim::Volume;

/// Mixed into the seed of the starting codes' draws, so they do not repeat a fit's rays.
const CODE_STREAM: u64 = 0x656e_7365_6d62_6c65;

/// `infer.ensemble` fits of `generator` to `refs` on `grid` (one with more views than
/// `infer.ensemble_max_views`), averaged voxel by voxel (see the module's doc). The
/// result's `tuned` field and codes are the first fit's; its `iterations` and `losses` all
/// fits' together; its `psnr` the average volume's; its `spread` each voxel's standard
/// deviation across the fits.
/// `progress(iteration, loss)` counts on across the fits.
pub fn fit_ensemble(
    generator: &Generator,
    refs: &[Reference],
    grid: &Volume,
    infer: &InferConfig,
    seed: u64,
    device: &Device,
    progress: &mut dyn FnMut(usize, f64),
) -> Result<Fit> {
    let mut first = fit_network(generator, refs, grid, infer, seed, device, progress)?;
    let fits = infer.ensemble_fits(refs.len());
    if fits <= 1 {
        return Ok(first);
    }
    let m = &generator.config.model;
    let starts = starting_codes(seed, fits - 1, infer.ensemble_code_sd, m.z_shape, m.z_app);
    let mut sum: Vec<f64> = first.volume.data().iter().map(|&v| f64::from(v)).collect();
    let mut sum_sq: Vec<f64> = sum.iter().map(|v| v * v).collect();
    for (k, start) in (1..).zip(starts) {
        let done = first.iterations;
        let fit = fit_network_from(
            generator,
            refs,
            grid,
            infer,
            member_seed(seed, k),
            Some(start),
            device,
            &mut |i, loss| progress(done + i, loss),
        )?;
        for ((s, q), &v) in sum.iter_mut().zip(&mut sum_sq).zip(fit.volume.data()) {
            let v = f64::from(v);
            *s += v;
            *q += v * v;
        }
        first.iterations += fit.iterations;
        first.losses.extend(fit.losses);
    }
    let n = fits as f64;
    let v = &first.volume;
    let mean = sum.iter().map(|s| (s / n) as f32).collect();
    // Var = E[v²] − E[v]², clamped at 0 against rounding (f64 sums of at most a few fits).
    let sd = sum
        .iter()
        .zip(&sum_sq)
        .map(|(s, q)| ((q / n - (s / n).powi(2)).max(0.0)).sqrt() as f32)
        .collect();
    first.spread = Some(Volume::new(
        v.dims(),
        v.spacing(),
        v.origin(),
        v.direction(),
        sd,
    )?);
    first.volume = Volume::new(v.dims(), v.spacing(), v.origin(), v.direction(), mean)?;
    let state = &generator.state;
    first.psnr = projection_psnr(&first.volume, &state.density_scale, refs, state.proj_scale)?;
    Ok(first)
}

/// The whitened starting codes (shape, appearance) of fits 1 … `count` of an ensemble
/// seeded `seed`: `z_shape` and `z_app` draws each from N(0, `sd`²).
pub fn starting_codes(
    seed: u64,
    count: usize,
    sd: f64,
    z_shape: usize,
    z_app: usize,
) -> Vec<(Vec<f32>, Vec<f32>)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ CODE_STREAM);
    let mut draw =
        |n: usize| -> Vec<f32> { (0..n).map(|_| (sd * normal(&mut rng)) as f32).collect() };
    (0..count).map(|_| (draw(z_shape), draw(z_app))).collect()
}

/// The seed of fit `k` of an ensemble seeded `seed` (fit 0: `seed` itself).
pub fn member_seed(seed: u64, k: usize) -> u64 {
    seed.wrapping_add(k as u64)
}

/// A standard normal draw (Box–Muller).
fn normal(rng: &mut impl Rng) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>();
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}
