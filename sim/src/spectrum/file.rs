//! User spectrum files: two columns, photon energy (keV) and photons per mAs per mm² at 1 m
//! from the focal spot for that bin.
//!
//! Columns may be separated by a comma, a tab or spaces; `#` starts a comment; one header line
//! (a first data line that does not start with a number) is skipped. Energies must lie in
//! 1–500 keV (the attenuation tables) and strictly increase; fluences must be finite and ≥ 0
//! with a positive total. Every error names the line.

use crate::error::{Result, SimError};

/// Parses spectrum text; `source` names the file in error messages.
pub(super) fn parse(text: &str, source: &str) -> Result<(Vec<f64>, Vec<f64>)> {
    let bad = |line: usize, msg: String| {
        SimError::InvalidSpectrum(format!("{source} line {line}: {msg}"))
    };
    let (mut energies, mut fluence) = (Vec::new(), Vec::new());
    let mut first = true;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let l = raw.split('#').next().unwrap_or("").trim();
        if l.is_empty() {
            continue;
        }
        let cols: Vec<&str> = l
            .split(|c: char| c == ',' || c == '\t' || c == ';' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .collect();
        let is_header = first && cols.first().is_some_and(|c| c.parse::<f64>().is_err());
        first = false;
        if is_header {
            continue;
        }
        if cols.len() != 2 {
            return Err(bad(
                line,
                format!(
                    "expected 2 columns (keV, photons/mAs/mm² at 1 m), found {}",
                    cols.len()
                ),
            ));
        }
        let e: f64 = cols[0]
            .parse()
            .map_err(|_| bad(line, format!("energy '{}' is not a number", cols[0])))?;
        let f: f64 = cols[1]
            .parse()
            .map_err(|_| bad(line, format!("fluence '{}' is not a number", cols[1])))?;
        check_bin(e, f, energies.last().copied()).map_err(|m| bad(line, m))?;
        energies.push(e);
        fluence.push(f);
    }
    check_total(&fluence, source)?;
    Ok((energies, fluence))
}

/// Checks one bin against the rules above; `prev` is the previous bin's energy.
pub(super) fn check_bin(e: f64, f: f64, prev: Option<f64>) -> std::result::Result<(), String> {
    if !(e.is_finite() && (1.0..=500.0).contains(&e)) {
        return Err(format!("energy {e} keV is outside 1–500 keV"));
    }
    if !(f.is_finite() && f >= 0.0) {
        return Err(format!("fluence {f} must be a finite number ≥ 0"));
    }
    if prev.is_some_and(|p| e <= p) {
        return Err(format!(
            "energy {e} keV does not increase (energies must be sorted)"
        ));
    }
    Ok(())
}

/// Errors on an empty spectrum or one without photons.
pub(super) fn check_total(fluence: &[f64], source: &str) -> Result<()> {
    if fluence.is_empty() {
        return Err(SimError::InvalidSpectrum(format!("{source}: no data rows")));
    }
    if fluence.iter().sum::<f64>() <= 0.0 {
        return Err(SimError::InvalidSpectrum(format!(
            "{source}: total fluence is zero"
        )));
    }
    Ok(())
}
