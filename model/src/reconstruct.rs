//! Inference (Methods 1.2.3, eq. 13), code first.
//!
//! 1. The codes start at the mean of the training codes (whitened codes u = 0, see
//!    [`crate::prior::CodeStats`]) and are fitted alone, the generator frozen, for
//!    `code_iterations` iterations of Adam at `lr_codes`, on coarse rays spanning the whole
//!    image (`code_patch`).
//! 2. With `tune = codes-and-generator`, the generator is then tuned with the codes, at the
//!    lower rate `lr`, on `patch`×`patch` patches at random scales.
//!
//! 3. With `refine_iterations` > 0, when some reference view's full-image PSNR against the
//!    network volume's projection is below `refine_below_db` (the prior could not explain
//!    the views: anatomy outside the training population), SART-TV (sim's defaults) runs
//!    that many sweeps from the network's volume ([`crate::refine`]: where they start).
//!    The network's own volume is kept beside the result.
//!
//! Each iteration fits one randomly drawn reference view with eq. 13's loss,
//! λ1·L_r + λ2·L_PSNR + λ3·NLL (0.3, 0.1, `w_nll`), the NLL taken under the training codes'
//! Gaussian. Every `check_every` iterations the current volume is rendered on the grid and
//! projected with sim's Siddon projector into every reference view; inference stops when
//! each view's full-image PSNR reaches the threshold, or at the iteration cap.

use crate::checkpoint::Generator;
use crate::config::{InferConfig, RefineStart, Tune};
use crate::error::{Result, ensure};
use crate::field::{Codes, Tuned};
use crate::held_out;
use crate::losses::{self, Perceptual, SsimL1};
use crate::prior::{CodeStats, MeanVolume};
use crate::rays::{Patch, bilinear, full_image, sample_rays};
use crate::refine::{StartWeights, start_weights, sweep_from};
use crate::render::{DensityScale, RayTensors, render_field};
use crate::train::adam;
use burn::module::Module;
use burn::optim::GradientsParams;
use burn::tensor::{Device, Tensor, TensorData};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tomograf_sim::{Pose, Projector, Renderer, View, Volume};

/// Weight λ1 of the reconstruction term (eq. 13).
pub const LAMBDA_R: f64 = 0.3;
/// Weight λ2 of the PSNR term.
pub const LAMBDA_PSNR: f64 = 0.1;

/// One reference projection with its geometry.
#[derive(Debug, Clone)]
pub struct Reference {
    /// Where it was taken from.
    pub view: View,
    /// Its pose ξ.
    pub pose: Pose,
    /// Line integrals, `view.rows × view.cols`, row-major.
    pub image: Vec<f32>,
}

/// What inference produced.
#[derive(Debug, Clone)]
pub struct Reconstruction {
    /// Normalised density on the requested grid (after the data-consistency sweeps, when
    /// they ran).
    pub volume: Volume,
    /// The network's own volume before the data-consistency sweeps (equal to `volume` when
    /// the gate kept them from running); `None` when `refine_iterations` is 0.
    pub network: Option<NetworkVolume>,
    /// Iterations run (both phases).
    pub iterations: usize,
    /// Full-image PSNR (dB, projections scaled to [0, 1]) of each reference view, from the
    /// final volume projected with sim's Siddon projector.
    pub psnr: Vec<f64>,
    /// Loss per iteration.
    pub losses: Vec<f64>,
    /// The fitted codes `(z_sh, z_a)` (not whitened).
    pub codes: (Vec<f32>, Vec<f32>),
    /// The estimated peak memory, bytes ([`crate::config::TrainConfig::inference_peak_bytes`]),
    /// checked against the memory available before the fit.
    pub peak_bytes: u128,
}

