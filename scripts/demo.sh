#!/usr/bin/env bash
# The README's first command: on a fresh Debian machine with the Rust
# toolchain (as root), install what is needed, build nudyn, export the
# bundled example vehicle as an FMU and validate it against MuJoCo.
#
#   bash scripts/demo.sh
#
# Writes out/validation/bus_arm7/: bus_arm7.fmu, bus_arm7.png (trajectories
# and errors over time), table.md (max errors, run times, energy drift) and
# results.json, and prints the table and where they are.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

bash scripts/setup.sh
cargo build --release --workspace
.venv/bin/python scripts/validate.py examples/bus_arm7.xml --out out/validation/bus_arm7
