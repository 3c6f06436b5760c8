//! Checkpoints: a folder with `config.toml`, `state.json` (iteration, projection scale,
//! density scale), the mean training volume (`mean_volume.npy`, the field's prior),
//! `codes.json` (the training items' ids, their learned codes and the codes' statistics),
//! the networks as burnpack files (`generator.bpk`, `codes.bpk`, `d1.bpk`, `d2.bpk`) and
//! the optimizers' state (`opt_g.bpk`, `opt_codes.bpk`, `opt_d1.bpk`, `opt_d2.bpk`).
//!
//! A checkpoint is written into `<name>.tmp` (its `state.json` last, so a complete
//! `<name>.tmp` is one with a `state.json`); the previous one is renamed to `<name>.old`,
//! `<name>.tmp` to `<name>`, and `<name>.old` removed. A save killed at any point leaves
//! either the previous or the new checkpoint, and [`recover`] (called when training resumes)
//! puts it back in place. Inference needs `config.toml`, `state.json`,
//! `mean_volume.npy`, `codes.json` and `generator.bpk`.

use crate::config::TrainConfig;
use crate::error::{ModelError, Result, ensure};
use crate::field::{Codes, RadianceField};
use crate::prior::{CodeStats, MeanVolume};
use crate::render::DensityScale;
use crate::train::{NumberParams, Trainer};
use burn::module::Module;
use burn::tensor::Device;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::path::Path;

/// What `state.json` holds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct State {
    /// Iterations completed.
    pub iteration: usize,
    /// Line integral mapped to 1 in the discriminators' and losses' inputs.
    pub proj_scale: f64,
    /// Density → mu map of the training data.
    pub density_scale: DensityScale,
}

/// What `codes.json` holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CodeTable {
    /// Training item ids, one per row.
    pub items: Vec<String>,
    /// SHA-256 of each training item's content
    /// ([`Item::content_sha256`](crate::data::Item::content_sha256)), one per row; absent
    /// in checkpoints written before it was recorded.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub item_sha256: Vec<String>,
    /// Shape codes, one row per item (empty for random codes).
    pub shape: Vec<Vec<f32>>,
    /// Appearance codes, one row per item (empty for random codes).
    pub app: Vec<Vec<f32>>,
    /// Per-dimension mean and spread of the codes (inference's prior).
    pub stats: CodeStats,
}

impl CodeTable {
    /// The learned code of training item `id`, `(z_sh, z_a)`, if it has one.
    pub fn code_of(&self, id: &str) -> Option<(&[f32], &[f32])> {
        let i = self.items.iter().position(|x| x == id)?;
        Some((self.shape.get(i)?.as_slice(), self.app.get(i)?.as_slice()))
    }
}

/// Everything inference needs from a checkpoint.
#[derive(Debug)]
pub struct Generator {
    /// The training configuration (network sizes, inference defaults).
    pub config: TrainConfig,
    /// Projection and density scales.
    pub state: State,
    /// The radiance field.
    pub field: RadianceField,
    /// The mean training volume (the field's prior).
    pub prior: MeanVolume,
    /// The training codes and their statistics.
    pub codes: CodeTable,
}

fn err(path: &Path, e: impl std::fmt::Display) -> ModelError {
    ModelError::file(path, e)
}

/// A weights or optimiser file that burn could not read (empty, truncated, or written for
/// another configuration).
fn bpk_err(path: &Path, e: impl std::fmt::Display) -> ModelError {
    ModelError::file(
        path,
        format!("cannot read the weights ({e}): the file is empty, truncated or corrupt"),
    )
}

/// Writes an optimizer's state with its tensors sorted by name ("{param id}.{field}"):
/// burn lists them in hash-map order, so the same state would give different bytes.
fn save_optimizer(
    o: &burn::optim::ModuleOptimizer,
    path: &Path,
) -> std::result::Result<(), Box<dyn std::error::Error>> {
    let reader = burn_pack::Reader::from_bytes(o.to_record().into_bytes()?)?;
    let (scalars, metadata) = (reader.scalars().clone(), reader.metadata().clone());
    let mut tensors = reader.into_tensors()?;
    tensors.sort_by(|a, b| a.name.cmp(&b.name));
    let mut writer = burn_pack::Writer::new(tensors);
    for (key, value) in &scalars {
        writer = writer.with_scalar(key, *value);
    }
    for (key, value) in &metadata {
        writer = writer.with_metadata(key, value);
    }
    writer.write_to_file(path)?;
    Ok(())
}

