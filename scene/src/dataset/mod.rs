//! Data-set items as in the TomoGRAF paper, the one definition behind `tomograf dataset`,
//! the studies and `tomograf.make_item` in Python.
//!
//! Per item (a CT file or DICOM folder, or a seeded anatomical phantom): a CT is first
//! brought into the patient frame ([`tomograf_datasets::frame`]) and, unless
//! [`ItemSettings::keep_table`], reduced to its body ([`tomograf_datasets::body`]); then,
//! optionally shape-augmented ([`tomograf_datasets::augment`]), the
//! black-border-cropped CT resampled to `size³` and normalised to [0, 1] over an HU window
//! (`ct.nii.gz`, whose affine keeps the world frame), and `views` projections every
//! 360/`views` degrees plus AP and lateral at `size²` (`projections.npy`, shape views × rows
//! × cols), rendered with exact Siddon from the cropped full-resolution volume — ideal line
//! integrals at an effective energy, or with an [`Acquisition`] the detector's signal —
//! with the geometry of every view in `views.json`. `item.json` is written last and marks
//! the item finished (the format: [`tomograf_datasets::item`]).
//!
//! Every file is written to a temporary name and renamed, so a killed run leaves no
//! half-written file, and items are independent: item i's bytes depend only on its source,
//! the settings and i (its noise seed is [`item_seed`]`(seed, i)`), so shards of a set give
//! the bytes of one run.
//!
//! Units: mm, keV, HU.

mod item_scene;

pub use item_scene::{ItemScene, make_item};

use crate::progress::Progress;
use anyhow::{Context, Result, bail};
use serde::Serialize;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use tomograf_datasets::anatomy::{AnatomySpec, Profile};
use tomograf_datasets::atomic;
use tomograf_datasets::augment::AugmentRanges;
use tomograf_datasets::body::BodySettings;
use tomograf_datasets::item::{self};
use tomograf_datasets::population::Population;
use tomograf_datasets::preprocess::HuWindow;
use tomograf_physics::acquisition::Acquisition;

/// How every item of a set is made. [`Default`] is the paper's protocol at 128³.
#[derive(Debug, Clone)]
pub struct ItemSettings {
    /// HU window mapped to [0, 1].
    pub window: HuWindow,
    /// Black-border crop threshold, HU: voxels at or below it count as border.
    pub crop_hu: f32,
    /// Effective energy for HU → μ of the ideal DRR, keV.
    pub energy_kev: f64,
    /// Projections per full rotation (every 360/views degrees), besides AP and lateral.
    pub views: usize,
    /// CT grid (size³) and detector (size²).
    pub size: usize,
    /// Source-to-isocentre distance, mm.
    pub sad_mm: f64,
    /// Source-to-detector distance, mm.
    pub sid_mm: f64,
    /// Name of the split the set belongs to (e.g. "train", or the institution).
    pub split: String,
    /// Real detector physics and its noise seed; `None`: ideal line integrals.
    pub acquisition: Option<(Acquisition, u64)>,
    /// Keep what lies around a CT's body (couch, padding, stray voxels) instead of setting
    /// it to air before the crop.
    pub keep_table: bool,
    /// How a CT's body is told from the rest ([`tomograf_datasets::body`]).
    pub body: BodySettings,
    /// Shape augmentation ([`tomograf_datasets::augment`]) within these ranges, item i's
    /// drawn from [`item_seed`]`(seed, i)`; `None`: none.
    pub augment: Option<(AugmentRanges, u64)>,
    /// A scan range ([`tomograf_datasets::scan_range`]) drawn per item, item i's from
    /// [`item_seed`]`(seed, i)`, applied after the augmentation; `None`: the whole body.
    pub scan_range: Option<u64>,
}

impl Default for ItemSettings {
    fn default() -> Self {
        Self {
            window: HuWindow::CHEST,
            crop_hu: -900.0,
            energy_kev: 60.0,
            views: 72,
            size: 128,
            sad_mm: 1000.0,
            sid_mm: 1500.0,
            split: "train".into(),
            acquisition: None,
            keep_table: false,
            body: BodySettings::default(),
            augment: None,
            scan_range: None,
        }
    }
}

