#!/usr/bin/env bash
# Tests of the Python bridge (docs/python.md), called by scripts/test.sh after the Rust
# tests: a virtual environment with the test packages (bridge/requirements-test.txt),
# libLLVM 19 for Mitsuba's llvm_ad_mono variant (apt-get, when missing), the module built
# and installed by `pip install ./bridge` (maturin), then pytest: the API, independent readers (nibabel, OpenImageIO) and the
# Mitsuba cross-validation (in its own process). Idempotent and quiet: packages are
# reinstalled only when the requirements file changes.
# Environment: TOMOGRAF_VENV (default .venv), PYTHON (default python3), TOMOGRAF_BIN (the
# CLI to test; built with `cargo build --release` when unset).
set -euo pipefail
cd "$(dirname "$0")/.."
venv="${TOMOGRAF_VENV:-.venv}"
py="${PYTHON:-python3}"
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
apt_get() { $sudo env DEBIAN_FRONTEND=noninteractive apt-get -qq -o=Dpkg::Use-Pty=0 "$@" >/dev/null; }
libllvm() { ls /usr/lib/*/libLLVM.so.19* 2>/dev/null | head -n1; }

if [ -z "$(libllvm)" ]; then
  apt_get update && apt_get install -y libllvm19
fi
if [ ! -x "$venv/bin/python" ]; then
  "$py" -m venv "$venv" 2>/dev/null || {
    rm -rf "$venv"
    apt_get update && apt_get install -y python3-venv && "$py" -m venv "$venv"
  }
fi
venv="$("$venv/bin/python" -c 'import sys; print(sys.prefix)')"
stamp="$venv/.tomograf-requirements"
if ! cmp -s bridge/requirements-test.txt "$stamp"; then
  "$venv/bin/python" -m pip install -q --disable-pip-version-check -r bridge/requirements-test.txt
  cp bridge/requirements-test.txt "$stamp"
fi
export DRJIT_LIBLLVM_PATH="${DRJIT_LIBLLVM_PATH:-$(libllvm)}"
# The documented install (docs/python.md): a wheel built from bridge/ and installed, not an
# editable build, so that what the tests import is what users get.
"$venv/bin/python" -m pip install -q --disable-pip-version-check --force-reinstall --no-deps ./bridge
# The CLI the tests drive: TOMOGRAF_BIN when the caller built it (scripts/test.sh), else built here.
if [ -z "${TOMOGRAF_BIN:-}" ]; then
  cargo build --release --quiet --bin tomograf
  export TOMOGRAF_BIN="$PWD/target/release/tomograf"
fi
"$venv/bin/python" -m pytest -q -p no:cacheprovider --durations=8 bridge/tests
