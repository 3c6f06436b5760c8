//! The command line's memory allocator: mimalloc, with transparent huge pages for large
//! blocks only.
//!
//! mimalloc advises the kernel to back all its memory with 2 MB pages. Where fresh 2 MB
//! pages are dear — on a virtual machine right after another large process — a render's
//! first touches of its small buffers then cost more than the render itself (the chest CT's
//! AP view: 20–35 ms against 16 ms; docs/projector.md, "Session 28"), while the large
//! buffers that are read over and over (a CT volume, its copies, the network's tensors)
//! gain from the TLB's reach (renders 2–25 % faster). So, as numpy does for its arrays,
//! only blocks of [`HUGE_FROM`] or more are advised, and the advice is taken back when
//! they are freed. Setting `MIMALLOC_ALLOW_THP` (`1`: mimalloc's own default, every block;
//! `0`: none) overrides this.

use std::alloc::{GlobalAlloc, Layout};
use std::sync::atomic::{AtomicBool, Ordering};

/// Blocks from this many bytes on are advised to use transparent huge pages.
pub const HUGE_FROM: usize = 4 << 20;

/// mimalloc's `mi_option_allow_thp` (`mimalloc.h` of mimalloc 3, which libmimalloc-sys
/// 0.1.49 builds by default; 37 in mimalloc 2). The crate does not export it; the test
/// `only_large_blocks_are_advised_huge_pages` fails if this names another option.
#[cfg(target_os = "linux")]
const MI_OPTION_ALLOW_THP: std::ffi::c_int = 43;

#[cfg(target_os = "linux")]
unsafe extern "C" {
    fn mi_option_set(option: std::ffi::c_int, value: std::ffi::c_long);
}

// mimalloc's `mi_collect` (`mimalloc.h`), on every platform the crate builds it for.
unsafe extern "C" {
    fn mi_collect(force: bool);
}

/// Returns to the system what mimalloc still keeps of freed blocks. mimalloc holds freed
/// memory for a few milliseconds (its `purge_delay`) before it gives it back, so a job
/// that makes items one after another could hold the last item's buffers beside the next
/// one's, and its peak would depend on timing (the `tiny` studies' data stage measured
/// 100–135 MiB in repeated runs, 67 MiB with the delay at 0). Jobs call it through
/// [`tomograf_sim::memory::release_freed`] between items and stages; it costs well under a
/// millisecond when little is held.
pub fn release_freed() {
    // SAFETY: `mi_collect` only gives back memory no live block uses.
    unsafe { mi_collect(true) }
}

/// mimalloc, with huge pages for large blocks only (see the module documentation).
pub struct Allocator;

/// Whether [`configure`] has run. Its first caller is the runtime's first allocation,
/// before `main` and any other thread.
static CONFIGURED: AtomicBool = AtomicBool::new(false);

/// Whether [`advise`] gives advice: not where the user chose with `MIMALLOC_ALLOW_THP`.
#[cfg(target_os = "linux")]
static ADVISING: AtomicBool = AtomicBool::new(false);

/// Turns mimalloc's advice off unless the user chose it with `MIMALLOC_ALLOW_THP`; runs
/// before mimalloc's first request for memory from the system.
#[inline]
fn configure() {
    if CONFIGURED.load(Ordering::Relaxed) {
        return;
    }
    CONFIGURED.store(true, Ordering::Relaxed);
    #[cfg(target_os = "linux")]
    // SAFETY: `getenv` reads the environment without allocating, and no other thread
    // exists yet to change it; `mi_option_set` only stores the value.
    unsafe {
        if libc::getenv(c"MIMALLOC_ALLOW_THP".as_ptr()).is_null() {
            mi_option_set(MI_OPTION_ALLOW_THP, 0);
            ADVISING.store(true, Ordering::Relaxed);
        }
    }
}

