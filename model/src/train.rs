//! One training iteration (Methods 1.2–1.3): sample patches P and the sub-volumes V along
//! their rays from the data set, render the generator's V′ and P′, then update the generator.
//!
//! * **Paired supervision** (`codes = "per-item"`, the default): every training item has its
//!   own shape and appearance codes in an embedding table learned with the generator (an
//!   auto-decoder), and the generator is trained on the reconstruction loss between V′ and V
//!   and between P′ and P (L1 plus the SSIM term, [`SsimL1`]) with a penalty keeping the codes
//!   near N(0, I).
//! * **Adversarial terms** (`w_adversarial > 0`; the paper's only signal with
//!   `codes = "random"`): D1 and D2 are updated first (hinge + decoder reconstruction, eqs.
//!   7–10, with DAG, eqs. 11–12), then the generator's hinge terms against them are added.
//!
//! Everything random comes from a ChaCha8 stream seeded by (config seed, iteration), and
//! burn's parameter initialisation by the config seed, so the same data, config and seed
//! give the same training run, and a resumed run continues exactly as an unbroken one.

use crate::augment;
use crate::config::{CodeMode, Optimiser, TrainConfig};
use crate::data::Item;
use crate::discriminator::{PatchDiscriminator, VolumeDiscriminator};
use crate::error::{Result, ensure};
use crate::field::{Codes, RadianceField};
use crate::losses::{self, Perceptual, SsimL1};
use crate::prior::MeanVolume;
use crate::rays::{Patch, bilinear, sample_rays};
use crate::render::{RayTensors, render_field};
use burn::module::Module;
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer, RmsPropConfig};
use burn::tensor::module::{adaptive_avg_pool2d, adaptive_avg_pool3d};
use burn::tensor::{Device, Tensor, TensorData};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use tomograf_sim::trace::trilinear;

/// RMSprop with PyTorch's defaults (alpha 0.99, momentum 0, eps 1e-8), as GRAF uses.
pub fn rmsprop() -> ModuleOptimizer {
    RmsPropConfig::new()
        .with_alpha(0.99)
        .with_momentum(0.0)
        .with_epsilon(1e-8)
        .init()
}

/// Adam (β 0.9, 0.999, ε 1e-8).
pub fn adam() -> ModuleOptimizer {
    AdamConfig::new().with_epsilon(1e-8).init()
}

/// The optimiser `o`.
pub fn optimiser(o: Optimiser) -> ModuleOptimizer {
    match o {
        Optimiser::Adam => adam(),
        Optimiser::Rmsprop => rmsprop(),
    }
}

/// A stream of standard normal draws (Box–Muller on ChaCha8).
pub fn normals(rng: &mut impl Rng, n: usize) -> Vec<f32> {
    (0..n)
        .map(|_| {
            let u1: f64 = rng.random_range(f64::EPSILON..1.0);
            let u2: f64 = rng.random();
            ((-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()) as f32
        })
        .collect()
}

/// The largest line integral of the items: projections are divided by it so patches lie in
/// [0, 1] like the normalised volumes.
pub fn projection_scale(items: &[Item]) -> Result<f64> {
    let m = items
        .iter()
        .flat_map(|i| i.projections.iter())
        .fold(0.0f32, |a, &b| a.max(b));
    ensure!(
        m.is_finite() && m > 0.0,
        "all projections are zero: nothing to learn from"
    );
    Ok(f64::from(m))
}

/// Losses of one iteration.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct StepMetrics {
    /// Iteration just completed (1-based).
    pub iteration: usize,
    /// Discriminator objective (eqs. 7–12, D side); 0 without adversarial terms.
    pub loss_d: f64,
    /// Generator objective (weighted sum of every term below that trains it).
    pub loss_g: f64,
    /// Reconstruction loss between V′ and V (L1 + (1 − SSIM)/2, normalised density).
    pub loss_volume: f64,
    /// Reconstruction loss between P′ and P (projections scaled to [0, 1]).
    pub loss_projection: f64,
    /// Code penalty mean(z²)/2 of the batch's codes.
    pub loss_code: f64,
    /// D1 hinge (identity transform); 0 without adversarial terms.
    pub hinge_v: f64,
    /// D2 hinge (identity transform).
    pub hinge_p: f64,
    /// D1 decoder reconstruction (identity transform).
    pub recon_v: f64,
    /// D2 decoder reconstruction (identity transform).
    pub recon_p: f64,
    /// L1 between V′ and V at the same points (normalised density).
    pub l1_volume: f64,
    /// L1 between P′ and P, projections scaled to [0, 1].
    pub l1_patch: f64,
}

