//! Validation of the physics against published reference results.
//!
//! * [`reference`] — the AAPM TG-195 tables shipped in `sim/data/tg195/`;
//! * [`tg195`] — the TG-195 cases as scenes, run and set beside the four codes.

pub mod reference;
pub mod tg195;
