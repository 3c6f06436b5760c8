//! What the projector examples share: the median of timings (the benchmarks' own), and the
//! CT path and a count from the command line.

pub use tomograf_bench::model::median;

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