/// Saves `trainer` (with the training data's density scale) to the folder `dir`.
pub fn save(trainer: &Trainer, density_scale: DensityScale, dir: &Path) -> Result<()> {
    let name = dir
        .file_name()
        .ok_or_else(|| err(dir, "checkpoint path has no folder name"))?;
    let tmp = dir.with_file_name(format!("{}.tmp", name.to_string_lossy()));
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).map_err(|e| err(&tmp, e))?;
    }
    std::fs::create_dir_all(&tmp).map_err(|e| err(&tmp, e))?;
    std::fs::write(tmp.join("config.toml"), trainer.config.to_toml()).map_err(|e| err(&tmp, e))?;
    let p = tmp.join("generator.bpk");
    trainer
        .field
        .clone()
        .save_file(&p)
        .map_err(|e| err(&p, e))?;
    let (shape, app) = match &trainer.codes {
        Some(t) => {
            let p = tmp.join("codes.bpk");
            t.clone().save_file(&p).map_err(|e| err(&p, e))?;
            let (s, a, rows) = t.values();
            let split = |v: Vec<f32>| -> Vec<Vec<f32>> {
                let m = v.len() / rows.max(1);
                v.chunks(m.max(1)).map(<[f32]>::to_vec).collect()
            };
            (split(s), split(a))
        }
        None => (Vec::new(), Vec::new()),
    };
    let table = CodeTable {
        items: trainer.item_ids.clone(),
        item_sha256: trainer.item_sha256.clone(),
        shape,
        app,
        stats: trainer.code_stats(),
    };
    std::fs::write(
        tmp.join("codes.json"),
        serde_json::to_string(&table).expect("codes serialise"),
    )
    .map_err(|e| err(&tmp, e))?;
    let p = tmp.join("d1.bpk");
    trainer.d1.clone().save_file(&p).map_err(|e| err(&p, e))?;
    let p = tmp.join("d2.bpk");
    trainer.d2.clone().save_file(&p).map_err(|e| err(&p, e))?;
    for (n, o) in [
        ("opt_g.bpk", &trainer.opt_g),
        ("opt_codes.bpk", &trainer.opt_codes),
        ("opt_d1.bpk", &trainer.opt_d1),
        ("opt_d2.bpk", &trainer.opt_d2),
    ] {
        let p = tmp.join(n);
        save_optimizer(o, &p).map_err(|e| err(&p, e))?;
    }
    let m = &trainer.prior;
    let p = tmp.join("mean_volume.npy");
    tomograf_datasets::image::write_npy(&p, &m.data, &[m.dims[2], m.dims[1], m.dims[0]])
        .map_err(|e| err(&p, e))?;
    // Last: the state, which marks the folder complete.
    let state = State {
        iteration: trainer.iteration,
        proj_scale: trainer.proj_scale,
        density_scale,
    };
    std::fs::write(
        tmp.join("state.json"),
        serde_json::to_string_pretty(&state).expect("state serialises"),
    )
    .map_err(|e| err(&tmp, e))?;
    let old = sibling(dir, "old")?;
    if old.exists() {
        std::fs::remove_dir_all(&old).map_err(|e| err(&old, e))?;
    }
    if dir.exists() {
        std::fs::rename(dir, &old).map_err(|e| err(dir, e))?;
    }
    std::fs::rename(&tmp, dir).map_err(|e| err(dir, e))?;
    if old.exists() {
        std::fs::remove_dir_all(&old).map_err(|e| err(&old, e))?;
    }
    Ok(())
}

/// `<dir>.<suffix>` beside `dir`.
fn sibling(dir: &Path, suffix: &str) -> Result<std::path::PathBuf> {
    let name = dir
        .file_name()
        .ok_or_else(|| err(dir, "checkpoint path has no folder name"))?;
    Ok(dir.with_file_name(format!("{}.{suffix}", name.to_string_lossy())))
}

/// Puts a checkpoint whose save was killed back in place: when `dir` is missing, a
/// complete `<dir>.tmp` (killed between the renames) or else `<dir>.old` (killed before the
/// new one was complete) becomes `dir`; leftovers of finished or abandoned saves are
/// removed. Returns whether `dir` now exists. Called by [`load_trainer`] (not by inference,
/// which must not move the folders of a training run that is saving).
pub fn recover(dir: &Path) -> Result<bool> {
    let (tmp, old) = (sibling(dir, "tmp")?, sibling(dir, "old")?);
    if !dir.exists() {
        if tmp.join("state.json").is_file() {
            std::fs::rename(&tmp, dir).map_err(|e| err(dir, e))?;
        } else if old.exists() {
            std::fs::rename(&old, dir).map_err(|e| err(dir, e))?;
        }
    }
    for leftover in [tmp, old] {
        if dir.exists() && leftover.exists() {
            std::fs::remove_dir_all(&leftover).map_err(|e| err(&leftover, e))?;
        }
    }
    Ok(dir.exists())
}