/// The network's volume before data-consistency sweeps.
#[derive(Debug, Clone)]
pub struct NetworkVolume {
    /// Normalised density on the requested grid.
    pub volume: Volume,
    /// Full-image PSNR (dB) of each reference view against its projection, as
    /// [`Reconstruction::psnr`].
    pub psnr: Vec<f64>,
    /// Whether the sweeps ran (some view's PSNR was below `refine_below_db`).
    pub refined: bool,
    /// The weights of the sweeps' start (network volume, mean volume), when they ran.
    pub start: Option<StartWeights>,
    /// Seconds the sweeps took (with the refits of a start chosen by left-out views).
    pub refine_seconds: f64,
    /// With a start chosen by left-out views: each candidate start and its PSNR (dB) on
    /// the left-out views ([`held_out::HeldOutChoice::scores`]).
    pub held_out: Option<Vec<(StartWeights, f64)>>,
}

/// Checks references against each other and the grid: at least one, sizes consistent.
pub fn check_references(refs: &[Reference]) -> Result<()> {
    ensure!(
        !refs.is_empty(),
        "no reference projections (view count 0): give at least one"
    );
    for (i, r) in refs.iter().enumerate() {
        r.view.validate()?;
        ensure!(
            r.image.len() == r.view.rows * r.view.cols,
            "reference {i}: image has {} values but its view's detector is {}×{}",
            r.image.len(),
            r.view.rows,
            r.view.cols
        );
        ensure!(
            r.image.iter().all(|v| v.is_finite()),
            "reference {i}: image has non-finite values"
        );
    }
    Ok(())
}

/// Refuses an inference whose estimated peak
/// ([`crate::config::TrainConfig::inference_peak_bytes`]), beyond what the process holds
/// now, exceeds the memory available; the estimate otherwise.
fn check_memory(
    generator: &Generator,
    infer: &InferConfig,
    refs: &[Reference],
    grid: &Volume,
) -> Result<u128> {
    let c = &generator.config;
    let view_pixels = refs
        .iter()
        .map(|r| r.view.rows as u128 * r.view.cols as u128)
        .max()
        .unwrap_or(0);
    let peak = c.inference_peak_bytes(infer, grid.len() as u128, view_pixels) as u128;
    let held = tomograf_sim::memory::resident_bytes().map_or(0, u128::from);
    let [nx, ny, nz] = grid.dims();
    tomograf_sim::memory::check(
        peak.saturating_sub(held),
        &format!(
            "inference onto a {nx}×{ny}×{nz} grid with the checkpoint's field (hidden {}, depth \
             {}, {} samples per ray, infer.patch {}, infer.code_patch {}; estimated peak {:.0} \
             MiB), beyond what is already held,",
            c.model.hidden,
            c.model.depth,
            c.model.samples,
            infer.patch,
            infer.code_patch,
            peak as f64 / (1u64 << 20) as f64
        ),
    )?;
    Ok(peak)
}

