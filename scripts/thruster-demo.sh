#!/usr/bin/env bash
# The servicer of examples/servicer.xml flown through its plant FMU's
# physical ports in FMPy: the thrusters fired (ctrl), a reaction wheel spun,
# the arm servoed; the attitude, rates, wheel speeds and end-effector pose
# read from its sensors (sensordata); the same flight run in MuJoCo and
# compared entry by entry.
#
#   bash scripts/thruster-demo.sh [--duration 28] [--out out/thruster-demo]
#
# Writes out/thruster-demo/servicer.png, results.json and the FMU; exits 1
# if the FMU's sensordata and MuJoCo's differ by more than 1e-6.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

bash scripts/setup.sh
cargo build --release --workspace
.venv/bin/python scripts/thruster_demo.py "$@"
