//! The network fitted to some views (Methods 1.2.3, eq. 13, code first; the steps:
//! [`crate::reconstruct`]): its tuned field and codes, its volume on the grid, and how well
//! that volume's projections explain each view.

use crate::checkpoint::Generator;
use crate::config::{InferConfig, Tune};
use crate::error::{Result, ensure};
use crate::field::{Codes, Tuned};
use crate::losses::{self, Perceptual, SsimL1};
use crate::prior::{CodeStats, MeanVolume};
use crate::rays::{Patch, bilinear, full_image, sample_rays};
use crate::reference::{Reference, check_references};
use crate::render::{DensityScale, RayTensors, render_field};
use crate::train::adam;
use burn::module::Module;
use burn::optim::GradientsParams;
use burn::tensor::{Device, Tensor, TensorData};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tomograf_sim::{Pose, Projector, Renderer, Volume};

/// Weight λ1 of the reconstruction term (eq. 13).
pub const LAMBDA_R: f64 = 0.3;
/// Weight λ2 of the PSNR term.
pub const LAMBDA_PSNR: f64 = 0.1;

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
    /// With several fits averaged ([`crate::ensemble`]): each voxel's standard deviation
    /// across them (normalised density, the root-mean-square deviation from their mean);
    /// `None` for a single fit.
    pub spread: Option<Volume>,
}

/// The network part of [`crate::reconstruct::reconstruct`]: `generator` (left as it is:
/// its field is copied) fitted to `refs`, code first, then as `infer.tune` says, and its
/// volume on `grid`. The fit starts from the mean code.
pub fn fit_network(
    generator: &Generator,
    refs: &[Reference],
    grid: &Volume,
    infer: &InferConfig,
    seed: u64,
    device: &Device,
    progress: &mut dyn FnMut(usize, f64),
) -> Result<Fit> {
    fit_network_from(generator, refs, grid, infer, seed, None, device, progress)
}

/// [`fit_network`] from the given whitened starting codes (shape, appearance; `None`: the
/// mean code, zeros).
#[allow(clippy::too_many_arguments)]
pub fn fit_network_from(
    generator: &Generator,
    refs: &[Reference],
    grid: &Volume,
    infer: &InferConfig,
    seed: u64,
    start: Option<(Vec<f32>, Vec<f32>)>,
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
    let (shape0, app0) = start.unwrap_or_else(|| (vec![0.0; m.z_shape], vec![0.0; m.z_app]));
    ensure!(
        shape0.len() == m.z_shape && app0.len() == m.z_app,
        "starting codes of {} + {} values for a model with {} + {}",
        shape0.len(),
        app0.len(),
        m.z_shape,
        m.z_app
    );
    let mut tuned = Tuned {
        field: field.clone(),
        codes: Codes::new(shape0, app0, 1, device),
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
        spread: None,
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