/// Generator, codes, discriminators and their optimizers.
pub struct Trainer {
    /// The configuration.
    pub config: TrainConfig,
    /// The generator's radiance field.
    pub field: RadianceField,
    /// The training items' codes, one row per item of [`Self::item_ids`] (per-item codes);
    /// `None` when codes are drawn at random.
    pub codes: Option<Codes>,
    /// The ids of the items the code table's rows belong to, in row order.
    pub item_ids: Vec<String>,
    /// The digests of those items' contents ([`crate::data::Item::content_sha256`]), in
    /// row order; empty when unknown (set by the caller; checkpoints written before the
    /// digests were recorded have none).
    pub item_sha256: Vec<String>,
    /// The mean training volume the field's density is a residual on.
    pub prior: MeanVolume,
    /// D1 (sub-volumes).
    pub d1: VolumeDiscriminator,
    /// D2 (patches).
    pub d2: PatchDiscriminator,
    pub(crate) opt_g: ModuleOptimizer,
    pub(crate) opt_codes: ModuleOptimizer,
    pub(crate) opt_d1: ModuleOptimizer,
    pub(crate) opt_d2: ModuleOptimizer,
    /// Iterations completed.
    pub iteration: usize,
    /// Line integral mapped to 1 (see [`projection_scale`]).
    pub proj_scale: f64,
    /// The perceptual distance of eqs. 7–8 and of the reconstruction losses.
    pub perceptual: Box<dyn Perceptual>,
    /// Where tensors live.
    pub device: Device,
}

/// Gives parameters the ids `n + 1, n + 2, …` in the module's traversal order.
pub(crate) struct NumberParams(pub(crate) u64);

impl burn::module::ModuleMapper for NumberParams {
    fn map_float<const D: usize>(
        &mut self,
        param: burn::module::Param<Tensor<D>>,
    ) -> burn::module::Param<Tensor<D>> {
        let (_, value, mapper) = param.consume();
        self.0 += 1;
        burn::module::Param::from_mapped_value(burn::module::ParamId::from(self.0), value, mapper)
    }
}

/// One batch of real patches P, sub-volumes V and the rays that produced them.
struct Batch {
    rays: RayTensors,
    real_v: Tensor<5>,
    real_p: Tensor<4>,
    /// Rows of the code table (per-item codes) of the batch's items.
    rows: Vec<usize>,
    scale: crate::render::DensityScale,
}

/// The initial code table: `rows` draws from N(0, I) of each code, seeded.
fn initial_codes(config: &TrainConfig, rows: usize, device: &Device) -> Codes {
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed ^ 0xC0DE_5EED);
    let m = &config.model;
    Codes::new(
        normals(&mut rng, rows * m.z_shape),
        normals(&mut rng, rows * m.z_app),
        rows,
        device,
    )
    .map(&mut NumberParams(3 << 32))
}

impl Trainer {
    /// Fresh networks for `config` (parameters seeded by `config.seed`), anchored at
    /// `prior`, with one code per item of `item_ids` when codes are per item.
    pub fn new(
        config: TrainConfig,
        proj_scale: f64,
        prior: MeanVolume,
        item_ids: Vec<String>,
        device: &Device,
    ) -> Result<Self> {
        config.validate()?;
        ensure!(
            proj_scale.is_finite() && proj_scale > 0.0,
            "projection scale {proj_scale} must be > 0"
        );
        ensure!(!item_ids.is_empty(), "no training items to give codes to");
        ensure!(
            prior.data.len() == prior.dims.iter().product::<usize>() && !prior.data.is_empty(),
            "the mean volume's data ({} values) does not match its size {:?}",
            prior.data.len(),
            prior.dims
        );
        config.check_grid(*prior.dims.iter().min().expect("3 dims"))?;
        let m = &config.model;
        tomograf_sim::memory::check(
            config.memory_floor_bytes() as u128,
            &format!(
                "at the least, a training step of '{}' (batch {}, patch {}², samples {}, hidden {}, depth {})",
                config.name, config.batch, m.patch, m.samples, m.hidden, m.depth
            ),
        )?;
        // burn's RNG is global: hold a lock from seeding to the last initialisation so
        // networks made concurrently (other threads, other tests) cannot interleave draws.
        static INIT: std::sync::Mutex<()> = std::sync::Mutex::new(());
        let guard = INIT.lock().unwrap_or_else(|e| e.into_inner());
        device.seed(config.seed);
        let m = &config.model;
        let field = RadianceField::new(m, device);
        let d1 = VolumeDiscriminator::new(m.disc_channels, config.n_aug, device);
        let d2 = PatchDiscriminator::new(m.disc_channels, config.n_aug, device);
        // Parameters are initialised lazily, on first use: use every one now, under the lock.
        let (side, q) = (m.patch, m.samples);
        let _ = field.density(
            Tensor::zeros([1, 1, 3], device),
            Tensor::zeros([1, 1], device),
            Tensor::zeros([1, 3], device),
            Tensor::zeros([1, m.z_shape], device),
            Tensor::zeros([1, m.z_app], device),
        );
        for k in 0..config.n_aug {
            let _ = d1.forward(Tensor::zeros([1, 1, q, side, side], device), k);
            let _ = d2.forward(Tensor::zeros([1, 1, side, side], device), k);
        }
        drop(guard);
        // burn gives each parameter a random id, which checkpoints store: number them instead
        // so the same seed writes the same checkpoint bytes.
        let field = field.map(&mut NumberParams(0));
        let d1 = d1.map(&mut NumberParams(1 << 32));
        let d2 = d2.map(&mut NumberParams(2 << 32));
        let codes = (config.codes == CodeMode::PerItem)
            .then(|| initial_codes(&config, item_ids.len(), device));
        Ok(Self {
            field,
            codes,
            item_ids,
            item_sha256: Vec::new(),
            prior,
            d1,
            d2,
            opt_g: optimiser(config.optimiser),
            opt_codes: optimiser(config.optimiser),
            opt_d1: rmsprop(),
            opt_d2: rmsprop(),
            iteration: 0,
            proj_scale,
            perceptual: Box::new(SsimL1),
            config,
            device: device.clone(),
        })
    }