/// Fits `generator` to `refs` (code first, then — as `infer.tune` says — the generator) and
/// renders the volume on `grid` (its geometry only); then, when `infer` asks for them and
/// some view is unexplained, the data-consistency sweeps ([`crate::refine`], and
/// [`crate::held_out`] for a start chosen by views left out). `progress(iteration, loss)`
/// is called after each iteration of the fit to all views.
pub fn reconstruct(
    generator: Generator,
    refs: &[Reference],
    grid: &Volume,
    infer: &InferConfig,
    seed: u64,
    device: &Device,
    mut progress: impl FnMut(usize, f64),
) -> Result<Reconstruction> {
    check_references(refs)?;
    let peak_bytes = check_memory(&generator, infer, refs, grid)?;
    let fit = fit_network(&generator, refs, grid, infer, seed, device, &mut progress)?;
    let Fit {
        tuned,
        iterations,
        losses,
        mut volume,
        mut psnr,
    } = fit;
    let density_scale = generator.state.density_scale;
    let proj_scale = generator.state.proj_scale;
    let mut network = None;
    if infer.refine_iterations > 0 {
        let unexplained = psnr.iter().any(|&p| p < infer.refine_below_db);
        let mut net = NetworkVolume {
            volume: volume.clone(),
            psnr: psnr.clone(),
            refined: unexplained,
            start: None,
            refine_seconds: 0.0,
            held_out: None,
        };
        if unexplained {
            let t0 = std::time::Instant::now();
            let prior = &generator.prior;
            let explained = psnr.iter().any(|&p| p >= infer.refine_below_db);
            let weights = if infer.refine_start == RefineStart::HeldOut
                && !explained
                && (2..=infer.held_out_max_views).contains(&refs.len())
            {
                let choice = held_out::choose(&generator, refs, grid, infer, seed, device)?;
                net.held_out = Some(choice.scores);
                choice.weights
            } else {
                start_weights(refs, &net.volume, prior, &density_scale, infer, &psnr)?
            };
            volume = sweep_from(refs, &net.volume, prior, &density_scale, infer, weights)?;
            net.start = Some(weights);
            net.refine_seconds = t0.elapsed().as_secs_f64();
            psnr = projection_psnr(&volume, &density_scale, refs, proj_scale)?;
        }
        network = Some(net);
    }
    let stats = &generator.codes.stats;
    let (z_sh, z_a) = stats.codes(tuned.codes.shape.val(), tuned.codes.app.val());
    let read = |t: Tensor<2>| t.into_data().try_to_vec::<f32>().expect("f32 codes");
    Ok(Reconstruction {
        volume,
        network,
        iterations,
        peak_bytes,
        psnr,
        losses,
        codes: (read(z_sh), read(z_a)),
    })
}

/// The network fitted to some views: its tuned field and codes, and its volume.
pub struct Fit {
    /// The tuned field and (whitened) codes.
    pub tuned: Tuned,
    /// Iterations run (both phases).
    pub iterations: usize,
    /// Loss per iteration.
    pub losses: Vec<f64>,
    /// Normalised density on the grid.
    pub volume: Volume,
    /// Full-image PSNR (dB) of each view against the volume's projection.
    pub psnr: Vec<f64>,
}

