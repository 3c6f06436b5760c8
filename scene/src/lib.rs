//! Scenes as data (Mitsuba 3's idea): what `tomograf project` renders — the volume, the
//! geometry and views, the projector, the detector physics (acquisition preset, spectrum,
//! materials, detector model, scatter), meshes, dose and outputs — as one [`Scene`],
//! loaded from TOML or built in code, and [`prepare`]d into something that renders view
//! `i`. The command line merges its flags into a `Scene`; the Python bridge builds the
//! same `Scene` from a TOML file, so both render the same bytes. docs/scene.md is the
//! reference of every key; units are mm, keV, mm⁻¹ and HU throughout.
//!
//! Data flows one way: scene → volume and views ([`volume`], [`job`]) → the physics the
//! scene asks for ([`physics`]) → [`prepare::SceneRenderer`] → images, written by [`project()`] ([`outputs`]). [`dataset`] makes
//! the model's training and test items (CT, projections, geometry) the same way.

pub mod dataset;
pub mod disk;
pub mod dose;
pub mod job;
pub mod outputs;
pub mod overrides;
pub mod peak;
pub mod phantom;
pub mod physics;
pub mod prepare;
pub mod progress;
pub mod project;
pub mod projections;
pub mod scatter;
pub mod scene;
pub mod volume;

pub use prepare::{Frame, Prepared, SceneRenderer, prepare, prepare_in_memory};
pub use progress::{Progress, Silent};
pub use project::project;
pub use scene::Scene;