    fn rng(&self) -> ChaCha8Rng {
        ChaCha8Rng::seed_from_u64(
            self.config
                .seed
                .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                .wrapping_add(self.iteration as u64),
        )
    }

    /// Checks that `items` are the items the code table was made for, in its order.
    fn check_items(&self, items: &[Item]) -> Result<()> {
        ensure!(!items.is_empty(), "no training items");
        if self.codes.is_some() {
            let ids: Vec<&str> = items.iter().map(|i| i.id.as_str()).collect();
            let mine: Vec<&str> = self.item_ids.iter().map(String::as_str).collect();
            ensure!(
                ids == mine,
                "the training items ({} of them, first {:?}) are not the {} items this model's \
                 codes were learned for (first {:?}): train and resume on the same data set",
                ids.len(),
                ids.first(),
                mine.len(),
                mine.first()
            );
        }
        Ok(())
    }

    fn batch(&self, items: &[Item], rng: &mut ChaCha8Rng) -> Result<Batch> {
        let m = &self.config.model;
        let (bsz, side, q) = (self.config.batch, m.patch, m.samples);
        let r = side * side;
        let mut pts: Vec<f32> = Vec::new();
        let mut steps: Vec<f32> = Vec::new();
        let mut poses: Vec<f32> = Vec::new();
        let mut rv: Vec<f32> = Vec::new();
        let mut rp: Vec<f32> = Vec::new();
        let mut rows = Vec::with_capacity(bsz);
        let mut scale = None;
        for _ in 0..bsz {
            let row = rng.random_range(0..items.len());
            rows.push(row);
            let item = &items[row];
            let ct = item.ct.as_ref().ok_or_else(|| {
                crate::ModelError::Invalid(format!(
                    "item {}: training needs the ground-truth CT (ct.nii.gz)",
                    item.id
                ))
            })?;
            ensure!(
                scale.is_none_or(|s| s == item.scale),
                "items have different HU windows or energies; train on one data set"
            );
            scale = Some(item.scale);
            let v = rng.random_range(0..item.views.len());
            let patch = Patch::random(rng, item.rows, item.cols, side)?;
            let pixels = patch.pixels();
            let s = sample_rays(&item.views[v], ct, &pixels, q, Some(rng))?;
            pts.extend(s.normalised(ct.dims()));
            steps.extend(&s.step_mm);
            poses.extend(item.poses[v].frame().to_source.as_vec3().to_array());
            let img = item.projection(v);
            rp.extend(pixels.iter().map(|&(pr, pc)| {
                (f64::from(bilinear(img, item.rows, item.cols, pr, pc)) / self.proj_scale) as f32
            }));
            // V in D1's layout [Q, M, M] from ray-major [M·M, Q].
            let mut sub = vec![0.0f32; r * q];
            for (ray, chunk) in s.grid.chunks(q).enumerate() {
                for (k, g) in chunk.iter().enumerate() {
                    sub[k * r + ray] = trilinear::sample(ct.data(), ct.dims(), *g) as f32;
                }
            }
            rv.extend(sub);
        }
        let dev = &self.device;
        Ok(Batch {
            rays: RayTensors::new(pts, steps, poses, r, q, &self.prior, dev),
            real_v: Tensor::from_data(TensorData::new(rv, [bsz, 1, q, side, side]), dev),
            real_p: Tensor::from_data(TensorData::new(rp, [bsz, 1, side, side]), dev),
            rows,
            scale: scale.expect("batch > 0"),
        })
    }

