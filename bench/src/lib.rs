//! The measurements behind `tomograf bench`, as library code (the command line only parses
//! its flags and prints what these return).
//!
//! Every section returns markdown, and every speed in it is a ratio or a time measured
//! against a baseline in the same run (interleaved where the section says so), since
//! timings on shared machines swing by ±25 %:
//! * [`projector`]: exact Siddon throughput, the chest-sized case, trilinear against exact
//!   (docs/benchmarks.md);
//! * [`accel`]: empty-space skipping and meshes (docs/benchmarks.md, docs/meshes.md);
//! * [`physics`]: the polychromatic chain and detector (docs/physics-benchmarks.md);
//! * [`model`]: TomoGRAF's training and inference iterations (docs/model-benchmarks.md);
//! * [`backend`]: a GPU backend against `flex` (docs/gpu-benchmarks.md);
//! * [`scatter`]: the scatter engine's speed against its error on a CT (docs/scatter.md).

pub mod accel;
pub mod backend;
pub mod fixtures;
pub mod model;
pub mod physics;
pub mod projector;
pub mod scatter;

/// How much to measure.
#[derive(Debug, Clone, Copy)]
pub struct Options {
    /// Small sizes only (a smoke test that runs in seconds).
    pub quick: bool,
    /// Renders (or iterations) per measurement; the median is reported.
    pub repeats: usize,
}

/// The CPU's model name from /proc/cpuinfo ("unknown CPU" elsewhere).
pub fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into())
}
