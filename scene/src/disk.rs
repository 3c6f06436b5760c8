//! Disk space: what a data set will write, checked against the space free on its folder's
//! file system before the first item is made, so a job that cannot fit ends at once with
//! the numbers instead of hours later with a full disk.
//!
//! Sizes are bytes. An item's size is an upper bound of what [`crate::dataset`] writes:
//! `projections.npy` (f32, one `size`² image per view, AP and lateral included), `ct.nii.gz`
//! (a `size`³ f32 grid: normalised CTs do not compress — gzip wrote a 64³ `lidc` item's in
//! 93 % of its raw size, a 64³ `full-chest` one's in 101.5 % and a 128³ one's in 102.8 % —
//! so the raw size and a sixteenth more is taken), `views.json`, `item.json` and the item's
//! line of `manifest.jsonl`.

use anyhow::{Result, bail};
use std::path::Path;

/// `views.json` and `item.json` per view, bytes (measured: 557 and 40 B per view on a
/// 38-view 64³ item; rounded up).
const JSON_BYTES_PER_VIEW: u128 = 1024;
/// The files' fixed parts: the npy and NIfTI headers, gzip's framing, the JSON records'
/// fixed fields and the manifest line (measured: about 5 KiB; rounded up).
const FIXED_BYTES: u128 = 16 * 1024;

/// Upper bound of the bytes one data-set item of `images` projections of `size`² pixels and
/// a `size`³ CT takes on disk.
pub fn item_bytes(size: usize, images: usize) -> u128 {
    let (size, images) = (size as u128, images as u128);
    let ct = 4 * size * size * size;
    4 * images * size * size + ct + ct / 16 + JSON_BYTES_PER_VIEW * images + FIXED_BYTES
}

/// Free bytes (for an unprivileged writer) on the file system that holds `path`, or that will
/// hold it: its nearest existing ancestor is asked.
pub fn available_bytes(path: &Path) -> Result<u64> {
    let mut at = path;
    loop {
        if at.exists() {
            return fs4::available_space(at).map_err(|e| {
                anyhow::anyhow!("cannot read the free space of {}: {e}", at.display())
            });
        }
        match at.parent() {
            Some(p) if !p.as_os_str().is_empty() => at = p,
            _ => return fs4::available_space(Path::new(".")).map_err(anyhow::Error::from),
        }
    }
}

/// Refuses a job that would write `needed` bytes where `available` are free; the error names
/// `what`, both sizes and the ways out.
pub fn check_fits(needed: u128, available: u64, what: &str) -> Result<()> {
    if needed > u128::from(available) {
        bail!(
            "{what} would write about {} but {} is free there: free space, give another \
             folder, or make fewer or smaller items",
            size(needed as f64),
            size(available as f64)
        );
    }
    Ok(())
}

/// `bytes` as "12.5 MiB", "3.2 GiB", "49.7 TiB".
fn size(bytes: f64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = bytes;
    let mut unit = 0;
    while v >= 1024.0 && unit + 1 < UNITS.len() {
        v /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{v:.0} B")
    } else {
        format!("{v:.1} {}", UNITS[unit])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bound holds over what items wrote (`tomograf dataset`, `full-chest` phantom seed
    /// 0: ct.nii.gz, projections.npy, views.json, item.json and a manifest line, measured
    /// 2026-11-30) and is not far above it.
    #[test]
    fn an_item_bound_covers_measured_items() {
        for (size, views, measured) in [
            (64, 36, 1_064_668 + 622_720 + 21_108 + 2351 + 1175),
            (128, 72, 8_626_800 + 4_849_792 + 40_604 + 3638 + 1598),
        ] {
            let bound = item_bytes(size, views + 2);
            assert!(bound >= measured, "{size}³: {bound} < {measured}");
            assert!(bound < measured * 11 / 10, "{size}³: {bound} ≫ {measured}");
        }
    }

    #[test]
    fn a_job_beyond_the_free_space_is_refused_with_its_numbers() {
        let err = check_fits(3 << 40, 1 << 30, "100 items")
            .unwrap_err()
            .to_string();
        assert!(err.contains("3.0 TiB"), "{err}");
        assert!(err.contains("1.0 GiB is free"), "{err}");
        assert!(check_fits(1 << 30, 1 << 30, "x").is_ok());
    }

    #[test]
    fn the_free_space_of_a_folder_not_yet_made_is_its_parents() {
        let tmp = tempfile::tempdir().unwrap();
        let deep = tmp.path().join("a/b/c");
        let free = available_bytes(&deep).unwrap();
        assert!(free > 0);
        assert!(free.abs_diff(available_bytes(tmp.path()).unwrap()) < 1 << 30);
    }
}
