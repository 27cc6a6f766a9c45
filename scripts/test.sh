#!/usr/bin/env bash
# Every test: the workspace's (Rust: unit, end-to-end, GUI) and the Python package's.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo test --workspace
scripts/test-python.sh
