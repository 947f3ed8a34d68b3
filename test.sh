#!/usr/bin/env bash
# Every test: the Rust workspace's, then the Python package's, built and installed into a
# virtual environment of pinned packages (python/requirements-test.txt) under the target
# folder. Needs the Rust toolchain and Python 3.9 or newer (with venv and pip); the Python
# packages come from PyPI.
# `./test.sh python` runs only the Python part (CI runs the Rust tests itself first).
set -euo pipefail
cd "$(dirname "$0")"
# The release profile without whole-program optimisation (Cargo.toml): the same code, without
# a whole-program link for each test binary.
export CARGO_PROFILE_RELEASE_LTO=false CARGO_PROFILE_RELEASE_CODEGEN_UNITS=16
# Also builds target/release/gencyl (for the CLI's integration tests), which the Python tests
# compare against.
[ "${1:-}" = python ] || cargo test --release --workspace

target="${CARGO_TARGET_DIR:-$PWD/target}"
venv="$target/python-venv"
python="${PYTHON:-python3}"
[ -x "$venv/bin/python" ] || "$python" -m venv "$venv"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r python/requirements-test.txt
# The package as a user installs it (`pip install ./python`), with the pinned maturin.
PATH="$venv/bin:$PATH" "$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
  --no-build-isolation --no-deps --force-reinstall ./python
# From the repository's root, so that python/gencyl (no native module) does not shadow the
# installed package.
GENCYL_BIN="$target/release/gencyl" "$venv/bin/python" -m pytest -q -p no:cacheprovider python/tests