/// The network part of [`reconstruct`]: `generator` (left as it is: its field is copied)
/// fitted to `refs`, code first, then as `infer.tune` says, and its volume on `grid`.
pub fn fit_network(
    generator: &Generator,
    refs: &[Reference],
    grid: &Volume,
    infer: &InferConfig,
    seed: u64,
    device: &Device,
    progress: &mut dyn FnMut(usize, f64),
) -> Result<Fit> {
    check_references(refs)?;
    let Generator {
        config,
        state,
        field,
        prior,
        codes: table,
    } = generator;
    let (proj_scale, density_scale) = (state.proj_scale, state.density_scale);
    let stats = &table.stats;
    let m = &config.model;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut tuned = Tuned {
        field: field.clone(),
        codes: Codes::new(vec![0.0; m.z_shape], vec![0.0; m.z_app], 1, device),
    };
    let (mut opt_codes, mut opt_field) = (adam(), adam());
    // The frozen generator of the first phase: no gradients of its weights are computed.
    let frozen = tuned.field.clone().no_grad();
    let perceptual = SsimL1;
    let mut psnr;
    let mut losses_seen = Vec::new();
    let mut iterations = 0;
    let reached = |p: &[f64]| p.iter().all(|&x| x >= infer.psnr_threshold);
    while iterations < infer.iterations {
        let codes_only = iterations < infer.code_iterations || infer.tune == Tune::Codes;
        let r = &refs[rng.random_range(0..refs.len())];
        let (rows, cols) = (r.view.rows, r.view.cols);
        let side = if codes_only {
            infer.code_patch
        } else {
            infer.patch
        };
        let pixels = match (side, codes_only) {
            (0, _) => full_image(rows, cols),
            (n, true) => Patch::spanning(&mut rng, rows, cols, n.min(rows).min(cols))?.pixels(),
            (n, false) => Patch::random(&mut rng, rows, cols, n.min(rows).min(cols))?.pixels(),
        };
        let s = sample_rays(&r.view, grid, &pixels, m.samples, Some(&mut rng))?;
        let target: Vec<f32> = pixels
            .iter()
            .map(|&(pr, pc)| {
                (f64::from(bilinear(&r.image, rows, cols, pr, pc)) / proj_scale) as f32
            })
            .collect();
        let n = pixels.len();
        let pose = r.pose.frame().to_source.as_vec3().to_array().to_vec();
        let rays = RayTensors::new(
            s.normalised(grid.dims()),
            s.step_mm.clone(),
            pose,
            n,
            m.samples,
            prior,
            device,
        );
        let target = Tensor::<2>::from_data(TensorData::new(target, [1, n]), device);
        let (u_sh, u_a) = (tuned.codes.shape.val(), tuned.codes.app.val());
        let (z_sh, z_a) = stats.codes(u_sh.clone(), u_a.clone());
        let field = if codes_only { &frozen } else { &tuned.field };
        let (_, integral) = render_field(field, z_sh, z_a, &rays, &density_scale);
        let pred = integral.div_scalar(proj_scale);
        let loss = perceptual
            .distance(pred.clone(), target.clone())
            .mul_scalar(LAMBDA_R)
            + losses::neg_psnr(pred, target).mul_scalar(LAMBDA_PSNR)
            + (losses::code_nll(u_sh) + losses::code_nll(u_a)).mul_scalar(infer.w_nll);
        let value = loss.clone().into_scalar::<f32>() as f64;
        ensure!(
            value.is_finite(),
            "{}",
            if iterations == 0 {
                "the loss is not finite at the first inference iteration, before any update: \
                 the checkpoint's weights hold non-finite values (generator.bpk is corrupt)"
                    .to_string()
            } else {
                format!(
                    "inference iteration {iterations}: loss is not finite; lower the learning \
                     rate"
                )
            }
        );
        let mut grads = loss.backward();
        let gc = GradientsParams::from_module(&mut grads, &tuned.codes);
        if !codes_only {
            let gf = GradientsParams::from_module(&mut grads, &tuned.field);
            tuned.field = opt_field.step(infer.lr, tuned.field, gf);
        }
        tuned.codes = opt_codes.step(infer.lr_codes, tuned.codes, gc);
        losses_seen.push(value);
        iterations += 1;
        progress(iterations, value);
        if iterations % infer.check_every == 0 && iterations < infer.iterations {
            let v = render_volume(&tuned, stats, prior, grid, refs[0].pose, device)?;
            psnr = projection_psnr(&v, &density_scale, refs, proj_scale)?;
            if reached(&psnr) {
                break;
            }
        }
    }
    let volume = render_volume(&tuned, stats, prior, grid, refs[0].pose, device)?;
    psnr = projection_psnr(&volume, &density_scale, refs, proj_scale)?;
    Ok(Fit {
        tuned,
        iterations,
        losses: losses_seen,
        volume,
        psnr,
    })
}

/// Full-image PSNR (dB, MAX 1 after dividing by `proj_scale`) of each reference view
/// against the projection of `volume` (normalised density, mapped to mu by `scale`) with
/// sim's exact Siddon projector.
pub fn projection_psnr(
    volume: &Volume,
    scale: &DensityScale,
    refs: &[Reference],
    proj_scale: f64,
) -> Result<Vec<f64>> {
    Ok(projection_sq_err(volume, scale, refs, proj_scale)?
        .into_iter()
        .map(|(sum, n)| -10.0 * (sum / n.max(1) as f64 + 1e-20).log10())
        .collect())
}

