//! What a study report averages over: per test set, the items every cell of that set has
//! scored. Test sets may hold different items (8 phantoms beside the user's 2 CTs), and a
//! partial report (a sharded evaluation that ran only some shards) averages every cell of a
//! set over the same items and says which.

use super::Study;
use super::render::Block;
use crate::evaluation::Row;
use std::collections::BTreeSet;

/// A cell's scores: (test set, training set or `None` for the classical baselines, rows).
pub type Cell<'a> = (String, Option<&'a str>, Vec<Row>);

/// Which items each test set's cells average, and what was left out.
pub struct Coverage {
    /// Per test set, the items every non-empty cell of it has scored: its cells average
    /// these.
    common: Vec<(String, Vec<String>)>,
    /// Per test set, items some cells have scored and others not (not averaged anywhere).
    left_out: Vec<(String, Vec<String>)>,
    /// (test set, cell) with nothing scored yet.
    unscored: Vec<(String, String)>,
}

impl Coverage {
    /// The coverage of `cells`, and the cells with only the rows of their set's common
    /// items (empty cells dropped).
    pub fn of(cells: Vec<Cell<'_>>) -> (Self, Vec<Cell<'_>>) {
        let mut common: Vec<(String, BTreeSet<String>)> = Vec::new();
        for (test, _, rows) in cells.iter().filter(|c| !c.2.is_empty()) {
            let items: BTreeSet<String> = rows.iter().map(|r| r.item.clone()).collect();
            match common.iter_mut().find(|(t, _)| t == test) {
                Some((_, c)) => *c = c.intersection(&items).cloned().collect(),
                None => common.push((test.clone(), items)),
            }
        }
        let mut unscored = Vec::new();
        let mut left_out: Vec<(String, BTreeSet<String>)> = Vec::new();
        let mut kept_cells = Vec::new();
        for (test, train, rows) in cells {
            if rows.is_empty() {
                unscored.push((test, cell_name(train)));
                continue;
            }
            let keep = common
                .iter()
                .find(|(t, _)| *t == test)
                .map(|(_, c)| c.clone())
                .unwrap_or_default();
            let (kept, other): (Vec<Row>, Vec<Row>) =
                rows.into_iter().partition(|r| keep.contains(&r.item));
            let other: BTreeSet<String> = other.into_iter().map(|r| r.item).collect();
            if !other.is_empty() {
                match left_out.iter_mut().find(|(t, _)| *t == test) {
                    Some((_, l)) => l.extend(other),
                    None => left_out.push((test.clone(), other)),
                }
            }
            kept_cells.push((test, train, kept));
        }
        let list = |v: Vec<(String, BTreeSet<String>)>| -> Vec<(String, Vec<String>)> {
            v.into_iter()
                .map(|(t, c)| (t, c.into_iter().collect()))
                .collect()
        };
        (
            Self {
                common: list(common),
                left_out: list(left_out),
                unscored,
            },
            kept_cells,
        )
    }

    /// The first item of the first test set (in `order`) that has any: the report's
    /// example.
    pub fn first_item(&self, order: &[String]) -> Option<String> {
        order.iter().find_map(|t| {
            self.common
                .iter()
                .find(|(n, _)| n == t)
                .and_then(|(_, c)| c.first().cloned())
        })
    }

    /// The paragraph of a partial report (`None` when every cell has every item).
    pub fn paragraph(&self, study: &Study) -> Option<Block> {
        let short: Vec<String> = study
            .settings
            .test_sets
            .iter()
            .filter_map(|t| {
                let want = study.test_items(t);
                let have = self
                    .common
                    .iter()
                    .find(|(n, _)| n == t)
                    .map_or(&[][..], |(_, c)| c.as_slice());
                (have.len() != want).then(|| {
                    let which = if have.is_empty() {
                        String::new()
                    } else {
                        format!(" ({})", have.join(", "))
                    };
                    format!(
                        "`{t}` averages {} of its {want} test items{which}",
                        have.len()
                    )
                })
            })
            .collect();
        if short.is_empty() && self.unscored.is_empty() {
            return None;
        }
        let mut text = String::from(
            "**Partial evaluation**: every cell of a test set averages the items scored in \
             every cell of that set that has any.",
        );
        if !short.is_empty() {
            text += &format!(" {}.", short.join("; "));
        }
        if !self.left_out.is_empty() {
            let l: Vec<String> = self
                .left_out
                .iter()
                .map(|(t, items)| format!("`{t}`: {}", items.join(", ")))
                .collect();
            text += &format!(" Left out, scored in some cells only: {}.", l.join("; "));
        }
        if !self.unscored.is_empty() {
            let cells: Vec<String> = self
                .unscored
                .iter()
                .map(|(t, w)| format!("`{t}` × {w}"))
                .collect();
            text += &format!(
                " Nothing scored yet (\"—\" in the tables): {}.",
                cells.join("; ")
            );
        }
        text += " Run the evaluate stage on the remaining shards to complete it.";
        Some(Block::Para(text))
    }
}

/// How a cell is named in the report: its model, or the classical baselines.
fn cell_name(train: Option<&str>) -> String {
    train.map_or_else(|| "classical baselines".into(), |t| format!("model `{t}`"))
}
