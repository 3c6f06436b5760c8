//! Paired differences between two methods' scores on the same test items, with the 95 %
//! t-interval of their mean: whether a difference the report shows is resolved.

use statrs::distribution::{ContinuousCDF, StudentsT};

/// The mean of the per-item differences a − b and its 95 % t-interval half-width.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Paired {
    /// Mean difference.
    pub mean: f64,
    /// Half-width of the 95 % t-interval (`None` with one item: no interval).
    pub half_width: Option<f64>,
    /// Items paired.
    pub n: usize,
}

impl Paired {
    /// The difference of `a` and `b` (item id, score) over the items both have; `None` when
    /// they share none.
    pub fn of(a: &[(String, f64)], b: &[(String, f64)]) -> Option<Self> {
        let d: Vec<f64> = a
            .iter()
            .filter_map(|(id, x)| b.iter().find(|(j, _)| j == id).map(|(_, y)| x - y))
            .filter(|d| d.is_finite())
            .collect();
        Self::of_differences(&d)
    }

    /// From the per-item differences.
    pub fn of_differences(d: &[f64]) -> Option<Self> {
        let n = d.len();
        if n == 0 {
            return None;
        }
        let mean = d.iter().sum::<f64>() / n as f64;
        let half_width = (n > 1).then(|| {
            let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
            let t = StudentsT::new(0.0, 1.0, (n - 1) as f64)
                .map(|t| t.inverse_cdf(0.975))
                .unwrap_or(f64::INFINITY);
            t * (var / n as f64).sqrt()
        });
        Some(Self {
            mean,
            half_width,
            n,
        })
    }

    /// Whether the interval excludes zero.
    pub fn resolved(&self) -> bool {
        self.half_width.is_some_and(|h| self.mean.abs() > h)
    }

    /// "+0.52 ± 0.31", bold when resolved; "+0.52 (n = 1)" without an interval.
    pub fn format(&self, digits: usize) -> String {
        match self.half_width {
            Some(h) if self.resolved() => format!("**{:+.digits$} ± {h:.digits$}**", self.mean),
            Some(h) => format!("{:+.digits$} ± {h:.digits$}", self.mean),
            None => format!("{:+.digits$} (n = 1)", self.mean),
        }
    }
}

/// One score of one method on one item: (views, method, item, score).
pub type Score<'a> = (usize, &'a str, &'a str, f64);

/// A markdown table of `reference` minus every other method, paired over the items both
/// scored, per view count: one column per named score in `scores` (each a list of
/// [`Score`]s), each cell "mean ± 95 % half-width", bold where the interval excludes zero.
/// `None` when fewer than two items were scored (no interval to give).
pub fn table(reference: &str, scores: &[(&str, Vec<Score>)], digits: &[usize]) -> Option<String> {
    let first = &scores.first()?.1;
    let items: std::collections::BTreeSet<&str> = first.iter().map(|s| s.2).collect();
    if items.len() < 2 || !first.iter().any(|s| s.1 == reference) {
        return None;
    }
    let mut keys: Vec<(usize, &str)> = Vec::new();
    for s in first {
        if s.1 != reference && !keys.contains(&(s.0, s.1)) {
            keys.push((s.0, s.1));
        }
    }
    let mut md = format!("| views | {reference} − | ");
    md.push_str(
        &scores
            .iter()
            .map(|(n, _)| *n)
            .collect::<Vec<_>>()
            .join(" | "),
    );
    md.push_str(" | items |\n|---:|---|");
    md.push_str(&"---:|".repeat(scores.len()));
    md.push_str("---:|\n");
    for (views, method) in keys {
        let mut n = 0;
        let cells: Vec<String> = scores
            .iter()
            .zip(digits)
            .map(|((_, s), d)| {
                let of = |m: &str| -> Vec<(String, f64)> {
                    s.iter()
                        .filter(|x| x.0 == views && x.1 == m)
                        .map(|x| (x.2.to_string(), x.3))
                        .collect()
                };
                match Paired::of(&of(reference), &of(method)) {
                    Some(p) => {
                        n = p.n;
                        p.format(*d)
                    }
                    None => "—".into(),
                }
            })
            .collect();
        md.push_str(&format!(
            "| {views} | {method} | {} | {n} |\n",
            cells.join(" | ")
        ));
    }
    Some(md)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two items, three methods: the reference minus each other method per view count,
    /// in the order the methods first appear; the differences by hand.
    #[test]
    fn the_table_pairs_the_reference_with_every_other_method() {
        let psnr: Vec<Score> = vec![
            (1, "A", "0", 20.0),
            (1, "B", "0", 19.0),
            (1, "C", "0", 21.0),
            (1, "A", "1", 22.0),
            (1, "B", "1", 20.0),
            (1, "C", "1", 22.5),
        ];
        let t = table("A", &[("PSNR (dB)", psnr.clone())], &[2]).unwrap();
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines[0], "| views | A − | PSNR (dB) | items |");
        // B: differences 1 and 2 (mean 1.5, s = 0.7071, t(0.975, 1) = 12.7062): ± 6.35.
        assert_eq!(lines[2], "| 1 | B | +1.50 ± 6.35 | 2 |");
        // C: differences −1 and −0.5.
        assert_eq!(lines[3], "| 1 | C | -0.75 ± 3.18 | 2 |");
        assert_eq!(lines.len(), 4);
        // One item: no table.
        let one: Vec<Score> = psnr.iter().filter(|s| s.2 == "0").cloned().collect();
        assert!(table("A", &[("PSNR (dB)", one)], &[2]).is_none());
    }

    /// Against a hand computation: differences 1, 2, 3 (mean 2, s = 1, n = 3) and
    /// t(0.975, 2 df) = 4.302653 (published tables: 4.303), so the half-width is
    /// 4.302653/√3 = 2.484138; resolved (2 > 2.48 is false): not resolved.
    #[test]
    fn interval_matches_the_t_table() {
        let p = Paired::of_differences(&[1.0, 2.0, 3.0]).unwrap();
        assert!((p.mean - 2.0).abs() < 1e-12);
        assert!((p.half_width.unwrap() - 2.484_138).abs() < 1e-5, "{p:?}");
        assert!(!p.resolved());
        // Ten items, differences 1 ± 0.1: resolved.
        let d: Vec<f64> = (0..10).map(|i| 1.0 + 0.1 * (i % 2) as f64).collect();
        assert!(Paired::of_differences(&d).unwrap().resolved());
        assert_eq!(Paired::of_differences(&[0.5]).unwrap().half_width, None);
        assert!(Paired::of_differences(&[]).is_none());
    }

    /// Items are paired by id, in any order; unshared items are left out.
    #[test]
    fn pairs_by_item() {
        let a = vec![
            ("1".to_string(), 10.0),
            ("0".to_string(), 5.0),
            ("9".into(), 0.0),
        ];
        let b = vec![("0".to_string(), 4.0), ("1".to_string(), 8.0)];
        let p = Paired::of(&a, &b).unwrap();
        assert_eq!(p.n, 2);
        assert!((p.mean - 1.5).abs() < 1e-12);
    }
}