/// For each reference view, the sum of squared differences between its image and the
/// projection of `volume` (as [`projection_psnr`] makes it), both divided by `proj_scale`,
/// and the number of pixels.
pub fn projection_sq_err(
    volume: &Volume,
    scale: &DensityScale,
    refs: &[Reference],
    proj_scale: f64,
) -> Result<Vec<(f64, usize)>> {
    let mu = volume.map(|d| scale.mu_scalar(f64::from(d)) as f32)?;
    let renderer = Renderer::new(&mu, Projector::Siddon)?;
    refs.iter()
        .map(|r| {
            let p = renderer.render(&r.view)?;
            let sum = p
                .data
                .iter()
                .zip(&r.image)
                .map(|(&a, &b)| ((f64::from(a) - f64::from(b)) / proj_scale).powi(2))
                .sum::<f64>();
            Ok((sum, p.data.len()))
        })
        .collect()
}

/// The field's density at every voxel centre of `grid` (as a volume with the grid's
/// geometry) for the whitened codes of `tuned` (decoded with `stats`), prior `prior`, and
/// pose `pose` (used only by a view-dependent field).
pub fn render_volume(
    tuned: &Tuned,
    stats: &CodeStats,
    prior: &MeanVolume,
    grid: &Volume,
    pose: Pose,
    device: &Device,
) -> Result<Volume> {
    let dims = grid.dims();
    let total = dims[0] * dims[1] * dims[2];
    let mut out = Vec::with_capacity(total);
    let xi = pose.frame().to_source.as_vec3().to_array().to_vec();
    let (z_sh, z_a) = stats.codes(tuned.codes.shape.val(), tuned.codes.app.val());
    let (z_sh, z_a) = (z_sh.detach(), z_a.detach());
    // No autodiff graph: a forward pass only, so no activations are kept for a backward.
    let field = tuned.field.clone().no_grad();
    const CHUNK: usize = 32768;
    let coord = |i: usize, a: usize| (2.0 * (i as f64 + 0.5) / dims[a] as f64 - 1.0) as f32;
    let mut start = 0;
    while start < total {
        let end = (start + CHUNK).min(total);
        let mut pts = Vec::with_capacity((end - start) * 3);
        for n in start..end {
            let (i, j, k) = (
                n % dims[0],
                (n / dims[0]) % dims[1],
                n / (dims[0] * dims[1]),
            );
            pts.extend([coord(i, 0), coord(j, 1), coord(k, 2)]);
        }
        let prior_t = prior.tensor_at(&pts, 1, device);
        let p = Tensor::<3>::from_data(TensorData::new(pts, [1, end - start, 3]), device);
        let pose_t = Tensor::<2>::from_data(TensorData::new(xi.clone(), [1, 3]), device);
        let d = field
            .density(p, prior_t, pose_t, z_sh.clone(), z_a.clone())
            .detach();
        out.extend(
            d.into_data().try_to_vec::<f32>().map_err(|e| {
                crate::ModelError::Invalid(format!("reading densities back: {e:?}"))
            })?,
        );
        start = end;
    }
    Ok(Volume::new(
        dims,
        grid.spacing(),
        grid.origin(),
        grid.direction(),
        out,
    )?)
}

/// AP and lateral references of attenuation `mu` (mm⁻¹) with sim's Siddon projector: a
/// 16 × 16 cone-beam detector of 6 mm pixels, source 400 mm and detector 600 mm from the
/// origin (for the tests of the methods that reconstruct from them).
#[cfg(test)]
pub(crate) fn test_references(mu: &Volume) -> Vec<Reference> {
    use tomograf_sim::{Beam, Detector, Geometry};
    let g = Geometry {
        beam: Beam::Cone {
            sad_mm: 400.0,
            sid_mm: 600.0,
        },
        detector: Detector::new(16, 16, 6.0),
        isocentre: glam::DVec3::ZERO,
    };
    let r = Renderer::new(mu, Projector::Siddon).expect("a renderer");
    [Pose::AP, Pose::LATERAL]
        .iter()
        .map(|&p| {
            let view = g.view(p).expect("a view");
            Reference {
                view,
                pose: p,
                image: r.render(&view).expect("a projection").data,
            }
        })
        .collect()
}