/// The configuration a checkpoint folder holds (`config.toml`), checked.
pub fn read_config(dir: &Path) -> Result<TrainConfig> {
    let cp = dir.join("config.toml");
    let text = std::fs::read_to_string(&cp).map_err(|e| {
        err(
            &cp,
            format!("{e} (is {} a checkpoint folder?)", dir.display()),
        )
    })?;
    let config = TrainConfig::parse(&text).map_err(|e| {
        let hint = if e.to_string().contains("missing field") {
            " (a checkpoint from before per-item codes and the mean-volume prior: retrain it \
             with this version)"
        } else {
            ""
        };
        err(&cp, format!("{e}{hint}"))
    })?;
    Ok(config)
}

fn read_meta(dir: &Path) -> Result<(TrainConfig, State)> {
    let config = read_config(dir)?;
    let sp = dir.join("state.json");
    let bytes = std::fs::read(&sp).map_err(|e| err(&sp, e))?;
    let state: State = serde_json::from_slice(&bytes).map_err(|e| err(&sp, e))?;
    // Training sets it to bring the line integrals to about 1 (9.2 for the shipped model);
    // anything beyond 10⁶ makes every projection loss meaningless.
    if !(state.proj_scale.is_finite() && state.proj_scale > 0.0 && state.proj_scale <= 1e6) {
        return Err(err(
            &sp,
            format!(
                "proj_scale = {}; it must be finite and in (0, 1e6] (the checkpoint is corrupt)",
                state.proj_scale
            ),
        ));
    }
    Ok((config, state))
}

/// A checkpoint's code table (`codes.json`): its items, their digests and learned codes.
pub fn read_code_table(dir: &Path) -> Result<CodeTable> {
    read_codes(dir)
}

fn read_codes(dir: &Path) -> Result<CodeTable> {
    let p = dir.join("codes.json");
    let bytes = std::fs::read(&p).map_err(|e| err(&p, e))?;
    serde_json::from_slice(&bytes).map_err(|e| err(&p, e))
}

fn require_mean(dir: &Path) -> Result<MeanVolume> {
    load_mean(dir)?.ok_or_else(|| {
        err(
            &dir.join("mean_volume.npy"),
            "missing: the field is a residual on the mean training volume, which every \
             checkpoint holds (written by `tomograf train`)",
        )
    })
}

/// Loads a whole trainer (to resume training).
pub fn load_trainer(dir: &Path, device: &Device) -> Result<(Trainer, State)> {
    recover(dir)?;
    let (config, state) = read_meta(dir)?;
    let mean = require_mean(dir)?;
    let codes = read_codes(dir)?;
    check_digests(dir, &codes)?;
    let mut t = load_networks(
        Trainer::new(config, state.proj_scale, mean, codes.items, device)?,
        dir,
    )?;
    t.item_sha256 = codes.item_sha256;
    let mut t = load_codes(t, dir)?;
    t.iteration = state.iteration;
    Ok((t, state))
}

/// A `codes.json` whose digests, when it has them, are one per item.
fn check_digests(dir: &Path, codes: &CodeTable) -> Result<()> {
    ensure!(
        codes.item_sha256.is_empty() || codes.item_sha256.len() == codes.items.len(),
        "{}: {} item digests for {} items: the file is corrupt",
        dir.join("codes.json").display(),
        codes.item_sha256.len(),
        codes.items.len()
    );
    Ok(())
}

/// Puts the checkpoint's learned codes and their optimiser state into `t` (per-item codes).
fn load_codes(mut t: Trainer, dir: &Path) -> Result<Trainer> {
    if let Some(table) = t.codes.take() {
        let p = dir.join("codes.bpk");
        t.codes = Some(table.try_load_file(&p).map_err(|e| bpk_err(&p, e))?);
        let p = dir.join("opt_codes.bpk");
        t.opt_codes = t.opt_codes.load(&p).map_err(|e| bpk_err(&p, e))?;
    }
    Ok(t)
}

