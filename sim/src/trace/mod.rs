//! Ray tracers: how a ray's path through the voxel grid is turned into numbers.
//!
//! * [`siddon`] — exact: visits every voxel the ray crosses with the exact length of the
//!   crossing, and hands `(voxel, length)` pairs to a [`PathAccumulator`].
//! * [`trilinear`] — ray marching through the trilinearly interpolated field.
//! * [`packet`] and [`sheet`] — exact, as [`siddon`], for groups of rays at once: SIMD
//!   packets of neighbouring rays, and whole detector rows whose rays share one path in
//!   the plane of two grid axes (AP and lateral views).
//!
//! Both take a [`crate::ray::GridRay`] (a world ray already clipped to the grid), so the
//! geometry is decided once, in one place, for every tracer.

pub mod accumulate;
#[cfg(target_arch = "x86_64")]
#[macro_use]
mod lanes;
pub mod packet;
pub mod sheet;
pub mod siddon;
pub mod trilinear;

pub use accumulate::{LineIntegral, MaterialPaths, PathAccumulator};
