//! Inference (Methods 1.2.3, eq. 13): fine-tune the codes — and by default the generator,
//! as the paper does — to the reference projections with
//! λ1·L_r + λ2·L_PSNR + λ3·L_NLL (0.3, 0.1, 0.3), until every reference view reaches the PSNR
//! threshold or the iteration cap; then render the full volume.

use crate::config::{InferConfig, TrainConfig, Tune};
use crate::error::{Result, ensure};
use crate::field::{Codes, RadianceField, Tuned};
use crate::losses::{self, Perceptual, SsimL1};
use crate::rays::{Patch, bilinear, full_image, sample_rays};
use crate::render::{DensityScale, RayTensors, render_field};
use crate::train::{normals, rmsprop};
use burn::optim::GradientsParams;
use burn::tensor::{Device, Tensor, TensorData};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tomograf_sim::{Pose, View, Volume};

/// Weights of eq. 13.
pub const LAMBDA_R: f64 = 0.3;
/// Weight of the PSNR term.
pub const LAMBDA_PSNR: f64 = 0.1;
/// Weight of the codes' negative log-likelihood.
pub const LAMBDA_NLL: f64 = 0.3;

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
    /// Normalised density on the requested grid.
    pub volume: Volume,
    /// Iterations run.
    pub iterations: usize,
    /// Last PSNR (dB) of each reference view's rendered rays.
    pub psnr: Vec<f64>,
    /// Loss per iteration.
    pub losses: Vec<f64>,
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

/// Fine-tunes `field` to `refs` and renders the volume on `grid` (its geometry only).
/// `progress(iteration, loss)` is called after each iteration.
#[allow(clippy::too_many_arguments)]
pub fn reconstruct(
    field: RadianceField,
    config: &TrainConfig,
    proj_scale: f64,
    density_scale: &DensityScale,
    refs: &[Reference],
    grid: &Volume,
    infer: &InferConfig,
    seed: u64,
    device: &Device,
    mut progress: impl FnMut(usize, f64),
) -> Result<Reconstruction> {
    check_references(refs)?;
    let m = &config.model;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let codes = Codes::new(
        normals(&mut rng, m.z_shape),
        normals(&mut rng, m.z_app),
        1,
        device,
    );
    let mut tuned = Tuned { field, codes };
    let mut opt = rmsprop();
    let perceptual = SsimL1;
    let mut psnr = vec![f64::NEG_INFINITY; refs.len()];
    let mut losses_seen = Vec::new();
    let mut iterations = 0;
    while iterations < infer.iterations && !psnr.iter().all(|&p| p >= infer.psnr_threshold) {
        let i = rng.random_range(0..refs.len());
        let r = &refs[i];
        let pixels = if infer.patch == 0 {
            full_image(r.view.rows, r.view.cols)
        } else {
            Patch::random(&mut rng, r.view.rows, r.view.cols, infer.patch)?.pixels()
        };
        let s = sample_rays(&r.view, grid, &pixels, m.samples, Some(&mut rng))?;
        let target: Vec<f32> = pixels
            .iter()
            .map(|&(pr, pc)| {
                (f64::from(bilinear(&r.image, r.view.rows, r.view.cols, pr, pc)) / proj_scale)
                    as f32
            })
            .collect();
        let n = pixels.len();
        let rays = RayTensors {
            points: Tensor::from_data(
                TensorData::new(s.normalised(grid.dims()), [1, n * m.samples, 3]),
                device,
            ),
            step_mm: Tensor::from_data(TensorData::new(s.step_mm.clone(), [1, n]), device),
            pose: Tensor::from_data(
                TensorData::new(
                    r.pose.frame().to_source.as_vec3().to_array().to_vec(),
                    [1, 3],
                ),
                device,
            ),
            rays: n,
            samples: m.samples,
        };
        let target = Tensor::<2>::from_data(TensorData::new(target, [1, n]), device);
        let (_, integral) = render_field(&tuned.field, &tuned.codes, &rays, density_scale);
        let pred = integral.div_scalar(proj_scale);
        let neg_psnr = losses::neg_psnr(pred.clone(), target.clone());
        psnr[i] = -(neg_psnr.clone().into_scalar::<f32>() as f64);
        let loss = perceptual.distance(pred, target).mul_scalar(LAMBDA_R)
            + neg_psnr.mul_scalar(LAMBDA_PSNR)
            + (losses::code_nll(tuned.codes.shape.val()) + losses::code_nll(tuned.codes.app.val()))
                .mul_scalar(LAMBDA_NLL);
        let value = loss.clone().into_scalar::<f32>() as f64;
        ensure!(
            value.is_finite(),
            "inference iteration {iterations}: loss is not finite; lower the learning rate"
        );
        let mut grads = loss.backward();
        match infer.tune {
            Tune::CodesAndGenerator => {
                let g = GradientsParams::from_module(&mut grads, &tuned);
                tuned = opt.step(infer.lr, tuned, g);
            }
            Tune::Codes => {
                let g = GradientsParams::from_module(&mut grads, &tuned.codes);
                tuned.codes = opt.step(infer.lr, tuned.codes, g);
            }
        }
        losses_seen.push(value);
        iterations += 1;
        progress(iterations, value);
    }
    let volume = render_volume(&tuned, grid, refs[0].pose, device)?;
    Ok(Reconstruction {
        volume,
        iterations,
        psnr,
        losses: losses_seen,
    })
}

/// The field's density at every voxel centre of `grid` (as a volume with the grid's
/// geometry), for pose `pose`.
pub fn render_volume(tuned: &Tuned, grid: &Volume, pose: Pose, device: &Device) -> Result<Volume> {
    let dims = grid.dims();
    let total = dims[0] * dims[1] * dims[2];
    let mut out = Vec::with_capacity(total);
    let xi = pose.frame().to_source.as_vec3().to_array().to_vec();
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
        let p = Tensor::<3>::from_data(TensorData::new(pts, [1, end - start, 3]), device);
        let pose_t = Tensor::<2>::from_data(TensorData::new(xi.clone(), [1, 3]), device);
        let d = tuned
            .field
            .density(p, pose_t, tuned.codes.shape.val(), tuned.codes.app.val())
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
