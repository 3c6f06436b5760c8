//! Atomic file replacement: a reader never sees a half-written file.
//!
//! The content is written to a temporary file in the destination's directory (same file
//! system, so the final rename is atomic), flushed and synced to disk, then renamed over
//! the destination. On any failure — including a panic in the write closure — the
//! temporary file is removed and the destination is left untouched (an existing file keeps
//! its old content; a missing one stays missing).

use crate::error::{DatasetError, Result};
use std::fs::{File, OpenOptions};
use std::io::{self, BufWriter};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Distinguishes temporary files created by concurrent calls in one process.
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes a file atomically.
///
/// `write` receives a buffered writer on a temporary file named
/// `.<file name>.<pid>.<n>.tmp` in the same directory as `path`. When it returns `Ok`, the
/// data is flushed, `fsync`ed and the temporary file is renamed over `path`. When it
/// returns an error (or panics), the temporary file is deleted and `path` is not touched.
///
/// Errors name `path` and the step that failed (creating, writing, syncing, renaming).
/// The directory of `path` must already exist.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> io::Result<()>,
) -> Result<()> {
    let (name, dir) = split(path)?;
    let (file, guard) = create_temp(&dir, |pid, n| format!(".{name}.{pid}.{n}.tmp"))
        .map_err(|e| DatasetError::io(path, "creating a temporary file", e))?;

    let mut writer = BufWriter::new(file);
    write(&mut writer).map_err(|e| DatasetError::io(path, "writing", e))?;
    let file = writer
        .into_inner()
        .map_err(|e| DatasetError::io(path, "writing", e.into_error()))?;
    commit(path, &dir, file, guard)
}

/// Writes `value` as pretty JSON with a final newline, atomically (as [`write_atomic`]).
pub fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    write_atomic(path, |w| {
        serde_json::to_writer_pretty(&mut *w, value).map_err(io::Error::other)?;
        io::Write::write_all(w, b"\n")
    })
}

/// Writes a file atomically through a writer that needs a *path* rather than a stream
/// (e.g. one that picks compression from the file name).
///
/// An empty temporary file `.<file name, dots → _>-tmp-<pid>-<n><suffix>` is reserved in
/// the directory of `path`; `suffix` (e.g. `.nii.gz`) must start with a dot and is the only
/// extension of that name. `write` must replace the content of the path it is given
/// (creating or truncating the file). Then the file is `fsync`ed and renamed over `path`,
/// as in [`write_atomic`]; when `write` fails (or panics) the temporary file is removed and
/// `path` is not touched.
pub(crate) fn write_atomic_to_path(
    path: &Path,
    suffix: &str,
    write: impl FnOnce(&Path) -> Result<()>,
) -> Result<()> {
    let (name, dir) = split(path)?;
    let stem = name.replace('.', "_");
    let (file, guard) = create_temp(&dir, |pid, n| format!(".{stem}-tmp-{pid}-{n}{suffix}"))
        .map_err(|e| DatasetError::io(path, "creating a temporary file", e))?;
    drop(file);

    write(&guard.path)?;
    let file = OpenOptions::new()
        .write(true)
        .open(&guard.path)
        .map_err(|e| DatasetError::io(path, "reopening the temporary file", e))?;
    commit(path, &dir, file, guard)
}

/// The destination's file name (lossy UTF-8) and directory.
fn split(path: &Path) -> Result<(String, PathBuf)> {
    let Some(name) = path.file_name() else {
        return Err(DatasetError::invalid_output(
            path,
            "the path has no file name",
        ));
    };
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    };
    Ok((name.to_string_lossy().into_owned(), dir))
}

/// Syncs the finished temporary file and renames it over `path`.
fn commit(path: &Path, dir: &Path, file: File, guard: TempGuard) -> Result<()> {
    file.sync_all()
        .map_err(|e| DatasetError::io(path, "syncing to disk", e))?;
    drop(file);

    std::fs::rename(&guard.path, path)
        .map_err(|e| DatasetError::io(path, "renaming the temporary file into place", e))?;
    guard.disarm();
    sync_dir(dir);
    Ok(())
}