impl ItemSettings {
    /// Checks the settings before any work, naming the bad one.
    pub fn validate(&self) -> Result<()> {
        if self.size < 2 || self.views == 0 {
            bail!("the size must be at least 2 and the views at least 1");
        }
        // What one item holds at once: its views + AP + lateral as f32 images, and the CT
        // resampled to the grid, normalised and written (three f32 copies).
        let (size, views) = (self.size as u128, self.views as u128);
        tomograf_sim::memory::check(
            (views + 2) * size * size * 4 + 3 * size * size * size * 4,
            &format!(
                "an item of {} views of {}² pixels and a {}³ CT",
                self.views + 2,
                self.size,
                self.size
            ),
        )?;
        if let Some((acq, _)) = &self.acquisition
            && acq.detector.channels() != 1
        {
            bail!("data sets hold one image per view: use a one-channel detector");
        }
        Ok(())
    }
}

impl ItemSettings {
    /// Settings that are legal but almost certainly not meant, as warnings: a detector at or
    /// before the isocentre's distance cuts through every item's CT (its rays end inside
    /// it, so the line integrals are truncated), as `tomograf project` warns too.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        if self.sid_mm <= self.sad_mm {
            w.push(format!(
                "warning: the source-detector distance {} mm is not beyond the source-isocentre \
                 distance {} mm: the detector cuts through every CT and the line integrals are \
                 truncated; raise sid_mm (--sid)",
                self.sid_mm, self.sad_mm
            ));
        }
        w
    }
}

/// Where an item comes from.
#[derive(Debug, Clone, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum ItemSource {
    /// A CT: NIfTI or NRRD file, or DICOM series folder.
    File {
        /// Its path.
        path: PathBuf,
    },
    /// A seeded anatomical phantom.
    Phantom {
        /// What is generated.
        spec: AnatomySpec,
    },
}

impl ItemSource {
    /// Phantom `seed` of `profile` on a grid large enough for the profile's field of view,
    /// at about CT resolution, optionally on a table and with a pacemaker.
    pub fn phantom(seed: u64, profile: Profile, table: bool, pacemaker: bool) -> Self {
        let (dims, spacing) = match profile {
            Profile::LidcCropped => ([200, 200, 128], [2.0, 2.0, 2.5]),
            Profile::FullChest => ([256, 256, 200], [2.2, 2.2, 2.5]),
        };
        let mut spec = AnatomySpec::new(seed, profile, dims, spacing);
        spec.table = table;
        spec.pacemaker = pacemaker;
        ItemSource::Phantom { spec }
    }

    /// The same source with a phantom's soft tissue made heterogeneous: a correlated
    /// texture of `hu` HU standard deviation ([`anatomy::heterogeneity`]); a CT file is
    /// left as it is.
    pub fn with_heterogeneity(mut self, hu: f64) -> Self {
        if let ItemSource::Phantom { spec } = &mut self {
            spec.heterogeneity_hu = hu;
        }
        self
    }

    /// The same source with a phantom's heart and diaphragm drawn from ranges `k` times as
    /// wide ([`anatomy::AnatomySpec::organ_spread`]); a CT file is left as it is.
    pub fn with_organ_spread(mut self, k: f64) -> Self {
        if let ItemSource::Phantom { spec } = &mut self {
            spec.organ_spread = k;
        }
        self
    }

    /// The same source with a phantom warped by a smooth random displacement field of
    /// `mm` standard deviation per component ([`anatomy::deform`]); a CT file is left as
    /// it is.
    pub fn with_deformation(mut self, mm: f64) -> Self {
        if let ItemSource::Phantom { spec } = &mut self {
            spec.deform_mm = mm;
        }
        self
    }
}

