//! Validation of the physics against published reference results.
//!
//! * [`reference`] — the AAPM TG-195 tables shipped in `sim/data/tg195/`;
//! * [`tg195`] — the TG-195 cases as scenes, run and set beside the four codes;
//! * [`tg195_case3`] — its Case 3, mammography and breast tomosynthesis.

pub mod reference;
pub mod tg195;
pub mod tg195_case3;
