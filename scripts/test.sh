#!/usr/bin/env bash
# The full test command (README "Run every test"; .ci/run calls exactly this).
# Formatting and lints first (cheap), then every Rust test in the workspace with
# optimised code (the tests render real-sized volumes).
set -euo pipefail
cd "$(dirname "$0")/.."
# Each phase's wall time goes to stderr (CI must stay under 30 min: whoever trims it reads these).
phase() { echo "scripts/test.sh: $1 took $((SECONDS - start)) s" >&2; start=$SECONDS; }
start=$SECONDS
cargo fmt --all -- --check
cargo clippy --workspace --all-targets --release --quiet -- -D warnings
python3 scripts/module_cycles.py # no module imports itself through others (docs/architecture.md)
phase "fmt + clippy"
# Examples are user commands (docs name them), not tests: clippy --all-targets above checks
# they compile, so they are not linked again here (≈ 25 CPU-s, 22 binaries).
cargo test --workspace --release --lib --bins --tests
cargo test --workspace --release --doc
phase "cargo test (build + run)"

# Python bridge: module build, pytest (API, nibabel/OpenImageIO readers, Mitsuba 3
# cross-validation); installs its own virtualenv and libLLVM 19 (see bridge/test.sh).
# It uses the CLI binary `cargo test` just built: `cargo build` would resolve other
# features (dev-dependencies off) and compile the whole burn stack a second time.
TOMOGRAF_BIN="$PWD/target/release/tomograf" bridge/test.sh
phase "Python bridge"