/// Inputs expanded: files as given; a folder with DICOM files is one series, any other
/// folder contributes its NIfTI and NRRD files and series sub-folders, sorted by path.
pub fn expand_inputs(inputs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for p in inputs {
        if p.is_dir()
            && !tomograf_datasets::dicom::scan_dicom_tree(p)?
                .iter()
                .any(|s| s.folder == *p)
        {
            let mut nii: Vec<PathBuf> = std::fs::read_dir(p)
                .with_context(|| format!("cannot list {}", p.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|f| {
                    let n = f.to_string_lossy().to_ascii_lowercase();
                    n.ends_with(".nii") || n.ends_with(".nii.gz") || crate::volume::is_nrrd(f)
                })
                .collect();
            nii.sort();
            out.extend(nii);
            out.extend(
                tomograf_datasets::dicom::scan_dicom_tree(p)?
                    .into_iter()
                    .map(|s| s.folder),
            );
        } else {
            out.push(p.clone());
        }
    }
    Ok(out)
}

/// SHA-256 (hex) of a file, or of a folder's files (sorted names and contents): how an item
/// and the scatter bench's reference cache know a CT by its contents.
pub fn sha256_of(path: &Path) -> Result<String> {
    let mut h = Sha256::new();
    if path.is_dir() {
        let mut files: Vec<PathBuf> = std::fs::read_dir(path)?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|f| f.is_file())
            .collect();
        files.sort();
        for f in files {
            h.update(f.file_name().unwrap_or_default().as_encoded_bytes());
            h.update(std::fs::read(&f).with_context(|| format!("cannot read {}", f.display()))?);
        }
    } else {
        h.update(std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?);
    }
    Ok(format!("{:x}", h.finalize()))
}

/// Whether `dir` holds a finished item (its `item.json` exists and parses).
pub fn is_finished(dir: &Path) -> bool {
    item::finished_record(dir).is_some()
}

/// A set's items, the shard this run makes, and where they go.
#[derive(Debug, Clone)]
pub struct DatasetJob {
    /// Every item of the set, in order.
    pub sources: Vec<ItemSource>,
    /// How each is made.
    pub settings: ItemSettings,
    /// Output folder: item i in `{i:05}/`, `manifest.jsonl` beside them.
    pub output: PathBuf,
    /// This run makes items i with i mod n = shard.0, n = shard.1.
    pub shard: (usize, usize),
}

/// What a [`DatasetJob`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DatasetSummary {
    /// Items made by this run.
    pub made: usize,
    /// Items of this shard already finished (skipped).
    pub skipped: usize,
    /// Finished items the rebuilt manifest lists (all shards).
    pub listed: usize,
    /// The largest estimated peak memory of the items made, bytes
    /// ([`crate::peak::item_peak_bytes`]); 0 when none was made.
    pub peak_bytes: u128,
}

/// The most phantoms one data set holds (a million 64³ items is a terabyte).
pub const MAX_PHANTOMS: usize = 1_000_000;

/// Refuses more than [`MAX_PHANTOMS`] phantoms, or seeds `seed … seed + count − 1` that pass
/// 2⁶⁴ − 1 (they would wrap round and repeat patients).
pub fn check_phantom_count(seed: u64, count: usize) -> Result<()> {
    if count > MAX_PHANTOMS {
        bail!(
            "{count} phantoms: at most {MAX_PHANTOMS} per data set (make a larger one as \
             several folders, each with its own seed)"
        );
    }
    if seed.checked_add(count.saturating_sub(1) as u64).is_none() {
        bail!(
            "seed {seed} with {count} phantoms: the phantoms' seeds would pass 2^64 − 1 and \
             repeat; give a smaller seed"
        );
    }
    Ok(())
}

impl DatasetJob {
    /// `count` procedural phantoms of `profile` with seeds `seed, seed + 1, …` (no table,
    /// a pacemaker if asked), `size`³ voxels with `views` views (+ AP and lateral), the
    /// paper's protocol otherwise ([`ItemSettings::default`]), into `output`, one shard.
    pub fn phantoms(
        output: PathBuf,
        (seed, count): (u64, usize),
        profile: Profile,
        pacemaker: bool,
        (size, views): (usize, usize),
        split: &str,
        acquisition: Option<(Acquisition, u64)>,
    ) -> Result<Self> {
        check_phantom_count(seed, count)?;
        Ok(Self {
            sources: (0..count)
                .map(|n| ItemSource::phantom(seed + n as u64, profile, false, pacemaker))
                .collect(),
            settings: ItemSettings {
                views,
                size,
                split: split.into(),
                acquisition,
                ..ItemSettings::default()
            },
            output,
            shard: (0, 1),
        })
    }

