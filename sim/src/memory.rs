//! How much memory this machine has, so that a size a user asks for (a volume's
//! dimensions, a reconstruction grid) is refused with a clear error before an allocation
//! that cannot succeed — rather than the process aborting with "memory allocation of N
//! bytes failed", or the kernel killing it mid-run.
//!
//! The limit is the machine's physical memory (`MemTotal` in `/proc/meminfo`), or
//! `TOMOGRAF_MEMORY_LIMIT_GB` when set (a job's own budget; tests use it to make the
//! check independent of the machine). Where neither is known, nothing is refused here.

use crate::error::{Result, SimError};

/// The memory one allocation may take, bytes (`None`: unknown, no limit).
pub fn limit_bytes() -> Option<u64> {
    if let Some(gb) = std::env::var("TOMOGRAF_MEMORY_LIMIT_GB")
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
        .filter(|g| g.is_finite() && *g > 0.0)
    {
        return Some((gb * (1u64 << 30) as f64) as u64);
    }
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Refuses `bytes` for `what` (e.g. "a 2400×2400×2400 volume") when they exceed
/// [`limit_bytes`], naming both in GiB.
pub fn check(bytes: u128, what: &str) -> Result<()> {
    match limit_bytes() {
        Some(limit) if bytes > u128::from(limit) => Err(SimError::OutOfRange(format!(
            "{what} needs {:.1} GiB, more than this machine's {:.1} GiB of memory \
             (TOMOGRAF_MEMORY_LIMIT_GB sets another limit)",
            bytes as f64 / (1u64 << 30) as f64,
            limit as f64 / (1u64 << 30) as f64
        ))),
        _ => Ok(()),
    }
}
