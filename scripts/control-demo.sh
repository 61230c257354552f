#!/usr/bin/env bash
# Noninteracting control, closed loop in two FMI masters: the plant FMU
# (`nudyn export`) and the controller FMU (`nudyn export --controller`) of
# examples/bus_arm7.xml, connected name to name, run in FMPy and in libcosim.
#
#   bash scripts/control-demo.sh detumble   # rate feedback eps = -c1 nu from a tumble
#   bash scripts/control-demo.sh arm        # end effector to a target pose, base floating
#
# Writes docs/control/SCENARIO.png and out/control/SCENARIO/ (the FMUs,
# libcosim/OspSystemStructure.xml, results.json); prints a table and the
# checks; exits 1 if a check fails.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
case "${1:-}" in
    detumble | arm) ;;
    *) echo "usage: bash scripts/control-demo.sh detumble|arm" >&2; exit 2 ;;
esac

bash scripts/setup-test.sh
cargo build --release --workspace
.venv/bin/python scripts/control_demo.py "$1"
