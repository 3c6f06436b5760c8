//! The report's example figures: the evaluations' slices and line profiles of the first test
//! item.

use super::super::render::Block;
use super::super::{Kind, Study, relative};

/// The evaluations' example figures of the first test item.
pub(super) fn examples(study: &Study, id: &str) -> Vec<Block> {
    let s = &study.settings;
    let mut b = vec![Block::Heading(format!("Example: test item {id}"))];
    let last = s.test_sets.last().map(String::as_str).unwrap_or_default();
    let mut cells: Vec<(String, Option<&str>, usize)> = Vec::new();
    match s.kind {
        Kind::RealismGap => {
            for t in s
                .train_sets
                .iter()
                .filter(|t| *t == &s.train_sets[0] || *t == last)
            {
                cells.push((last.into(), Some(t), 1));
            }
            cells.push((last.into(), None, 1));
            cells.push((last.into(), None, 10));
        }
        Kind::DomainShift => {
            for t in &s.test_sets {
                cells.push((t.clone(), Some(s.train_sets[0].as_str()), 1));
            }
        }
    }
    for (test, train, v) in cells {
        let dir = study.eval_dir(&test, train);
        let slices = dir.join(format!("{id}_{v}view_slices.png"));
        if !slices.exists() {
            continue;
        }
        let (what, cols, lines) = match train {
            Some(t) => (
                format!("TomoGRAF trained on `{t}`"),
                "truth, TomoGRAF, mean training volume, |TomoGRAF − truth| × 4",
                "blue = truth, red = TomoGRAF, green = mean volume",
            ),
            None => (
                "FDK and SART-TV".to_string(),
                "truth, FDK, SART-TV, |FDK − truth| × 4",
                "blue = truth, red = FDK, green = SART-TV",
            ),
        };
        b.push(Block::Image(
            relative(&study.dir, &slices),
            format!(
                "{what}, tested on `{test}`, {v} view(s). Rows: axial, coronal, sagittal \
                 mid-slices; columns: {cols}; window [0, 1] of the normalised CT."
            ),
        ));
        b.push(Block::Image(
            relative(&study.dir, &dir.join(format!("{id}_{v}view_profile.png"))),
            format!("Line profile through the centre of the axial slice: {lines}."),
        ));
    }
    b
}