    fn weight(&self, k: usize) -> f64 {
        if k == 0 {
            1.0
        } else {
            self.config.lambda1 / (self.config.n_aug - 1) as f64
        }
    }

    /// One iteration on `items` (sampled with replacement; with per-item codes, the items
    /// the model was made for, in the same order); returns its losses.
    pub fn step(&mut self, items: &[Item]) -> Result<StepMetrics> {
        self.check_items(items)?;
        let mut rng = self.rng();
        let batch = self.batch(items, &mut rng)?;
        let m = &self.config.model;
        let (bsz, side, q) = (self.config.batch, m.patch, m.samples);
        let dev = self.device.clone();
        let (z_sh, z_a) = match &self.codes {
            Some(table) => table.rows(&batch.rows),
            None => (
                Tensor::from_data(
                    TensorData::new(normals(&mut rng, bsz * m.z_shape), [bsz, m.z_shape]),
                    &dev,
                ),
                Tensor::from_data(
                    TensorData::new(normals(&mut rng, bsz * m.z_app), [bsz, m.z_app]),
                    &dev,
                ),
            ),
        };
        let (density, integral) = render_field(
            &self.field,
            z_sh.clone(),
            z_a.clone(),
            &batch.rays,
            &batch.scale,
        );
        // V' [B, 1, Q, M, M] and P' [B, 1, M, M] in the real data's layout and units.
        let fake_v = density
            .reshape([bsz, side, side, q])
            .permute([0, 3, 1, 2])
            .unsqueeze_dim::<5>(1);
        let fake_p = integral
            .div_scalar(self.proj_scale)
            .reshape([bsz, 1, side, side]);
        let scalar = |t: Tensor<1>| t.into_scalar::<f32>() as f64;
        let l1_volume = scalar(
            (fake_v.clone().detach() - batch.real_v.clone())
                .abs()
                .mean(),
        );
        let l1_patch = scalar(
            (fake_p.clone().detach() - batch.real_p.clone())
                .abs()
                .mean(),
        );
        let flat5 = |t: Tensor<5>| t.reshape([bsz as i32, -1]);
        let flat4 = |t: Tensor<4>| t.reshape([bsz as i32, -1]);
        let loss_volume = self
            .perceptual
            .distance(flat5(fake_v.clone()), flat5(batch.real_v.clone()));
        let loss_projection = self
            .perceptual
            .distance(flat4(fake_p.clone()), flat4(batch.real_p.clone()));
        let loss_code = losses::code_nll(z_sh) + losses::code_nll(z_a);
        let c = &self.config;
        let paired = c.codes == CodeMode::PerItem;
        let mut metrics = StepMetrics {
            loss_volume: scalar(loss_volume.clone()),
            loss_projection: scalar(loss_projection.clone()),
            loss_code: scalar(loss_code.clone()),
            l1_volume,
            l1_patch,
            ..StepMetrics::default()
        };
        let mut loss_g: Tensor<1> = if paired {
            loss_volume.mul_scalar(c.w_volume)
                + loss_projection.mul_scalar(c.w_projection)
                + loss_code.mul_scalar(c.w_code)
        } else {
            Tensor::zeros([1], &dev)
        };
        if c.w_adversarial > 0.0 {
            let hinge = self.adversarial(&batch, fake_v, fake_p, &mut metrics)?;
            loss_g = loss_g + hinge.mul_scalar(self.config.w_adversarial);
        }
        metrics.loss_g = scalar(loss_g.clone());
        let mut grads = loss_g.backward();
        let gg = GradientsParams::from_module(&mut grads, &self.field);
        self.field = self.opt_g.step(self.config.lr_g, self.field.clone(), gg);
        if let Some(table) = self.codes.take() {
            let gc = GradientsParams::from_module(&mut grads, &table);
            self.codes = Some(self.opt_codes.step(self.config.lr_codes, table, gc));
        }
        self.iteration += 1;
        metrics.iteration = self.iteration;
        ensure!(
            metrics.loss_d.is_finite() && metrics.loss_g.is_finite(),
            "iteration {}: loss is not finite (D {}, G {}); lower the learning rates",
            self.iteration,
            metrics.loss_d,
            metrics.loss_g
        );
        Ok(metrics)
    }

