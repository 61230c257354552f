#!/usr/bin/env bash
# nudyn's whole test suite: setup, Rust build and tests, Python tests
# against MuJoCo.  Fails if any step fails.
#
#   bash scripts/test.sh
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

bash scripts/setup.sh

cargo build --release --workspace
cargo test --release --workspace

NUDYN_BIN=target/release/nudyn \
    .venv/bin/python -m pytest tests/python -q
