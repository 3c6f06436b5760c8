//! The value-length pre-check (`tomograf_datasets::dicom::check_value_lengths`) against the
//! DICOM parser on files from other software: every file the parser reads whole must pass
//! the pre-check (it must never refuse a file the parser would read), and the files it
//! refuses are listed with the parser's own verdict.
//!
//! ```sh
//! pip download --no-deps pydicom==3.0.2 && unzip -q pydicom-3.0.2-py3-none-any.whl 'pydicom/data/test_files/*'
//! cargo run --release -p tomograf-datasets --example dicom_lengths -- pydicom/data/test_files
//! ```
//!
//! Exits 1 when a file the parser reads is refused. docs/reliability.md has the result.

use std::path::{Path, PathBuf};

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            files(&p, out);
        } else {
            out.push(p);
        }
    }
}

fn main() {
    let mut all = Vec::new();
    for arg in std::env::args().skip(1) {
        files(Path::new(&arg), &mut all);
    }
    all.sort();
    if all.is_empty() {
        eprintln!("usage: dicom_lengths FOLDER… (DICOM files; see the module doc)");
        std::process::exit(2);
    }
    let (mut part10, mut both_ok, mut refused, mut wrong) = (0, 0, 0, 0);
    for p in &all {
        let head = std::fs::read(p).unwrap_or_default();
        if head.len() < 132 || &head[128..132] != b"DICM" {
            continue;
        }
        part10 += 1;
        let parser = dicom_object::OpenFileOptions::new().open_file(p);
        let check = tomograf_datasets::dicom::check_value_lengths(p);
        let name = p.file_name().unwrap_or_default().to_string_lossy();
        match (&parser, &check) {
            (Ok(_), Ok(())) => both_ok += 1,
            (Ok(_), Err(e)) => {
                wrong += 1;
                println!("REFUSED, but the parser reads it: {name}: {e}");
            }
            (Err(pe), Err(e)) => {
                refused += 1;
                println!("refused (the parser fails too: {pe}): {name}: {e}");
            }
            (Err(_), Ok(())) => {}
        }
    }
    println!(
        "{part10} Part-10 files: {both_ok} read by the parser and passed by the pre-check, \
         {refused} refused by both, {wrong} refused that the parser reads"
    );
    if wrong > 0 {
        std::process::exit(1);
    }
}