/// Puts a checkpoint's generator and discriminators, with their optimiser states, into `t`
/// (what [`load_trainer`] and [`load_trainer_for`] share; the codes are each one's own).
fn load_networks(mut t: Trainer, dir: &Path) -> Result<Trainer> {
    let p = dir.join("generator.bpk");
    t.field = t.field.try_load_file(&p).map_err(|e| bpk_err(&p, e))?;
    let p = dir.join("d1.bpk");
    t.d1 = t.d1.try_load_file(&p).map_err(|e| bpk_err(&p, e))?;
    let p = dir.join("d2.bpk");
    t.d2 = t.d2.try_load_file(&p).map_err(|e| bpk_err(&p, e))?;
    let p = dir.join("opt_g.bpk");
    t.opt_g = t.opt_g.load(&p).map_err(|e| bpk_err(&p, e))?;
    let p = dir.join("opt_d1.bpk");
    t.opt_d1 = t.opt_d1.load(&p).map_err(|e| bpk_err(&p, e))?;
    let p = dir.join("opt_d2.bpk");
    t.opt_d2 = t.opt_d2.load(&p).map_err(|e| bpk_err(&p, e))?;
    Ok(t)
}

/// A trainer that carries a checkpoint's training on to another data set (fine-tuning):
/// the checkpoint's configuration, projection scale, iteration count, generator and
/// discriminators with their optimiser states; fresh codes (drawn as a new run draws them)
/// for `item_ids`, the new set's items, with a fresh code optimiser; and `prior`, the new
/// set's mean volume, as the field's anchor. `seed` (default: the checkpoint's) seeds the
/// new codes and the run's sampling. The new items must share the checkpoint's density
/// scale (HU window and energy): the generator learned in those units.
///
/// When the new items are the very items the checkpoint's codes were learned on — the same
/// ids in the same order with the same content digests `item_sha256`
/// ([`Item::content_sha256`](crate::data::Item::content_sha256)), as recorded in its
/// `codes.json` — their learned codes and the code optimiser's state are kept instead of
/// drawn afresh (training on further: fresh codes would undo what the codes had learned).
/// When only some are — the checkpoint's items with others added, or some taken away — each
/// item whose digest the checkpoint learned a code for keeps that code, the others get
/// fresh ones, and the code optimiser starts afresh. Returns the trainer and how many items
/// kept their learned codes. A checkpoint without recorded digests always gets fresh codes.
pub fn load_trainer_for(
    dir: &Path,
    seed: Option<u64>,
    prior: MeanVolume,
    density_scale: DensityScale,
    item_ids: Vec<String>,
    item_sha256: Vec<String>,
    device: &Device,
) -> Result<(Trainer, usize)> {
    recover(dir)?;
    let (mut config, state) = read_meta(dir)?;
    if let Some(seed) = seed {
        config.seed = seed;
    }
    ensure!(
        state.density_scale == density_scale,
        "{}: the checkpoint was trained on items with density scale {:?}, the new data set's \
         are {:?} (another HU window or energy): fine-tune on items made alike",
        dir.display(),
        state.density_scale,
        density_scale
    );
    ensure!(
        item_sha256.len() == item_ids.len(),
        "{} item digests for {} items",
        item_sha256.len(),
        item_ids.len()
    );
    let codes = read_codes(dir)?;
    check_digests(dir, &codes)?;
    let same_items = !codes.item_sha256.is_empty()
        && codes.items == item_ids
        && codes.item_sha256 == item_sha256;
    let mut t = load_networks(
        Trainer::new(config, state.proj_scale, prior, item_ids, device)?,
        dir,
    )?;
    t.item_sha256 = item_sha256;
    let kept = if same_items && t.codes.is_some() {
        t = load_codes(t, dir)?;
        t.item_ids.len()
    } else {
        keep_known_codes(&mut t, &codes)
    };
    t.iteration = state.iteration;
    Ok((t, kept))
}

