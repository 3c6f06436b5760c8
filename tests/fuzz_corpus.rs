//! Replays the fuzzers' committed corpus and seeds (`fuzz/corpus/<target>/`,
//! `fuzz/seeds/<target>/`) through the parsers on stable Rust: every input must end in a
//! value or an error. A parser change that makes a once-fuzzed input panic fails CI here,
//! without nightly. The fuzzing itself: docs/reliability.md.

#[path = "../fuzz/src/targets.rs"]
#[allow(dead_code)]
mod targets;

use std::path::Path;
use std::time::{Duration, Instant};

#[test]
fn every_corpus_input_ends_in_a_value_or_an_error() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut total = 0;
    let mut slow = Vec::new();
    for (name, run) in targets::TARGETS {
        let mut n = 0;
        for folder in ["seeds", "corpus"] {
            let Ok(entries) = std::fs::read_dir(root.join(folder).join(name)) else {
                continue;
            };
            let mut files: Vec<_> = entries.map(|e| e.unwrap().path()).collect();
            files.sort();
            for f in files {
                let data = std::fs::read(&f).unwrap();
                let t0 = Instant::now();
                eprintln!("{}", f.display());
                run(&data);
                if t0.elapsed() > Duration::from_secs(5) {
                    slow.push(format!("{} ({:?})", f.display(), t0.elapsed()));
                }
                n += 1;
            }
        }
        eprintln!("{name}: {n} input(s) replayed");
        assert!(n > 0, "{name}: no seeds or corpus under {}", root.display());
        total += n;
    }
    assert!(slow.is_empty(), "inputs over 5 s: {slow:?}");
    eprintln!("{total} input(s) in all");
}