    /// Updates D1 and D2 on this batch (eqs. 7–12) and returns the generator's hinge terms
    /// against the updated discriminators (with DAG weights).
    fn adversarial(
        &mut self,
        batch: &Batch,
        fake_v: Tensor<5>,
        fake_p: Tensor<4>,
        metrics: &mut StepMetrics,
    ) -> Result<Tensor<1>> {
        let m = &self.config.model;
        let (bsz, side, q) = (self.config.batch, m.patch, m.samples);
        let (fv, fp) = (fake_v.clone().detach(), fake_p.clone().detach());
        let lam2 = self.config.lambda2;
        let mut loss_d: Option<Tensor<1>> = None;
        for k in 0..self.config.n_aug {
            let w = self.weight(k);
            let real_v = augment::volume(batch.real_v.clone(), k);
            let real_p = augment::patch(batch.real_p.clone(), k);
            let (lr_v, rec_v) = self.d1.forward(real_v.clone(), k);
            let (lf_v, _) = self.d1.forward(augment::volume(fv.clone(), k), k);
            let (lr_p, rec_p) = self.d2.forward(real_p.clone(), k);
            let (lf_p, _) = self.d2.forward(augment::patch(fp.clone(), k), k);
            let tv = adaptive_avg_pool3d(real_v, [q / 4, side / 4, side / 4]);
            let tp = adaptive_avg_pool2d(real_p, [side / 4, side / 4]);
            let h_v = losses::hinge_discriminator(lr_v, lf_v);
            let h_p = losses::hinge_discriminator(lr_p, lf_p);
            let r_v = self.perceptual.distance(
                rec_v.reshape([bsz as i32, -1]),
                tv.reshape([bsz as i32, -1]),
            );
            let r_p = self.perceptual.distance(
                rec_p.reshape([bsz as i32, -1]),
                tp.reshape([bsz as i32, -1]),
            );
            if k == 0 {
                [
                    metrics.hinge_v,
                    metrics.hinge_p,
                    metrics.recon_v,
                    metrics.recon_p,
                ] = [h_v.clone(), h_p.clone(), r_v.clone(), r_p.clone()]
                    .map(|t| t.into_scalar::<f32>() as f64);
            }
            let term = (h_v + r_v + (h_p + r_p).mul_scalar(lam2)).mul_scalar(w);
            loss_d = Some(match loss_d {
                None => term,
                Some(l) => l + term,
            });
        }
        let loss_d = loss_d.expect("n_aug ≥ 1");
        metrics.loss_d = loss_d.clone().into_scalar::<f32>() as f64;
        let mut grads = loss_d.backward();
        let g1 = GradientsParams::from_module(&mut grads, &self.d1);
        let g2 = GradientsParams::from_module(&mut grads, &self.d2);
        self.d1 = self.opt_d1.step(self.config.lr_d, self.d1.clone(), g1);
        self.d2 = self.opt_d2.step(self.config.lr_d, self.d2.clone(), g2);

        // The generator's terms, against the updated discriminators.
        let mut loss_g: Option<Tensor<1>> = None;
        for k in 0..self.config.n_aug {
            let (lv, _) = self.d1.forward(augment::volume(fake_v.clone(), k), k);
            let (lp, _) = self.d2.forward(augment::patch(fake_p.clone(), k), k);
            let term = (losses::hinge_generator(lv) + losses::hinge_generator(lp).mul_scalar(lam2))
                .mul_scalar(self.weight(k));
            loss_g = Some(match loss_g {
                None => term,
                Some(l) => l + term,
            });
        }
        Ok(loss_g.expect("n_aug ≥ 1"))
    }

    /// The statistics of the learned codes (the standard normal for random codes).
    pub fn code_stats(&self) -> crate::prior::CodeStats {
        match &self.codes {
            Some(t) => {
                let (s, a, rows) = t.values();
                crate::prior::CodeStats::from_table(&s, &a, rows)
            }
            None => crate::prior::CodeStats::standard(
                self.config.model.z_shape,
                self.config.model.z_app,
            ),
        }
    }

    /// Parameter count of the generator (codes included) and of both discriminators.
    pub fn parameter_counts(&self) -> (usize, usize) {
        (
            self.field.num_params() + self.codes.as_ref().map_or(0, |c| c.num_params()),
            self.d1.num_params() + self.d2.num_params(),
        )
    }
}