    /// The indices this run is responsible for.
    pub fn mine(&self) -> Vec<usize> {
        let (shard, shards) = self.shard;
        (0..self.sources.len())
            .filter(|i| i % shards == shard)
            .collect()
    }

    /// [`DatasetJob::run`] reporting to `progress` (stage "item", the item's index as the
    /// message), ending with a note of what was made and where the manifest is.
    pub fn make(&self, progress: &dyn Progress) -> Result<DatasetSummary> {
        progress.start("item", self.mine().len() as u64, 0);
        let summary = self.run(|index, _| {
            progress.inc();
            progress.set_message(&format!("{index:05}"));
        });
        progress.finish();
        let summary = summary?;
        let (shard, shards) = self.shard;
        if summary.made > 0 {
            progress.note(&format!(
                "estimated peak memory {:.0} MiB (the largest item's)",
                summary.peak_bytes as f64 / (1u64 << 20) as f64
            ));
        }
        progress.note(&format!(
            "{} item(s) made, {} already finished (shard {shard}/{shards}); manifest lists {} \
             of {} item(s): {}",
            summary.made,
            summary.skipped,
            summary.listed,
            self.sources.len(),
            self.output.join("manifest.jsonl").display()
        ));
        Ok(summary)
    }

    /// Makes this shard's unfinished items (resumable: finished ones are skipped), then
    /// rebuilds the manifest. `progress(index, made)` is called after each item.
    pub fn run(&self, mut progress: impl FnMut(usize, bool)) -> Result<DatasetSummary> {
        self.settings.validate()?;
        let (shard, shards) = self.shard;
        if shards == 0 || shard >= shards {
            bail!("shard {shard}/{shards}: give I/N with 0 ≤ I < N");
        }
        if self.sources.is_empty() {
            bail!("nothing to do: give CT inputs or phantoms");
        }
        self.check_disk()?;
        std::fs::create_dir_all(&self.output)
            .with_context(|| format!("cannot create {}", self.output.display()))?;
        atomic::remove_stale_temporaries(&self.output)?;
        let (mut made, mut skipped, mut peak_bytes) = (0, 0, 0);
        for index in self.mine() {
            let dir = self.output.join(format!("{index:05}"));
            let done = is_finished(&dir);
            if done {
                skipped += 1;
            } else {
                let peak = make_item(&self.settings, index, &self.sources[index], &dir)
                    .with_context(|| format!("item {index:05}"))?;
                peak_bytes = peak_bytes.max(peak);
                made += 1;
            }
            progress(index, !done);
        }
        let listed = item::write_manifest(&self.output, self.sources.len())?;
        if let Some(p) = Population::of(&item::read_manifest(&self.output, None)?) {
            p.write(&self.output)?;
        }
        Ok(DatasetSummary {
            made,
            skipped,
            listed,
            peak_bytes,
        })
    }
}

impl DatasetJob {
    /// Refuses a run whose unfinished items ([`crate::disk::item_bytes`] each) would not fit
    /// in the space free on the output folder's file system.
    fn check_disk(&self) -> Result<()> {
        let pending = self
            .mine()
            .into_iter()
            .filter(|i| !is_finished(&self.output.join(format!("{i:05}"))))
            .count();
        if pending == 0 {
            return Ok(());
        }
        let s = &self.settings;
        let needed = pending as u128 * crate::disk::item_bytes(s.size, s.views + 2);
        crate::disk::check_fits(
            needed,
            crate::disk::available_bytes(&self.output)?,
            &format!(
                "{pending} item(s) of {}³ voxels and {} views of {}² pixels in {}",
                s.size,
                s.views + 2,
                s.size,
                self.output.display()
            ),
        )
    }
}

/// The finished items of the data set in `dir` whose body fraction or tissue fractions lie
/// far outside `reference` ([`Population::outliers`]): (item id, what is off) for each.
pub fn outliers(dir: &Path, reference: &Population) -> Result<Vec<(String, Vec<String>)>> {
    Ok(item::read_manifest(dir, None)?
        .iter()
        .map(|r| (r.id.clone(), reference.outliers(r)))
        .filter(|(_, o)| !o.is_empty())
        .collect())
}
