#!/usr/bin/env bash
# Regenerate docs/bench/ (results.json, table.md, work_precision.png,
# tolerance.json, tolerance.md, tolerance.png, methods.*, auto.*,
# scaling.png): set up, build, and run every benchmark of
# docs/performance.md. About 15 minutes on 2 cores; the machine should
# be otherwise idle, although every comparison is timed side by side.
#
#   bash scripts/bench.sh [--out DIR] [--quick]
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

bash scripts/setup-test.sh
cargo build --release --workspace
.venv/bin/python scripts/bench.py "$@"
.venv/bin/python scripts/bench_tolerance.py "$@"
.venv/bin/python scripts/bench_methods.py "$@"
.venv/bin/python scripts/bench_auto.py "$@"
.venv/bin/python scripts/bench_auto.py --work-precision "$@"
