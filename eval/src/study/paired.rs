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

#[cfg(test)]
mod tests {
    use super::*;

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
