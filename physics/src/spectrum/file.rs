//! User spectrum files, as other tools write them: two columns, photon energy (keV) and the
//! fluence of that bin, in the unit a [`FluenceUnit`] names (tomograf's own: photons per mAs
//! per mm² at 1 m from the focal spot, per bin).
//!
//! * Columns may be separated by a comma, a tab, a semicolon or spaces; `#` and `%` start a
//!   comment.
//! * Header lines (lines before the first data row that do not start with a number, as
//!   SpekPy's export writes) are skipped.
//! * A first data row holding one integer is a bin count (XCIST's `.dat` files); the number of
//!   rows that follow must equal it.
//! * Rows outside 1–500 keV (the attenuation tables) are dropped when their fluence is 0
//!   (tables that start at 0 or 0.5 keV); a row outside the range with photons is an error.
//! * Energies strictly increase (any bin width, e.g. 0.5 keV); fluences are finite and ≥ 0
//!   with a positive total. Every error names the line.

use serde::{Deserialize, Serialize};
use tomograf_sim::error::{Result, SimError};

/// The unit of a spectrum file's fluence column (a scene's `[spectrum] fluence_unit`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FluenceUnit {
    /// Photons per mAs per mm² at 1 m in each bin (tomograf's unit; the default).
    #[default]
    PerMm2,
    /// Photons per mAs per cm² at 1 m in each bin.
    PerCm2,
    /// Photons per mAs per mm² per keV at 1 m (a density: times each bin's width).
    PerMm2PerKev,
    /// Photons per mAs per cm² per keV at 1 m (SpekPy's `export_spectrum` unit, TASMIP's
    /// tables per mm² use `per-mm2-per-kev`).
    PerCm2PerKev,
}

impl FluenceUnit {
    /// Every unit's name, as a scene writes it.
    pub const NAMES: &[&str] = &["per-mm2", "per-cm2", "per-mm2-per-kev", "per-cm2-per-kev"];

    /// Photons per mAs per mm² at 1 m in each bin from the column's values at `energies`
    /// (keV, strictly increasing). A density's bin width is the distance between the
    /// neighbouring bins' midpoints (the spacing itself for uniform bins; one-sided at the
    /// ends; 1 keV for a single line).
    pub fn to_per_mm2_per_bin(self, energies: &[f64], values: &[f64]) -> Vec<f64> {
        let area = match self {
            Self::PerMm2 | Self::PerMm2PerKev => 1.0,
            Self::PerCm2 | Self::PerCm2PerKev => 0.01,
        };
        let density = matches!(self, Self::PerMm2PerKev | Self::PerCm2PerKev);
        let n = energies.len();
        (0..n)
            .map(|i| {
                let width = if !density || n == 1 {
                    1.0
                } else {
                    let lo = if i == 0 {
                        energies[0] - 0.5 * (energies[1] - energies[0])
                    } else {
                        0.5 * (energies[i - 1] + energies[i])
                    };
                    let hi = if i == n - 1 {
                        energies[i] + 0.5 * (energies[i] - energies[i - 1])
                    } else {
                        0.5 * (energies[i] + energies[i + 1])
                    };
                    hi - lo
                };
                values[i] * area * width
            })
            .collect()
    }
}

/// Parses spectrum text; `source` names the file in error messages. Returns the energies
/// (keV) and the fluence column as written (convert with [`FluenceUnit`]).
pub(super) fn parse(text: &str, source: &str) -> Result<(Vec<f64>, Vec<f64>)> {
    let bad = |line: usize, msg: String| {
        SimError::InvalidSpectrum(format!("{source} line {line}: {msg}"))
    };
    let (mut energies, mut fluence) = (Vec::new(), Vec::new());
    let mut data_started = false;
    let mut count: Option<(usize, usize)> = None; // (declared rows, line)
    let mut rows = 0usize;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let l = raw.split(['#', '%']).next().unwrap_or("").trim();
        if l.is_empty() {
            continue;
        }
        let cols: Vec<&str> = l
            .split(|c: char| c == ',' || c == '\t' || c == ';' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .collect();
        if !data_started && cols.first().is_none_or(|c| c.parse::<f64>().is_err()) {
            continue; // a header line
        }
        if !data_started && cols.len() == 1 {
            data_started = true;
            let n = cols[0].parse::<usize>().map_err(|_| {
                bad(
                    line,
                    format!(
                        "a one-column first row must be the bin count (an integer), found '{}'",
                        cols[0]
                    ),
                )
            })?;
            count = Some((n, line));
            continue;
        }
        data_started = true;
        if cols.len() != 2 {
            return Err(bad(
                line,
                format!(
                    "expected 2 columns (keV, then the fluence of the bin), found {}",
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
        rows += 1;
        if e.is_finite() && !(1.0..=500.0).contains(&e) && f == 0.0 {
            if let Some(&p) = energies.last()
                && e <= p
            {
                return Err(bad(
                    line,
                    format!("energy {e} keV does not increase (energies must be sorted)"),
                ));
            }
            continue; // an empty bin outside the tables' range
        }
        check_bin(e, f, energies.last().copied()).map_err(|m| bad(line, m))?;
        energies.push(e);
        fluence.push(f);
    }
    if let Some((n, line)) = count
        && n != rows
    {
        return Err(bad(
            line,
            format!("the bin count says {n} rows but {rows} follow"),
        ));
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
