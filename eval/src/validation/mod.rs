//! Validation of the physics against published reference results.
//!
//! * [`reference`] — the AAPM TG-195 tables shipped in `eval/data/tg195/`;
//! * [`tg195`] — the TG-195 cases as scenes, run and set beside the four codes;
//! * [`tg195_case3`] — its Case 3, mammography and breast tomosynthesis;
//! * [`matched`] — the scatter Monte Carlo's matched-physics mode (monoenergetic, constant
//!   albedo, isotropic or Henyey–Greenstein phase, homogeneous box) for the cross-check with
//!   Mitsuba 3 (bridge/tests/test_scatter_mitsuba.py).

pub mod matched;
pub mod reference;
pub mod tg195;
pub mod tg195_case3;

#[cfg(test)]
mod tests;
