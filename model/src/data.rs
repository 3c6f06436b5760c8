//! Reading a data set made by `tomograf dataset`: `manifest.jsonl`, and per item
//! `item.json`, `views.json` (geometry), `projections.npy` (line integrals, views × rows ×
//! cols) and `ct.nii.gz` (the CT normalised to [0, 1] over the item's HU window).

use crate::error::{ModelError, Result, ensure};
use crate::render::DensityScale;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use tomograf_datasets::preprocess::HuWindow;
use tomograf_sim::acquisition::Acquisition;
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

#[derive(Deserialize)]
struct ItemJson {
    id: String,
    hu_window: HuWindow,
    energy_kev: f64,
    ct: String,
    projections: String,
    views: String,
    #[serde(default)]
    acquisition: Option<AcquisitionJson>,
}

/// `item.json`'s `acquisition`: the settings and the noise seed.
#[derive(Deserialize)]
struct AcquisitionJson {
    settings: Acquisition,
}

#[derive(Deserialize)]
struct ViewsJson {
    geometry: Option<Geometry>,
    poses: Option<Vec<Pose>>,
    views: Option<Vec<View>>,
}

fn read(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| ModelError::file(path, e))
}

/// Loads one item folder.
pub fn load_item(dir: &Path) -> Result<Item> {
    let ij = dir.join("item.json");
    let item: ItemJson =
        serde_json::from_slice(&read(&ij)?).map_err(|e| ModelError::file(&ij, e))?;
    let vp = dir.join(&item.views);
    let vj: ViewsJson =
        serde_json::from_slice(&read(&vp)?).map_err(|e| ModelError::file(&vp, e))?;
    let (Some(geometry), Some(poses), Some(views)) = (vj.geometry, vj.poses, vj.views) else {
        return Err(ModelError::file(
            &vp,
            "geometry missing: views.json needs 'geometry', 'poses' and 'views'",
        ));
    };
    geometry.validate()?;
    let pp = dir.join(&item.projections);
    let bytes = read(&pp)?;
    let npy = npyz::NpyFile::new(&bytes[..]).map_err(|e| ModelError::file(&pp, e))?;
    let shape: Vec<u64> = npy.shape().to_vec();
    let projections: Vec<f32> = npy.into_vec().map_err(|e| ModelError::file(&pp, e))?;
    let [nv, rows, cols] = shape[..] else {
        return Err(ModelError::file(
            &pp,
            format!("expected views × rows × cols, found shape {shape:?}"),
        ));
    };
    let (nv, rows, cols) = (nv as usize, rows as usize, cols as usize);
    ensure!(nv > 0, "{}: no projections (view count 0)", pp.display());
    ensure!(
        views.len() == nv && poses.len() == nv,
        "{}: {} projections but {} views and {} poses in {}",
        pp.display(),
        nv,
        views.len(),
        poses.len(),
        vp.display()
    );
    for v in &views {
        v.validate()?;
        ensure!(
            v.rows == rows && v.cols == cols,
            "{}: projections are {rows}×{cols} but a view's detector is {}×{}",
            dir.display(),
            v.rows,
            v.cols
        );
    }
    if let Some(i) = projections.iter().position(|x| !x.is_finite()) {
        return Err(ModelError::file(&pp, format!("value {i} is not finite")));
    }
    let cp = dir.join(&item.ct);
    let ct = if cp.exists() {
        Some(tomograf_datasets::nifti::read_nifti(&cp).map_err(|e| ModelError::file(&cp, e))?)
    } else {
        None
    };
    let mu_w = mu_water_per_mm(item.energy_kev)?;
    let scale = DensityScale::from_window(
        f64::from(item.hu_window.lo),
        f64::from(item.hu_window.hi),
        mu_w,
    )?;
    Ok(Item {
        id: item.id,
        dir: dir.to_path_buf(),
        ct,
        projections,
        rows,
        cols,
        geometry,
        poses,
        views,
        window: item.hu_window,
        scale,
        acquisition: item.acquisition.map(|a| a.settings),
    })
}

#[derive(Deserialize)]
struct ManifestLine {
    id: String,
    split: String,
}

/// Loads every item of a data set folder listed in its `manifest.jsonl` (optionally only
/// those of `split`); errors if none is found.
pub fn load_dataset(dir: &Path, split: Option<&str>) -> Result<Vec<Item>> {
    let mp = dir.join("manifest.jsonl");
    let text = String::from_utf8(read(&mp)?).map_err(|e| ModelError::file(&mp, e))?;
    let mut items = Vec::new();
    for (n, line) in text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
    {
        let m: ManifestLine = serde_json::from_str(line)
            .map_err(|e| ModelError::file(&mp, format!("line {}: {e}", n + 1)))?;
        if split.is_some_and(|s| s != m.split) {
            continue;
        }
        items.push(load_item(&dir.join(&m.id))?);
    }
    ensure!(
        !items.is_empty(),
        "{}: no items{}",
        mp.display(),
        split
            .map(|s| format!(" in split '{s}'"))
            .unwrap_or_default()
    );
    Ok(items)
}
