//! Kill-and-resume soaks: `dataset`, `train`, `evaluate` and a tiny `study` are killed with
//! SIGKILL at seeded random moments, then re-run with the same command, and must end with
//! the same bytes as an uninterrupted run (run times masked) and no temporary file left in
//! the output tree.
//!
//! CI kills each command 3 times; the full soak (20 kills each, the 60+ trials):
//! `TOMOGRAF_SOAK_KILLS=20 cargo test --release --test soak -- --nocapture`.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Kills per command (CI: 3).
fn kills() -> usize {
    std::env::var("TOMOGRAF_SOAK_KILLS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3)
}

/// SplitMix64: the kill moments are seeded, so a failing trial can be re-run.
struct Moments(u64);

impl Moments {
    /// A fraction in [0.02, 0.98).
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        0.02 + 0.96 * (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn command(args: &[String]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_tomograf"));
    c.args(args).stdout(Stdio::null()).stderr(Stdio::piped());
    c
}

/// Runs to the end; returns the wall time.
fn run(args: &[String]) -> Duration {
    let t0 = Instant::now();
    let out = command(args).output().expect("runs");
    assert!(
        out.status.success(),
        "{args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    t0.elapsed()
}

/// Starts the command and kills it (SIGKILL) after `after`; false when it had already
/// finished.
fn run_and_kill(args: &[String], after: Duration) -> bool {
    let mut child = command(args).stderr(Stdio::null()).spawn().expect("starts");
    let t0 = Instant::now();
    while t0.elapsed() < after {
        if child.try_wait().expect("waits").is_some() {
            return false;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let killed = child.try_wait().expect("waits").is_none();
    let _ = child.kill();
    let _ = child.wait();
    killed
}

/// Every file under `dir` (relative path → content), with run times masked (the `seconds`
/// column of CSV files and lines that report seconds) and `dir` itself written `<OUT>` in
/// text files (a job records the paths of its inputs).
fn tree(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let rel = p.strip_prefix(dir).unwrap().to_string_lossy().into_owned();
            if p.is_dir() {
                out.push((format!("{rel}/"), Vec::new()));
                stack.push(p);
            } else {
                out.push((rel, mask(&p, std::fs::read(&p).unwrap(), dir)));
            }
        }
    }
    out.sort();
    out
}

fn mask(path: &Path, bytes: Vec<u8>, dir: &Path) -> Vec<u8> {
    let name = path.to_string_lossy();
    let Ok(text) = String::from_utf8(bytes.clone()) else {
        return bytes;
    };
    let text = text.replace(dir.to_str().unwrap(), "<OUT>");
    if !(name.ends_with(".csv") || name.ends_with(".md") || name.ends_with(".html")) {
        return text.into_bytes();
    }
    let mut lines = text.lines();
    let header = lines.next().unwrap_or_default().to_string();
    let column = name
        .ends_with(".csv")
        .then(|| header.split(',').position(|c| c == "seconds"))
        .flatten();
    let mut out = header + "\n";
    for l in lines {
        if l.contains(" s per iteration") || l.contains("seconds") {
            continue;
        }
        match column {
            Some(c) => {
                let mut f: Vec<&str> = l.split(',').collect();
                if c < f.len() {
                    f[c] = "";
                }
                out += &f.join(",");
            }
            None => out += l,
        }
        out.push('\n');
    }
    out.into_bytes()
}

/// Files a killed writer could leave: atomic writers' temporaries and checkpoint folders
/// of an unfinished save.
fn leftovers(t: &[(String, Vec<u8>)]) -> Vec<String> {
    t.iter()
        .map(|(p, _)| p.clone())
        .filter(|p| {
            let name = p
                .trim_end_matches('/')
                .rsplit('/')
                .next()
                .unwrap_or_default();
            name.ends_with(".tmp") || name.contains("-tmp-") || name.ends_with(".old")
        })
        .collect()
}

/// The soak of one command: `args(out)` run uninterrupted into `reference`, then killed
/// `kills()` times at seeded moments of that run's duration, each in a fresh folder, and
/// re-run to the end with the same command.
fn soak(name: &str, seed: u64, args: impl Fn(&Path) -> Vec<String>) {
    let tmp = tempfile::tempdir().unwrap();
    let reference_dir = tmp.path().join("reference");
    let took = run(&args(&reference_dir));
    let reference = tree(&reference_dir);
    assert!(
        leftovers(&reference).is_empty(),
        "{name}: {:?}",
        leftovers(&reference)
    );
    let mut moments = Moments(seed);
    let (mut killed, mut differences) = (0, Vec::new());
    for k in 0..kills() {
        let dir: PathBuf = tmp.path().join(format!("trial-{k}"));
        // A kill after the run had finished tests nothing: try earlier (the reference
        // run may have been slower than this one).
        let mut at = took.mul_f64(moments.next());
        for _ in 0..4 {
            if run_and_kill(&args(&dir), at) {
                killed += 1;
                break;
            }
            std::fs::remove_dir_all(&dir).unwrap();
            at = at.mul_f64(0.5);
        }
        run(&args(&dir));
        let resumed = tree(&dir);
        let left = leftovers(&resumed);
        if !left.is_empty() {
            differences.push(format!("trial {k} (killed at {at:?}): left {left:?}"));
        } else if resumed != reference {
            let names = |t: &[(String, Vec<u8>)]| -> Vec<String> {
                t.iter().map(|(p, _)| p.clone()).collect()
            };
            let differing: Vec<String> = resumed
                .iter()
                .filter(|f| !reference.contains(f))
                .map(|(p, _)| p.clone())
                .collect();
            differences.push(format!(
                "trial {k} (killed at {at:?}): differs in {differing:?}; files {:?} vs {:?}",
                names(&resumed).len(),
                names(&reference).len()
            ));
        }
    }
    eprintln!(
        "{name}: {} trial(s), {killed} killed mid-run, {} difference(s); uninterrupted run {took:?}",
        kills(),
        differences.len()
    );
    assert!(
        differences.is_empty(),
        "{name}:\n{}",
        differences.join("\n")
    );
}

fn s(p: &Path) -> String {
    p.to_str().unwrap().to_string()
}

fn strings(a: &[&str]) -> Vec<String> {
    a.iter().map(|x| x.to_string()).collect()
}

/// A tiny realistic data set (16³, 10 views per rotation; the flat panel's noise).
fn dataset_args(out: &Path, phantoms: &str) -> Vec<String> {
    let mut a = strings(&["dataset", "-o"]);
    a.push(s(out));
    a.extend(strings(&[
        "--phantoms",
        phantoms,
        "--size",
        "16",
        "--views",
        "10",
        "--preset",
        "kv-flat-panel-120kvp",
        "--noise-seed",
        "5",
    ]));
    a
}

#[test]
fn dataset_resumes_to_the_same_bytes() {
    soak("dataset", 1, |out| dataset_args(out, "4"));
}

#[test]
fn train_resumes_to_the_same_bytes() {
    let data = tempfile::tempdir().unwrap();
    run(&dataset_args(data.path(), "2"));
    let d = s(data.path());
    soak("train", 2, |out| {
        let mut a = strings(&["train", &d, "-o"]);
        a.push(s(out));
        // `--resume` from the first run: it starts afresh when there is no checkpoint yet.
        a.extend(strings(&[
            "--config",
            "tiny",
            "--iterations",
            "40",
            "--resume",
        ]));
        a
    });
}

#[test]
fn evaluate_resumes_to_the_same_bytes() {
    let data = tempfile::tempdir().unwrap();
    run(&dataset_args(data.path(), "3"));
    let d = s(data.path());
    soak("evaluate", 3, |out| {
        let mut a = strings(&["evaluate", &d, "-o"]);
        a.push(s(out));
        a.extend(strings(&["--views", "1,2,5"]));
        a
    });
}

#[test]
fn a_study_resumes_to_the_same_bytes() {
    soak("study", 4, |out| {
        let mut a = strings(&["study", "realism-gap", "-o"]);
        a.push(s(out));
        a.extend(strings(&["--seed", "3", "--levels", "ideal-drr"]));
        a
    });
}
