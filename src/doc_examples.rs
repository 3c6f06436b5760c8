//! Every code block of README.md and docs/*.md, and the scene examples of `scene.rs`,
//! checked against the code, so that a documented example that drifts fails CI.
//!
//! * `toml` blocks are scene files: each must parse as a [`Scene`] (unknown keys are
//!   errors) and resolve into its detector physics ([`physics::acquisition`]: names of
//!   presets, detectors, signals, materials), and its `[[mesh]]` tables into meshes where they
//!   are generated in code.
//! * `sh` blocks: every `tomograf …` or `cargo run --release -- …` command must parse with the
//!   command line's own definition ([`Cli`]), flags and values alike. Placeholders written
//!   `$NAME`/`${NAME}` or as capital letters in `K/8` become values of the right kind (a
//!   folder, 0). They are parsed, not run: the commands train for hours or need files a
//!   reader brings; the runs themselves are covered by the end-to-end tests (`tests/`).
//! * `python` blocks are compiled by the bridge's pytest suite
//!   (`bridge/tests/test_doc_examples.py`), against the installed module.
//! * `text` blocks (folder trees, output) are not code.
//!
//! A block of any other kind, or without one, fails: say what it is.

use crate::Cli;
use clap::Parser;
use std::path::{Path, PathBuf};
use tomograf_scene::physics;
use tomograf_scene::scene::{MeshPhysics, Scene};

