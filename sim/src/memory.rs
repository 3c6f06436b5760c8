//! How much memory a job may still take, so that a size a user asks for (a volume's
//! dimensions, a reconstruction grid, a job's peak) is refused with a clear error before an
//! allocation that cannot succeed — rather than the process aborting with "memory
//! allocation of N bytes failed", or the kernel killing it mid-run.
//!
//! The limit is `TOMOGRAF_MEMORY_LIMIT_GB` when set (a job's own budget; tests use it to
//! make the check independent of the machine); otherwise the memory available now: the
//! kernel's `MemAvailable` (`/proc/meminfo`), or less when the process runs in a cgroup
//! (v2 `memory.max` − `memory.current`, v1 `memory.limit_in_bytes` − `memory.usage_in_bytes`).
//! Where none is known, nothing is refused here.

use crate::error::{Result, SimError};

/// A memory limit and where it comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limit {
    /// Bytes a job may still take.
    pub bytes: u64,
    /// Where the number comes from, as error messages name it.
    pub source: Source,
}

/// Where a [`Limit`] comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// `TOMOGRAF_MEMORY_LIMIT_GB`.
    Environment,
    /// `MemAvailable` of `/proc/meminfo`.
    Available,
    /// The cgroup's limit less its usage.
    Cgroup,
}

impl Source {
    fn words(self) -> &'static str {
        match self {
            Self::Environment => "that TOMOGRAF_MEMORY_LIMIT_GB allows",
            Self::Available => "of memory this machine has available now (MemAvailable)",
            Self::Cgroup => "that this process's cgroup may still take (its memory limit)",
        }
    }
}

/// The memory a job may still take (`None`: unknown, no limit).
pub fn limit() -> Option<Limit> {
    if let Some(gb) = std::env::var("TOMOGRAF_MEMORY_LIMIT_GB")
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
        .filter(|g| g.is_finite() && *g > 0.0)
    {
        return Some(Limit {
            bytes: (gb * (1u64 << 30) as f64) as u64,
            source: Source::Environment,
        });
    }
    let read = |p: &str| std::fs::read_to_string(p).ok();
    let available = read("/proc/meminfo")
        .and_then(|t| mem_available(&t))
        .map(|bytes| Limit {
            bytes,
            source: Source::Available,
        });
    let cgroup = cgroup_room(
        read("/sys/fs/cgroup/memory.max").as_deref(),
        read("/sys/fs/cgroup/memory.current").as_deref(),
    )
    .or_else(|| {
        cgroup_room(
            read("/sys/fs/cgroup/memory/memory.limit_in_bytes").as_deref(),
            read("/sys/fs/cgroup/memory/memory.usage_in_bytes").as_deref(),
        )
    })
    .map(|bytes| Limit {
        bytes,
        source: Source::Cgroup,
    });
    match (available, cgroup) {
        (Some(a), Some(c)) => Some(if c.bytes < a.bytes { c } else { a }),
        (a, c) => a.or(c),
    }
}

/// The memory one allocation may take, bytes (`None`: unknown, no limit).
pub fn limit_bytes() -> Option<u64> {
    limit().map(|l| l.bytes)
}

/// `MemAvailable` (bytes) from the text of `/proc/meminfo`.
fn mem_available(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// A cgroup's limit less its usage (bytes) from the two files' text; `None` without a
/// limit ("max", or v1's near-2⁶³ "unlimited") or when either cannot be read.
fn cgroup_room(max: Option<&str>, current: Option<&str>) -> Option<u64> {
    let max: u64 = max?.trim().parse().ok()?;
    if max >= 1 << 60 {
        return None;
    }
    let used: u64 = current?.trim().parse().ok()?;
    Some(max.saturating_sub(used))
}

/// Refuses `bytes` for `what` (e.g. "a 2400×2400×2400 volume") when they exceed
/// [`limit`], naming both (in GiB, or MiB below 1 GiB) and where the limit comes from.
pub fn check(bytes: u128, what: &str) -> Result<()> {
    match limit() {
        Some(l) if bytes > u128::from(l.bytes) => Err(SimError::OutOfRange(format!(
            "{what} needs {}, more than the {} {} (TOMOGRAF_MEMORY_LIMIT_GB sets another limit)",
            size(bytes as f64),
            size(l.bytes as f64),
            l.source.words()
        ))),
        _ => Ok(()),
    }
}

/// `bytes` as "3.2 GiB", or "12.5 MiB" below 1 GiB (the words of [`check`]'s errors).
pub fn size(bytes: f64) -> String {
    const GIB: f64 = (1u64 << 30) as f64;
    if bytes >= GIB {
        format!("{:.1} GiB", bytes / GIB)
    } else {
        format!("{:.1} MiB", bytes / (1u64 << 20) as f64)
    }
}

/// How the program's allocator gives freed memory back to the system, when it keeps some
/// (the command line's mimalloc does, for a few milliseconds after each free).
static RELEASE: std::sync::OnceLock<fn()> = std::sync::OnceLock::new();

/// Sets how [`release_freed`] returns freed memory (once, at start-up; later calls change
/// nothing).
pub fn set_release(release: fn()) {
    let _ = RELEASE.set(release);
}

/// Returns to the system the memory the allocator still keeps of freed blocks, so that the
/// next piece of work (an item, a stage) starts from what is really held: called between
/// a job's items and stages, it keeps their peaks from adding up with timing, and
/// [`resident_bytes`] honest. Does nothing where no allocator was set ([`set_release`]).
pub fn release_freed() {
    if let Some(release) = RELEASE.get() {
        release();
    }
}

/// The memory this process holds now (its resident set, bytes; `/proc/self/statm`), or
/// `None` where it cannot be read.
pub fn resident_bytes() -> Option<u64> {
    let statm = std::fs::read_to_string("/proc/self/statm").ok()?;
    let pages: u64 = statm.split_whitespace().nth(1)?.parse().ok()?;
    Some(pages * 4096)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_are_named_in_the_unit_that_shows_them() {
        assert_eq!(size(1.5 * (1u64 << 20) as f64), "1.5 MiB");
        assert_eq!(size(8.0 * (1u64 << 30) as f64), "8.0 GiB");
        assert!(resident_bytes().is_some_and(|b| b > 1 << 20));
    }

    #[test]
    fn the_available_memory_and_a_cgroups_room_are_read_from_their_files() {
        let meminfo = "MemTotal:       24000000 kB\nMemFree:  100 kB\nMemAvailable:   2000 kB\n";
        assert_eq!(mem_available(meminfo), Some(2000 * 1024));
        assert_eq!(mem_available("MemTotal: 5 kB\n"), None);
        assert_eq!(cgroup_room(Some("1000\n"), Some("300\n")), Some(700));
        assert_eq!(cgroup_room(Some("1000"), Some("3000")), Some(0));
        assert_eq!(cgroup_room(Some("max\n"), Some("300")), None);
        assert_eq!(cgroup_room(Some("9223372036854771712"), Some("1")), None);
        assert_eq!(cgroup_room(None, Some("1")), None);
        assert_eq!(cgroup_room(Some("1000"), None), None);
    }
}
