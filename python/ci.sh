#!/usr/bin/env bash
# The Python package's tests (docs/PYTHON.md): a fresh venv, the package installed from this
# repository with one `pip install`, the `vps` binary the tests compare against, and pytest.
# Needs only the package registries (PyPI, crates.io). Run from anywhere:
#   bash python/ci.sh
# VPS_PY_VENV picks the venv's directory (default: target/py-venv, made anew each run).
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
target="${CARGO_TARGET_DIR:-$repo/target}"
venv="${VPS_PY_VENV:-$target/py-venv}"

rm -rf "$venv"
python3 -m venv "$venv"
py="$venv/bin/python"
"$py" -m pip install -q maturin pytest numpy "zstandard>=0.23" "dask[distributed]"
# The package is built unoptimised (the `dev` profile) for the tests: a release build from
# scratch takes minutes on a small CI machine. Users install with plain `pip install ./python`.
# The `vps` binary the tests compare against is the one `cargo test` just built (`test` profile).
CARGO_TARGET_DIR="$target" "$py" -m pip install -q "$repo/python" --config-settings=build-args="--profile=dev"

cargo build -q --profile test -p vps-cli
export VPS_BIN="$target/debug/vps"

cd "$repo"
"$py" -m pytest python/tests -q -p no:cacheprovider