/// Deletes the temporary file when dropped, unless disarmed after the rename.
struct TempGuard {
    path: PathBuf,
    armed: bool,
}

impl TempGuard {
    fn disarm(mut self) {
        self.armed = false;
    }
}

impl Drop for TempGuard {
    fn drop(&mut self) {
        if self.armed {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// Creates a fresh temporary file in `dir` named `name(pid, n)` (never reusing an existing
/// one).
fn create_temp(dir: &Path, name: impl Fn(u32, u64) -> String) -> io::Result<(File, TempGuard)> {
    let pid = std::process::id();
    let mut last = io::Error::other("no temporary name tried");
    for _ in 0..1000 {
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let tmp = dir.join(name(pid, n));
        match OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(file) => {
                let guard = TempGuard {
                    path: tmp,
                    armed: true,
                };
                return Ok((file, guard));
            }
            // A stale file left by a crashed process with the same pid: try the next name.
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => last = e,
            Err(e) => return Err(e),
        }
    }
    Err(last)
}

/// Makes the rename durable where the platform allows it (best effort).
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

/// The process id a temporary file of this module was created by, from its name
/// (`.<name>.<pid>.<n>.tmp` or `.<stem>-tmp-<pid>-<n><suffix>`); `None` for other files.
fn temp_owner(name: &str) -> Option<u32> {
    if !name.starts_with('.') {
        return None;
    }
    if let Some(rest) = name.strip_suffix(".tmp") {
        // .<name>.<pid>.<n>
        let mut parts = rest.rsplitn(3, '.');
        let n = parts.next()?;
        let pid = parts.next()?;
        parts.next()?;
        n.parse::<u64>().ok()?;
        return pid.parse().ok();
    }
    // .<stem>-tmp-<pid>-<n><suffix>
    let (_, tail) = name.rsplit_once("-tmp-")?;
    let (pid, rest) = tail.split_once('-')?;
    let n: String = rest.chars().take_while(char::is_ascii_digit).collect();
    if n.is_empty() || !rest[n.len()..].starts_with('.') {
        return None;
    }
    pid.parse().ok()
}

/// Whether process `pid` is running on this machine (Linux: `/proc/<pid>` exists). Where
/// that cannot be told, every process counts as alive, so nothing is removed.
fn alive(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    let proc_root = Path::new("/proc/self");
    if !proc_root.exists() {
        return true;
    }
    Path::new("/proc").join(pid.to_string()).exists()
}

/// Removes, under `dir` (recursively), the temporary files this module's writers left when
/// their process was killed (SIGKILL, power loss: no destructor ran) — those whose creating
/// process is no longer running on this machine; a live writer's temporaries (another shard
/// in the same folder) are kept. Returns how many were removed. A resumed job calls it on
/// its output folder, so a kill leaves no orphaned file behind. (On a file system shared
/// between machines a temporary of a writer on another machine looks orphaned here: run
/// the resumes of one folder on one machine, or accept that such a writer fails and is
/// re-run.)
pub fn remove_stale_temporaries(dir: &Path) -> Result<usize> {
    let mut removed = 0;
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let entries = match std::fs::read_dir(&d) {
            Ok(e) => e,
            Err(e) if e.kind() == io::ErrorKind::NotFound => continue,
            Err(e) => return Err(DatasetError::io(&d, "listing", e)),
        };
        for entry in entries {
            let entry = entry.map_err(|e| DatasetError::io(&d, "listing", e))?;
            let path = entry.path();
            let kind = entry
                .file_type()
                .map_err(|e| DatasetError::io(&path, "reading the type of", e))?;
            if kind.is_dir() {
                stack.push(path);
            } else if kind.is_file()
                && let Some(pid) = entry.file_name().to_str().and_then(temp_owner)
                && !alive(pid)
            {
                std::fs::remove_file(&path)
                    .map_err(|e| DatasetError::io(&path, "removing the stale temporary", e))?;
                removed += 1;
            }
        }
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    #[test]
    fn temporaries_are_recognised_and_stale_ones_removed() {
        assert_eq!(temp_owner(".item.json.1234.7.tmp"), Some(1234));
        assert_eq!(temp_owner(".ct_nii-tmp-99-0.nii.gz"), Some(99));
        for other in [
            "item.json",
            ".hidden",
            ".a.b.tmp",
            "x-tmp-1-2.nii",
            ".a-tmp-x-1.nii",
        ] {
            assert_eq!(temp_owner(other), None, "{other}");
        }
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("00001");
        std::fs::create_dir(&sub).unwrap();
        // pid 0 is never a user process; our own pid is alive.
        let dead = sub.join(".projections.npy.0.3.tmp");
        let dead2 = dir.path().join(".ct-tmp-0-1.nii.gz");
        let mine = sub.join(format!(".item.json.{}.0.tmp", std::process::id()));
        let keep = sub.join("item.json");
        for f in [&dead, &dead2, &mine, &keep] {
            std::fs::write(f, b"x").unwrap();
        }
        if Path::new("/proc/self").exists() {
            assert_eq!(remove_stale_temporaries(dir.path()).unwrap(), 2);
            assert!(!dead.exists() && !dead2.exists());
        }
        assert!(mine.exists() && keep.exists());
    }

    use super::*;
    use std::io::Write;

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn success_replaces_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bin");
        std::fs::write(&path, b"old").unwrap();
        write_atomic(&path, |w| w.write_all(b"new content")).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new content");
        assert_eq!(entries(dir.path()), vec!["out.bin"]);
    }

    #[test]
    fn failing_closure_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bin");
        let err = write_atomic(&path, |w| {
            w.write_all(&[1u8; 100_000])?;
            Err(io::Error::other("encoder exploded"))
        })
        .unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.contains("out.bin") && msg.contains("encoder exploded"),
            "{msg}"
        );
        assert!(entries(dir.path()).is_empty(), "{:?}", entries(dir.path()));
    }

    #[test]
    fn failing_closure_keeps_old_content() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("keep.bin");
        std::fs::write(&path, b"old").unwrap();
        assert!(write_atomic(&path, |_| Err(io::Error::other("no"))).is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(entries(dir.path()), vec!["keep.bin"]);
    }

    #[test]
    fn panicking_closure_leaves_no_temp_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.bin");
        let r = std::panic::catch_unwind(|| {
            let _ = write_atomic(&path, |_| panic!("boom"));
        });
        assert!(r.is_err());
        assert!(entries(dir.path()).is_empty());
    }

    #[test]
    fn path_writer_gets_a_temp_name_with_only_the_suffix_as_extension() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ct.scan.nii.gz");
        std::fs::write(&path, b"old").unwrap();
        let mut seen = PathBuf::new();
        write_atomic_to_path(&path, ".nii.gz", |tmp| {
            seen = tmp.to_owned();
            std::fs::write(tmp, b"new").map_err(|e| DatasetError::io(&path, "writing", e))
        })
        .unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
        assert_eq!(entries(dir.path()), vec!["ct.scan.nii.gz"]);
        assert_eq!(seen.parent(), Some(dir.path()));
        let name = seen.file_name().unwrap().to_string_lossy().into_owned();
        assert!(name.starts_with(".ct_scan_nii_gz-tmp-"), "{name}");
        // Stripping the suffix leaves a name with no extension of its own.
        let stem = Path::new(name.strip_suffix(".nii.gz").unwrap());
        assert_eq!(stem.extension(), None, "{name}");
    }

    #[test]
    fn failing_path_writer_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.nii");
        let err = write_atomic_to_path(&path, ".nii", |tmp| {
            std::fs::write(tmp, [0u8; 1000]).unwrap();
            Err(DatasetError::invalid_output(&path, "writer refused"))
        })
        .unwrap_err();
        assert!(err.to_string().contains("writer refused"), "{err}");
        assert!(entries(dir.path()).is_empty(), "{:?}", entries(dir.path()));
    }

    #[test]
    fn missing_directory_is_a_clear_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/dir/x.bin");
        let msg = write_atomic(&path, |_| Ok(())).unwrap_err().to_string();
        assert!(
            msg.contains("x.bin") && msg.contains("creating a temporary file"),
            "{msg}"
        );
    }
}
