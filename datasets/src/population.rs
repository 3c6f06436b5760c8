//! What a data set's CTs look like, coarsely, so that an input far from a model's training
//! population is named before anyone trusts its reconstruction.
//!
//! Every item records the fraction of its grid inside the body and the body's tissue
//! fractions ([`crate::body`]). A data set's [`Population`] is their range over its items
//! (`population.json` beside `manifest.jsonl`; `tomograf train` copies it into the
//! checkpoint). [`Population::outliers`] names every figure of an item that lies more than
//! [`MARGIN`] outside the population's range.

use crate::atomic::write_json;
use crate::body::TISSUE_CLASSES;
use crate::error::{DatasetError, Result};
use crate::item::ItemRecord;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The file a data set or a checkpoint keeps its population in.
pub const POPULATION_JSON: &str = "population.json";

/// How far (absolute, as a fraction: 0.10 = 10 points) outside the population's range a
/// figure must lie to be named.
pub const MARGIN: f64 = 0.10;

/// The range of each figure over a data set's items.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Population {
    /// Items summarised.
    pub items: usize,
    /// Smallest and largest fraction of the grid inside the body.
    pub body_fraction: [f64; 2],
    /// Smallest and largest fraction of the body in each tissue class
    /// ([`crate::body::TISSUE_CLASSES`]).
    pub tissue_fractions: [[f64; 2]; 4],
}

impl Population {
    /// The range over the records that hold the figures; `None` when none does (items made
    /// before they were recorded).
    pub fn of(records: &[ItemRecord]) -> Option<Self> {
        let mut out: Option<Self> = None;
        for r in records {
            let (Some(b), Some(t)) = (r.body_fraction, r.tissue_fractions) else {
                continue;
            };
            let p = out.get_or_insert(Self {
                items: 0,
                body_fraction: [b, b],
                tissue_fractions: t.map(|f| [f, f]),
            });
            p.items += 1;
            p.body_fraction = [p.body_fraction[0].min(b), p.body_fraction[1].max(b)];
            for (range, f) in p.tissue_fractions.iter_mut().zip(t) {
                *range = [range[0].min(f), range[1].max(f)];
            }
        }
        out
    }

    /// Writes `population.json` into `dir` (atomically).
    pub fn write(&self, dir: &Path) -> Result<()> {
        let value = serde_json::to_value(self)
            .map_err(|e| DatasetError::Invalid(format!("population: {e}")))?;
        write_json(&dir.join(POPULATION_JSON), &value)
    }

    /// `dir`'s `population.json`, `None` if it has none; errors name a corrupt file.
    pub fn read(dir: &Path) -> Result<Option<Self>> {
        let path = dir.join(POPULATION_JSON);
        let Ok(bytes) = std::fs::read(&path) else {
            return Ok(None);
        };
        serde_json::from_slice(&bytes)
            .map(Some)
            .map_err(|e| DatasetError::corrupt(&path, format!("not a population summary: {e}")))
    }

    /// Each of the record's figures that lies more than [`MARGIN`] outside this
    /// population's range, in words with the numbers; empty when all are within (or the
    /// record holds none).
    pub fn outliers(&self, record: &ItemRecord) -> Vec<String> {
        let mut out = Vec::new();
        let mut check = |what: &str, value: f64, [lo, hi]: [f64; 2]| {
            if value < lo - MARGIN || value > hi + MARGIN {
                out.push(format!(
                    "{what} {:.1} % lies outside the training population's {:.1}–{:.1} % by more \
                     than {:.0} points",
                    100.0 * value,
                    100.0 * lo,
                    100.0 * hi,
                    100.0 * MARGIN
                ));
            }
        };
        if let Some(b) = record.body_fraction {
            check("body fraction of the grid", b, self.body_fraction);
        }
        if let Some(t) = record.tissue_fractions {
            for ((name, _, _), (f, range)) in TISSUE_CLASSES
                .iter()
                .zip(t.iter().zip(self.tissue_fractions))
            {
                check(&format!("{name} fraction of the body"), *f, range);
            }
        }
        out
    }
}