/// One fenced block: file, first line, info string, body.
struct Block {
    file: PathBuf,
    line: usize,
    info: String,
    body: String,
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn documents() -> Vec<PathBuf> {
    let mut files = vec![root().join("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root().join("docs"))
        .expect("docs/")
        .map(|e| e.expect("docs entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    files.extend(docs);
    files
}

/// Fenced blocks of a markdown file (``` fences at the start of a line).
fn blocks(file: &Path) -> Vec<Block> {
    let text = std::fs::read_to_string(file).expect("readable document");
    blocks_of(&text, file, "```")
}

fn blocks_of(text: &str, file: &Path, fence: &str) -> Vec<Block> {
    let mut out = Vec::new();
    let mut open: Option<Block> = None;
    for (i, line) in text.lines().enumerate() {
        let t = line.trim_start();
        match (&mut open, t.strip_prefix(fence)) {
            (None, Some(info)) => {
                open = Some(Block {
                    file: file.to_path_buf(),
                    line: i + 1,
                    info: info.trim().to_string(),
                    body: String::new(),
                })
            }
            (Some(_), Some(_)) => out.push(open.take().expect("open block")),
            (Some(b), None) => {
                b.body.push_str(line);
                b.body.push('\n');
            }
            (None, None) => {}
        }
    }
    assert!(open.is_none(), "{}: an unclosed code block", file.display());
    out
}

/// The scene examples in `scene/src/scene.rs`'s module docs (`//! ```toml` blocks).
fn scene_rs_blocks() -> Vec<Block> {
    let file = root().join("scene/src/scene.rs");
    let text = std::fs::read_to_string(&file).expect("scene.rs");
    let docs: String = text
        .lines()
        .filter_map(|l| l.strip_prefix("//!"))
        .map(|l| format!("{}\n", l.strip_prefix(' ').unwrap_or(l)))
        .collect();
    blocks_of(&docs, &file, "```")
}

fn check_scene(b: &Block) -> Result<(), String> {
    let scene: Scene = toml::from_str(&b.body).map_err(|e| format!("not a scene: {e}"))?;
    let poly = physics::acquisition(&scene)
        .map_err(|e| format!("{e:#}"))?
        .is_some();
    for (i, m) in scene.mesh.iter().enumerate() {
        if m.path.is_some() {
            continue; // a file the reader brings
        }
        let physics = if poly {
            MeshPhysics::Polychromatic
        } else {
            MeshPhysics::Monochromatic {
                energy_kev: Some(60.0),
            }
        };
        m.build(i, physics).map_err(|e| format!("{e:#}"))?;
    }
    Ok(())
}

/// The `tomograf` command lines of a shell block, continuation lines joined, comments
/// dropped, placeholders filled; each as its arguments after the program name.
fn commands(body: &str) -> Vec<Vec<String>> {
    let mut joined = Vec::new();
    let mut cur = String::new();
    for line in body.lines() {
        let l = line.split(" #").next().unwrap_or("");
        let l = if l.trim_start().starts_with('#') {
            ""
        } else {
            l
        };
        match l.trim_end().strip_suffix('\\') {
            Some(head) => cur.push_str(head),
            None => {
                cur.push_str(l);
                joined.push(std::mem::take(&mut cur));
            }
        }
    }
    let mut out = Vec::new();
    let mut vars: Vec<(String, String)> = Vec::new();
    for line in joined {
        // NAME=value or NAME="several words": remembered for later $NAME.
        if let Some((name, value)) = line.trim().split_once('=')
            && !name.is_empty()
            && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
            && (value.starts_with('"') || !value.contains(' '))
        {
            vars.push((name.to_string(), value.trim_matches('"').to_string()));
            continue;
        }
        // Commands chained with && or ;, or backgrounded with &.
        for part in line.split(['&', ';', '|']) {
            let words: Vec<&str> = part.split_whitespace().collect();
            // Leading environment assignments and wrappers (time, setsid, nohup, timeout N).
            let mut i = 0;
            while i < words.len() {
                match words[i] {
                    "time" | "setsid" | "nohup" | "env" => i += 1,
                    "timeout" => i += 2,
                    w if w.contains('=') && !w.starts_with('-') => i += 1,
                    _ => break,
                }
            }
            let rest = &words[i.min(words.len())..];
            let start = match rest {
                // Another crate's example (`-p tomograf-sim --example …`) is not the CLI.
                ["cargo", "run", tail @ ..]
                    if !tail
                        .iter()
                        .any(|w| matches!(*w, "-p" | "--package" | "--example")) =>
                {
                    match tail.iter().position(|w| *w == "--") {
                        Some(p) => 3 + p,
                        None => continue, // `cargo run --release` alone: no subcommand
                    }
                }
                [w, ..] if *w == "tomograf" || w.ends_with("/tomograf") => 1,
                _ => continue,
            };
            out.push(
                rest[start..]
                    .iter()
                    .flat_map(|w| {
                        fill(w, &vars)
                            .split_whitespace()
                            .map(String::from)
                            .collect::<Vec<_>>()
                    })
                    .collect(),
            );
        }
    }
    out
}

/// Placeholders as values of the right kind: a variable set earlier in the block → its
/// value, any other `$NAME` → `0` (a folder name or an index alike), `K/8` → `0/8`.
fn fill(word: &str, vars: &[(String, String)]) -> String {
    let w = word.trim_matches(|c| c == '"' || c == '\'');
    let mut s = String::new();
    let mut chars = w.chars().peekable();
    while let Some(c) = chars.next() {
        if c == '$' {
            let braced = chars.peek() == Some(&'{');
            if braced {
                chars.next();
            }
            let mut name = String::new();
            while let Some(&n) = chars.peek() {
                if n.is_ascii_alphanumeric() || n == '_' {
                    name.push(n);
                    chars.next();
                } else {
                    break;
                }
            }
            if braced {
                chars.next();
            }
            match vars.iter().rev().find(|(n, _)| *n == name) {
                Some((_, v)) => s.push_str(v),
                None => s.push('0'),
            }
        } else {
            s.push(c);
        }
    }
    // K/8, I/N: a shard index placeholder.
    match s.split_once('/') {
        Some((k, n))
            if k.len() == 1
                && k.chars().all(|c| c.is_ascii_uppercase())
                && (n.chars().all(|c| c.is_ascii_digit()) || n == "N") =>
        {
            format!("0/{}", if n == "N" { "2" } else { n })
        }
        _ => s,
    }
}

#[test]
fn every_documented_example_matches_the_code() {
    let mut failures = Vec::new();
    let (mut scenes, mut lines) = (0, 0);
    let mut all: Vec<Block> = documents().iter().flat_map(|f| blocks(f)).collect();
    all.extend(scene_rs_blocks());
    for b in &all {
        let at = format!("{}:{}", b.file.display(), b.line);
        let kind = b.info.split_whitespace().next().unwrap_or("");
        match kind {
            "toml" => {
                scenes += 1;
                if let Err(e) = check_scene(b) {
                    failures.push(format!("{at}: scene example: {e}"));
                }
            }
            "sh" => {
                for args in commands(&b.body) {
                    lines += 1;
                    let argv = std::iter::once("tomograf".to_string()).chain(args.clone());
                    if let Err(e) = Cli::try_parse_from(argv) {
                        let msg = e.to_string();
                        let first = msg.lines().next().unwrap_or("");
                        failures.push(format!("{at}: `tomograf {}`: {first}", args.join(" ")));
                    }
                }
            }
            "python" | "text" => {}
            other => failures.push(format!(
                "{at}: a code block of kind '{other}': mark it toml, sh, python or text"
            )),
        }
    }
    assert!(
        failures.is_empty(),
        "{} documented example(s) do not match the code:\n{}",
        failures.len(),
        failures.join("\n")
    );
    // The check must have found the examples it is about.
    eprintln!("{scenes} scene examples, {lines} command lines checked");
    assert!(scenes >= 7, "{scenes} scene examples");
    assert!(lines >= 80, "{lines} command lines");
}

#[test]
fn a_drifted_example_is_caught() {
    let bad = Block {
        file: PathBuf::from("x.md"),
        line: 1,
        info: "toml".into(),
        body: "[detector]\nmode = \"energy-integrating\"\n".into(),
    };
    assert!(
        check_scene(&bad)
            .unwrap_err()
            .contains("unknown field `mode`")
    );
    let bad = Block {
        body: "[acquisition]\npreset = \"cbct-100kvp\"\n[detector]\nmodel = \"csi\"\n".into(),
        ..bad
    };
    assert!(
        check_scene(&bad)
            .unwrap_err()
            .contains("unknown detector model")
    );
    let block = "D=\"-o out --seed 1\"\ntomograf evaluate $S/data $D --shard K/8 \\\n  \
                 --no-such-flag # note\n";
    let cmds = commands(block);
    let want = "evaluate 0/data -o out --seed 1 --shard 0/8 --no-such-flag";
    assert_eq!(
        cmds,
        vec![want.split(' ').map(String::from).collect::<Vec<_>>()]
    );
    let argv = std::iter::once("tomograf".to_string()).chain(cmds[0].clone());
    assert!(Cli::try_parse_from(argv).is_err());
}

/// The keys a section's parser accepts, from its own error for an unknown key.
fn keys_of(probe: &str) -> Vec<String> {
    let e = toml::from_str::<Scene>(probe)
        .expect_err("the probe key is unknown")
        .to_string();
    let tail = e
        .split("expected")
        .nth(1)
        .unwrap_or_else(|| panic!("no key list in: {e}"));
    tail.split('`')
        .skip(1)
        .step_by(2)
        .map(String::from)
        .collect()
}

#[test]
fn the_scene_reference_names_every_key() {
    let doc = std::fs::read_to_string(root().join("docs/scene.md")).expect("docs/scene.md");
    let section = |heading: &str| -> String {
        let start = doc
            .find(heading)
            .unwrap_or_else(|| panic!("docs/scene.md has no section {heading}"));
        let rest = &doc[start + heading.len()..];
        rest[..rest.find("\n## ").unwrap_or(rest.len())].to_string()
    };
    let p = "__probe = 1\n";
    let probes: Vec<(&str, String)> = vec![
        ("## `[volume]`", format!("[volume]\n{p}")),
        ("## `[geometry]`", format!("[geometry]\n{p}")),
        ("## `[detector]`", format!("[detector]\n{p}")),
        ("## `[detector]`", format!("[detector.response]\n{p}")),
        (
            "## `[detector]`",
            format!("[detector.response.mode]\nkind = \"energy-integrating\"\n{p}"),
        ),
        (
            "## `[detector]`",
            format!("[detector.response.scintillator]\n{p}"),
        ),
        ("## `[detector]`", format!("[detector.response.blur]\n{p}")),
        (
            "## `[detector]`",
            format!("[detector.response.readout]\n{p}"),
        ),
        (
            "## `[detector]`",
            format!("[detector.response.calibration]\n{p}"),
        ),
        ("## `[views]`", format!("[views]\n{p}")),
        ("## `[views]`", format!("[[views.explicit]]\n{p}")),
        ("## `[projector]`", format!("[projector]\n{p}")),
        ("## `[output]`", format!("[output]\n{p}")),
        ("## `[acquisition]`", format!("[acquisition]\n{p}")),
        ("## `[spectrum]`", format!("[spectrum]\n{p}")),
        ("## `[materials]`", format!("[materials]\n{p}")),
        ("## `[materials]`", format!("[[materials.bins]]\n{p}")),
        (
            "## `[scatter]`",
            format!("[scatter]\nmodel = \"monte-carlo\"\n{p}"),
        ),
        (
            "## `[scatter]`",
            format!("[scatter]\nmodel = \"estimate\"\n{p}"),
        ),
        (
            "## `[scatter]`",
            format!("[scatter]\nmodel = \"none\"\n[scatter.anti_scatter_grid]\n{p}"),
        ),
        ("## `[dose]`", format!("[dose]\n{p}")),
        ("## `[[mesh]]`", format!("[[mesh]]\n{p}")),
    ];
    let mut missing = Vec::new();
    let mut total = 0;
    for (heading, probe) in &probes {
        let text = section(heading);
        let keys = keys_of(probe);
        assert!(!keys.is_empty(), "{probe}: no keys");
        for k in keys {
            total += 1;
            if !text.contains(&format!("`{k}`")) {
                missing.push(format!(
                    "{heading}: `{k}` ({})",
                    probe.lines().next().unwrap()
                ));
            }
        }
    }
    // Every top-level section has its heading.
    for k in keys_of(p) {
        if !doc.contains(&format!("[{k}]")) {
            missing.push(format!("section [{k}]"));
        }
    }
    assert!(
        missing.is_empty(),
        "docs/scene.md does not name:\n{}",
        missing.join("\n")
    );
    assert!(total > 80, "{total} keys");
    // A key beside model = "none" is an error too (serde's unit variant would drop it).
    let e = toml::from_str::<Scene>("[scatter]\nmodel = \"none\"\nphotons = 5\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("takes no settings, found `photons`"), "{e}");
}
