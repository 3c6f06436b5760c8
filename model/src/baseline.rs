//! Baselines evaluated from the same views as the model: the mean training volume
//! (here) and analytic reconstructions such as FDK (plugged in through [`Baseline`]).

use crate::error::{Result, ensure};
use crate::reconstruct::Reference;
use crate::render::DensityScale;
use tomograf_sim::Volume;

/// A reconstruction method to compare with.
pub trait Baseline {
    /// Name for tables.
    fn name(&self) -> &str;
    /// The normalised density on `grid`'s geometry from `refs` (line integrals;
    /// `scale` maps normalised density to mu).
    fn reconstruct(
        &self,
        refs: &[Reference],
        grid: &Volume,
        scale: &DensityScale,
    ) -> Result<Volume>;
}

/// The voxel-wise mean of the training CTs (normalised, on their common `n³` grid): it
/// ignores the views.
#[derive(Debug, Clone)]
pub struct MeanVolume {
    /// Voxel values, `i` fastest.
    pub data: Vec<f32>,
    /// Grid size.
    pub dims: [usize; 3],
}

impl MeanVolume {
    /// The mean of `volumes`; errors unless they share one grid size.
    pub fn from_volumes<'a>(volumes: impl IntoIterator<Item = &'a Volume>) -> Result<Self> {
        let mut sum: Vec<f64> = Vec::new();
        let mut dims = [0; 3];
        let mut n = 0usize;
        for v in volumes {
            if n == 0 {
                dims = v.dims();
                sum = vec![0.0; v.len()];
            }
            ensure!(
                v.dims() == dims,
                "training volumes differ in size ({:?} and {:?}); the mean needs one grid",
                dims,
                v.dims()
            );
            for (s, &x) in sum.iter_mut().zip(v.data()) {
                *s += f64::from(x);
            }
            n += 1;
        }
        ensure!(n > 0, "no training volumes for the mean");
        Ok(Self {
            data: sum.iter().map(|s| (s / n as f64) as f32).collect(),
            dims,
        })
    }
}

impl Baseline for MeanVolume {
    fn name(&self) -> &str {
        "mean training volume"
    }

    fn reconstruct(&self, _: &[Reference], grid: &Volume, _: &DensityScale) -> Result<Volume> {
        ensure!(
            grid.dims() == self.dims,
            "mean volume is {:?} but the test grid is {:?}",
            self.dims,
            grid.dims()
        );
        Ok(Volume::new(
            self.dims,
            grid.spacing(),
            grid.origin(),
            grid.direction(),
            self.data.clone(),
        )?)
    }
}
