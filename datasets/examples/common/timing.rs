//! What the examples share (datasets' loading examples and bench's projector examples, which
//! include this file by path): the median of timings, and the CT path and a count
//! from the command line.

/// The median of `v` (the upper one of an even count).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The first argument (a CT file), or exit with `usage`; and the second parsed as `T`, or
/// `default`.
pub fn args<T: std::str::FromStr>(usage: &str, default: T) -> (String, T) {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| panic!("usage: {usage}"));
    let second = std::env::args().nth(2).map_or(default, |s| {
        s.parse()
            .unwrap_or_else(|_| panic!("usage: {usage} (second argument: {s})"))
    });
    (path, second)
}
