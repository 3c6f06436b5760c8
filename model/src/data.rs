//! A data set made by `tomograf dataset`, as the model uses it: each item's files (read and
//! checked by [`tomograf_datasets::item`], the format's one definition) with the density
//! scale of its HU window.

use crate::error::{ModelError, Result, ensure};
use crate::render::DensityScale;
use std::path::{Path, PathBuf};
use tomograf_datasets::item;
use tomograf_datasets::preprocess::HuWindow;
use tomograf_physics::acquisition::Acquisition;
use tomograf_sim::attenuation::mu_water_per_mm;
use tomograf_sim::{Geometry, Pose, View, Volume};

/// One item: projections with their geometry and (when present) the ground-truth CT.
#[derive(Debug, Clone)]
pub struct Item {
    /// Item id (folder name).
    pub id: String,
    /// The folder.
    pub dir: PathBuf,
    /// Normalised CT (values in [0, 1]); `None` when the item has no `ct.nii.gz`.
    pub ct: Option<Volume>,
    /// Line integrals, `views × rows × cols`, row-major.
    pub projections: Vec<f32>,
    /// Detector rows.
    pub rows: usize,
    /// Detector columns.
    pub cols: usize,
    /// The set-up the views were made with.
    pub geometry: Geometry,
    /// One pose per projection.
    pub poses: Vec<Pose>,
    /// One view per projection.
    pub views: Vec<View>,
    /// HU window of the normalisation.
    pub window: HuWindow,
    /// Normalised density → mu.
    pub scale: DensityScale,
    /// The acquisition the projections were recorded with (`None`: ideal DRRs, or an item
    /// written before acquisitions were recorded).
    pub acquisition: Option<Acquisition>,
}

impl Item {
    /// Projection `i` (rows × cols).
    pub fn projection(&self, i: usize) -> &[f32] {
        let n = self.rows * self.cols;
        &self.projections[i * n..(i + 1) * n]
    }

    /// SHA-256 (hex) of what training reads from the item: its line integrals (with the
    /// detector size and view count) and its CT (size, voxel spacing and values; a marker
    /// when it has none). Two folders holding the same data give the same digest, whatever
    /// their paths; a checkpoint's per-item codes are kept only for items whose digest is
    /// the one they were learned on (`codes.json`).
    pub fn content_sha256(&self) -> String {
        use sha2::{Digest, Sha256};
        let mut h = Sha256::new();
        for n in [
            self.rows,
            self.cols,
            self.poses.len(),
            self.projections.len(),
        ] {
            h.update((n as u64).to_le_bytes());
        }
        hash_f32(&mut h, &self.projections);
        match &self.ct {
            None => h.update(b"no ct"),
            Some(ct) => {
                h.update(b"ct");
                for n in ct.dims() {
                    h.update((n as u64).to_le_bytes());
                }
                for s in ct.spacing().to_array() {
                    h.update(s.to_bits().to_le_bytes());
                }
                hash_f32(&mut h, ct.data());
            }
        }
        format!("{:x}", h.finalize())
    }

    /// Index of the projection taken at pose `(θ, φ)` (degrees, to 1e-6), if any.
    pub fn find_pose(&self, pose: Pose) -> Option<usize> {
        self.poses.iter().position(|p| {
            (p.theta_deg - pose.theta_deg)
                .rem_euclid(360.0)
                .min((pose.theta_deg - p.theta_deg).rem_euclid(360.0))
                < 1e-6
                && (p.phi_deg - pose.phi_deg).abs() < 1e-6
        })
    }
}

/// Feeds `values` (little-endian bytes) to `h`, a block at a time.
fn hash_f32(h: &mut sha2::Sha256, values: &[f32]) {
    use sha2::Digest;
    let mut block = Vec::with_capacity(4096);
    for chunk in values.chunks(1024) {
        block.clear();
        block.extend(chunk.iter().flat_map(|v| v.to_le_bytes()));
        h.update(&block);
    }
}

/// Loads one item folder (the format: [`tomograf_datasets::item`]).
pub fn load_item(dir: &Path) -> Result<Item> {
    let files = item::read_item(dir)?;
    let record = &files.record;
    // Nothing attenuated in any view (an all-air CT, or a volume outside the beam): the
    // item holds nothing to learn or score.
    ensure!(
        files.projections.iter().any(|&p| p != 0.0),
        "{}: every projection value is 0 (nothing in the beam attenuates: an all-air CT?); \
         re-make the item or remove its line from manifest.jsonl",
        dir.join(&record.projections).display()
    );
    let acquisition = record
        .acquisition()
        .map_err(|e| ModelError::file(&dir.join(item::ITEM_JSON), e))?
        .map(|a| a.settings);
    let mu_w = mu_water_per_mm(record.energy_kev)?;
    let scale = DensityScale::from_window(
        f64::from(record.hu_window.lo),
        f64::from(record.hu_window.hi),
        mu_w,
    )?;
    Ok(Item {
        id: record.id.clone(),
        dir: files.dir,
        ct: files.ct,
        projections: files.projections,
        rows: files.rows,
        cols: files.cols,
        geometry: files.geometry,
        poses: files.poses,
        views: files.views,
        window: record.hu_window,
        scale,
        acquisition,
    })
}

/// Loads every item of a data set folder listed in its `manifest.jsonl` (optionally only
/// those of `split`); errors if none is found.
pub fn load_dataset(dir: &Path, split: Option<&str>) -> Result<Vec<Item>> {
    let items = item::read_manifest(dir, split)?
        .iter()
        .map(|r| load_item(&dir.join(&r.id)))
        .collect::<Result<Vec<_>>>()?;
    ensure!(
        !items.is_empty(),
        "{}: no items{}",
        dir.join(item::MANIFEST).display(),
        split
            .map(|s| format!(" in split '{s}'"))
            .unwrap_or_default()
    );
    Ok(items)
}
