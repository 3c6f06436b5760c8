//! # tomograf-sim — X-ray projection physics
//!
//! Data flows one way: a [`volume::Volume`] in the LPS world frame (HU or mm⁻¹) →
//! [`attenuation`] (HU → mu, mm⁻¹) → [`geometry`] (set-up and pose → [`geometry::View`]) →
//! [`ray::Ray`] per pixel → a tracer in [`trace`] (exact Siddon or trilinear marching)
//! reporting path lengths to an accumulator → [`render::Projection`] (line integral,
//! transmission or intensity).
//!
//! Units: lengths in mm, attenuation in mm⁻¹, energies in keV, CT values in HU, angles in
//! degrees. World frame: DICOM LPS (+x patient left, +y posterior, +z head).

pub mod accel;
pub mod attenuation;
pub mod composition;
pub mod error;
pub mod geometry;
pub mod grid_box;
pub mod material;
pub mod memory;
pub mod mesh;
pub mod occupancy;
pub mod phantom;
pub mod ray;
pub mod render;
pub mod seed;
pub mod solid;
pub mod tissue;
pub mod trace;
pub mod volume;

pub use error::{Result, SimError};
pub use geometry::{Beam, Detector, Geometry, Pose, View, ViewBeam};
pub use ray::{GridRay, Ray};
pub use render::{
    LineIntegrals, MassThicknesses, Projection, Projector, Quantity, Renderer, Tracer,
};
pub use volume::Volume;
