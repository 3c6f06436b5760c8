//! cargo-fuzz targets for tomograf's parsers: see [`targets`] and docs/reliability.md.

pub mod targets;
