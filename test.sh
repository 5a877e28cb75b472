#!/usr/bin/env bash
# Every test: the Rust workspace's (`cargo test`), then the Python package's (python/ci.sh:
# a fresh venv, `pip install ./python`, pytest). The README's test command; CI runs it too.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")"
cargo test
bash python/ci.sh
