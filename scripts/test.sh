#!/usr/bin/env bash
# nudyn's whole test suite: setup, formatting and lints (rustfmt, clippy
# with warnings denied), Rust build and tests, Python tests against MuJoCo,
# the FMU's memory and fuzz checks (briefly; see scripts/stress-fmu.sh
# --long), the win64 binary under wine, the wheel in a fresh venv.  Fails if
# any step fails.
#
#   bash scripts/test.sh
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

bash scripts/setup-test.sh

cargo fmt --all --check
(cd fuzz && cargo fmt --check)
cargo clippy --release --workspace --all-targets -- -D warnings

cargo build --release --workspace
cargo test --release --workspace
# The win64 FMU binary: every FMU the tests export carries it, and
# tests/python/test_win64.py runs it under wine.
bash scripts/build-windows.sh
# The wheel (both platforms' binaries): tests/python/test_wheel.py installs it.
bash scripts/build-wheel.sh

NUDYN_BIN=target/release/nudyn \
    .venv/bin/python -m pytest tests/python -q --durations=25

bash scripts/stress-fmu.sh