/// Gives each item of `t` (its fresh code table, its `item_sha256`) whose content digest
/// `table` holds a learned code for — once: a digest learned twice is ambiguous and left
/// fresh — that code; returns how many items took one.
fn keep_known_codes(t: &mut Trainer, table: &CodeTable) -> usize {
    let Some(codes) = &t.codes else {
        return 0;
    };
    if table.item_sha256.len() != table.shape.len() || table.app.len() != table.shape.len() {
        return 0;
    }
    let mut learned: HashMap<&str, Option<usize>> = HashMap::new();
    for (row, sha) in table.item_sha256.iter().enumerate() {
        learned
            .entry(sha.as_str())
            .and_modify(|r| *r = None)
            .or_insert(Some(row));
    }
    let (mut shape, mut app, rows) = codes.values();
    let (ms, ma) = (shape.len() / rows.max(1), app.len() / rows.max(1));
    let mut kept = 0;
    for (i, sha) in t.item_sha256.iter().enumerate().take(rows) {
        let Some(&Some(j)) = learned.get(sha.as_str()) else {
            continue;
        };
        if table.shape[j].len() == ms && table.app[j].len() == ma {
            shape[i * ms..(i + 1) * ms].copy_from_slice(&table.shape[j]);
            app[i * ma..(i + 1) * ma].copy_from_slice(&table.app[j]);
            kept += 1;
        }
    }
    if kept > 0 {
        t.codes = Some(Codes::new(shape, app, rows, &t.device).map(&mut NumberParams(3 << 32)));
    }
    kept
}

/// Loads what inference needs: the generator, its prior and the training codes.
pub fn load_generator(dir: &Path, device: &Device) -> Result<Generator> {
    let (config, state) = read_meta(dir)?;
    let prior = require_mean(dir)?;
    let codes = read_codes(dir)?;
    let m = &config.model;
    ensure!(
        codes.stats.shape_mean.len() == m.z_shape && codes.stats.app_mean.len() == m.z_app,
        "{}: code statistics of sizes {} + {} but the config's codes are {} + {}",
        dir.display(),
        codes.stats.shape_mean.len(),
        codes.stats.app_mean.len(),
        m.z_shape,
        m.z_app
    );
    let field = RadianceField::new(m, device);
    let p = dir.join("generator.bpk");
    let field = field.try_load_file(&p).map_err(|e| bpk_err(&p, e))?;
    Ok(Generator {
        config,
        state,
        field,
        prior,
        codes,
    })
}

/// The files inference reads from a checkpoint, in the order [`fingerprint`] hashes them.
pub const INFERENCE_FILES: [&str; 5] = [
    "config.toml",
    "state.json",
    "mean_volume.npy",
    "codes.json",
    "generator.bpk",
];

/// SHA-256 (hex) of what inference reads from the checkpoint in `dir` ([`INFERENCE_FILES`],
/// each hashed with its name and length): two checkpoints that reconstruct alike share it,
/// whatever their folders are called; a resumed or fine-tuned one does not. An evaluation
/// records it so that scores of one checkpoint are never taken for another's.
pub fn fingerprint(dir: &Path) -> Result<String> {
    let mut h = Sha256::new();
    for name in INFERENCE_FILES {
        let p = dir.join(name);
        let bytes = std::fs::read(&p).map_err(|e| err(&p, e))?;
        h.update(name.as_bytes());
        h.update((bytes.len() as u64).to_le_bytes());
        h.update(&bytes);
    }
    Ok(format!("{:x}", h.finalize()))
}

/// The mean training volume stored with a checkpoint, if any.
pub fn load_mean(dir: &Path) -> Result<Option<MeanVolume>> {
    let p = dir.join("mean_volume.npy");
    if !p.exists() {
        return Ok(None);
    }
    let bytes = std::fs::read(&p).map_err(|e| err(&p, e))?;
    let npy = npyz::NpyFile::new(&bytes[..]).map_err(|e| err(&p, e))?;
    let shape: Vec<u64> = npy.shape().to_vec();
    let data: Vec<f32> = npy
        .into_vec()
        .map_err(|e| err(&p, format!("truncated or corrupt NPY data ({e})")))?;
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        return Err(err(
            &p,
            format!("value {i} is {} (the checkpoint is corrupt)", data[i]),
        ));
    }
    // The mean of training CTs each clamped to [0, 1] by its HU window.
    if let Some(i) = data.iter().position(|v| !(-1e-6..=1.0 + 1e-6).contains(v)) {
        return Err(err(
            &p,
            format!(
                "value {i} is {:e}, outside [0, 1], the normalised density every training \
                 CT is clamped to (the checkpoint is corrupt)",
                data[i]
            ),
        ));
    }
    let [nz, ny, nx] = shape[..] else {
        return Err(err(
            &p,
            format!("expected a 3D array, found shape {shape:?}"),
        ));
    };
    if data.len() as u64 != nz * ny * nx || data.is_empty() {
        return Err(err(&p, "data does not match its shape"));
    }
    Ok(Some(MeanVolume {
        data,
        dims: [nx as usize, ny as usize, nz as usize],
    }))
}
