//! # tomograf-model — TomoGRAF on burn
//!
//! An X-ray-aware conditional radiance field (the TomoGRAF paper, Methods 1.2–1.4) that
//! learns a prior over chest CTs from simulated projections and reconstructs a CT from
//! one to ten views by fine-tuning its codes (and, by default, the generator).
//!
//! Conventions are sim's (`tomograf_sim`): world frame DICOM LPS in mm, views from
//! [`tomograf_sim::Geometry`] and [`tomograf_sim::Pose`], pixel (0, 0) top-left in the
//! beam's-eye view, line integrals ∫mu ds with mu in mm⁻¹. The field predicts a
//! **normalised density** δ ≥ 0 (the data set's HU window mapped to [0, 1]);
//! [`render::DensityScale`] turns it into mu exactly as sim does (HU → mu at the data set's
//! effective energy), so rendered patches are comparable with the data set's projections.
//!
//! * [`rays`] — ray sampling: patches at continuous pixel coordinates, Q stratified samples.
//! * [`field`] — positional encoding and the conditional radiance field: a residual
//!   g(γ(x), z_sh, z_a) on the mean training volume (or the paper's ξ-dependent softplus form).
//! * [`prior`] — the mean training volume and the training codes' statistics.
//! * [`render`] — the differentiable line integral.
//! * [`trilinear`] — trilinear sampling of a volume tensor (built from `gather`).
//! * [`discriminator`], [`losses`], [`augment`] — D1 (3D) and D2 (2D), eqs. 7–12, DAG.
//! * [`train`], [`checkpoint`], [`reconstruct`], [`metrics`], [`data`].
//! * [`scatter_correction`] — an item's views corrected for scatter from a prior estimate.
//! * [`baseline`], [`pca`] — what the model is compared with: the mean volume, SART-TV from
//!   zero or from the mean, FDK, and the PCA-MAP linear prior of the training volumes.

pub mod augment;
pub mod backend;
pub mod baseline;
pub mod checkpoint;
pub mod config;
pub mod data;
pub mod discriminator;
pub mod ensemble;
pub mod error;
pub mod field;
pub mod fit;
pub mod held_out;
pub mod infer_config;
pub mod losses;
pub mod metrics;
pub mod pca;
pub mod prior;
pub mod rays;
pub mod reconstruct;
pub mod reference;
pub mod refine;
pub mod render;
pub mod scatter_correction;
pub mod train;
pub mod trilinear;

pub use burn::tensor::Device;
pub use error::{ModelError, Result};