/// Advises huge pages (`MADV_HUGEPAGE`), or takes the advice back (`MADV_NOHUGEPAGE`, before
/// the block is freed: its memory may then hold small blocks), for the whole pages inside a
/// block of `size` bytes at `ptr`, when it is large. Failure (a kernel without transparent
/// huge pages) changes nothing.
#[inline]
fn advise(ptr: *mut u8, size: usize, huge: bool) {
    #[cfg(target_os = "linux")]
    if size >= HUGE_FROM && !ptr.is_null() && ADVISING.load(Ordering::Relaxed) {
        const PAGE: usize = 4096;
        let start = (ptr as usize).next_multiple_of(PAGE);
        let end = (ptr as usize + size) & !(PAGE - 1);
        let advice = if huge {
            libc::MADV_HUGEPAGE
        } else {
            libc::MADV_NOHUGEPAGE
        };
        // SAFETY: the range lies inside the block; the advice moves no data.
        unsafe {
            libc::madvise(start as *mut libc::c_void, end - start, advice);
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (ptr, size, huge);
}

// SAFETY: every call is mimalloc's; `advise` changes no memory.
unsafe impl GlobalAlloc for Allocator {
    #[inline]
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        configure();
        // SAFETY: the caller's contract, passed on.
        let p = unsafe { mimalloc::MiMalloc.alloc(layout) };
        advise(p, layout.size(), true);
        p
    }

    #[inline]
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        configure();
        // SAFETY: the caller's contract, passed on.
        let p = unsafe { mimalloc::MiMalloc.alloc_zeroed(layout) };
        advise(p, layout.size(), true);
        p
    }

    #[inline]
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        advise(ptr, layout.size(), false);
        // SAFETY: the caller's contract, passed on.
        unsafe { mimalloc::MiMalloc.dealloc(ptr, layout) }
    }

    #[inline]
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: the caller's contract, passed on.
        let p = unsafe { mimalloc::MiMalloc.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            // A moved block's old memory is freed, and a shrunk block's tail: take their
            // advice back (another thread may have taken the memory meanwhile, which costs
            // that block its huge pages, nothing more).
            if p != ptr || new_size < layout.size() {
                advise(ptr, layout.size(), false);
            }
            advise(p, new_size, true);
        }
        p
    }
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    /// The `VmFlags` of the mapping holding `addr` (`None` where /proc gives none).
    fn vm_flags(addr: usize) -> Option<String> {
        let smaps = std::fs::read_to_string("/proc/self/smaps").ok()?;
        let mut inside = false;
        for line in smaps.lines() {
            let head = line.split_whitespace().next().unwrap_or("");
            if let Some((lo, hi)) = head.split_once('-')
                && let (Ok(lo), Ok(hi)) =
                    (usize::from_str_radix(lo, 16), usize::from_str_radix(hi, 16))
            {
                inside = (lo..hi).contains(&addr);
            } else if inside && let Some(flags) = line.strip_prefix("VmFlags:") {
                return Some(flags.to_string());
            }
        }
        None
    }

    /// Small blocks come from memory mimalloc did not advise, also where a large block
    /// was freed; a large block is advised. Fails if `MI_OPTION_ALLOW_THP` names another
    /// option (mimalloc then advises the small block's memory), if `advise` is left out,
    /// or if a freed block keeps its advice.
    #[test]
    fn only_large_blocks_are_advised_huge_pages() {
        if std::env::var_os("MIMALLOC_ALLOW_THP").is_some() {
            eprintln!("skipped: MIMALLOC_ALLOW_THP is set");
            return;
        }
        // A kernel without transparent huge pages refuses the advice.
        let probe = vec![0u8; 2 * super::HUGE_FROM];
        let page = (probe.as_ptr() as usize).next_multiple_of(4096);
        // SAFETY: advice on whole pages inside `probe`; no data moves.
        if unsafe { libc::madvise(page as *mut libc::c_void, 4096, libc::MADV_HUGEPAGE) } != 0 {
            eprintln!("skipped: this kernel has no transparent huge pages");
            return;
        }
        drop(probe);
        let small = vec![1u8; 1 << 16];
        let large = vec![1u8; 3 * super::HUGE_FROM];
        let Some(small_flags) = vm_flags(small.as_ptr() as usize) else {
            eprintln!("skipped: no /proc/self/smaps VmFlags");
            return;
        };
        let large_flags = vm_flags(large.as_ptr() as usize + large.len() / 2).unwrap();
        assert!(
            !small_flags.contains(" hg"),
            "small block's mapping: {small_flags}"
        );
        assert!(
            large_flags.contains(" hg"),
            "large block's mapping: {large_flags}"
        );
        assert!(!vm_flags(small.as_ptr() as usize).unwrap().contains(" hg"));
    }

    /// A freed large block is still resident until mimalloc purges it; `release_freed`
    /// gives it back at once. Fails if it does nothing (the block's 64 MiB stay resident
    /// right after the free) or if it names another mimalloc function.
    #[test]
    fn released_memory_leaves_the_resident_set() {
        let Some(before) = tomograf_sim::memory::resident_bytes() else {
            eprintln!("skipped: no /proc/self/statm");
            return;
        };
        let mut block = vec![0u8; 64 << 20];
        for b in block.iter_mut().step_by(4096) {
            *b = 1;
        }
        std::hint::black_box(&block);
        let during = tomograf_sim::memory::resident_bytes().unwrap();
        drop(block);
        super::release_freed();
        let after = tomograf_sim::memory::resident_bytes().unwrap();
        // Measured across the free and the release alone, so that what other tests of this
        // binary allocate meanwhile (tens of MiB while the block is touched) does not count:
        // most of the block's 64 MiB must have left the resident set.
        assert!(
            after + (40 << 20) < during,
            "{} MiB resident before the block, {} MiB with it, {} MiB after its release",
            before >> 20,
            during >> 20,
            after >> 20
        );
    }
}
