#!/usr/bin/env bash
# Install what the tests need beyond the main job: first everything of
# scripts/setup.sh, then (only what is missing)
#
#   - Debian: valgrind (scripts/stress-fmu.sh's memory check), wine64 and
#     gcc-mingw-w64-x86-64 (tests/python/test_win64.py runs the win64 binary
#     under wine; scripts/build-windows.sh installs the rest of the Windows
#     build);
#   - cargo-fuzz (cargo install --locked; scripts/stress-fmu.sh's fuzzing);
#   - Python: requirements-test.txt's pins into .venv (pytest and pytest-xdist; libcosimpy
#     for the closed-loop demos; pin and tqdm for scripts/bench.py).
#
# scripts/test.sh runs it in two halves, like setup.sh's: `system` (the
# Debian packages and cargo-fuzz, which the Rust builds need) and then
# `python` (the venv) beside the builds. Without an argument it does both.
# Idempotent like setup.sh: a rerun with everything in place touches nothing.
#
# Environment: PYTHON, as for setup.sh.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
VENV="$ROOT/.venv"
REQ="$ROOT/requirements-test.txt"

as_root() {
    if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi
}

# --- Debian packages and cargo-fuzz -----------------------------------------
system_tools() {
    bash scripts/setup.sh system
    missing=()
    for package in valgrind wine64 gcc-mingw-w64-x86-64 calculix-ccx; do
        dpkg -s "$package" >/dev/null 2>&1 || missing+=("$package")
    done
    if [ ${#missing[@]} -gt 0 ]; then
        echo "setup-test: installing ${missing[*]}"
        as_root apt-get update
        as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y "${missing[@]}"
    fi

    # cargo-fuzz (scripts/stress-fmu.sh)
    if ! cargo fuzz --version >/dev/null 2>&1; then
        echo "setup-test: installing cargo-fuzz"
        cargo install --locked cargo-fuzz
    fi
}

# --- Python packages ----------------------------------------------------------
python_packages() {
    bash scripts/setup.sh python
    # requirements-test.txt includes requirements.txt, so the stamp covers both:
    # reinstall when either changed since the last successful install, or the
    # test packages cannot be imported any more.
    stamp="$VENV/.requirements-test.sha256"
    want="$(cat "$ROOT/requirements.txt" "$REQ" | sha256sum | cut -d' ' -f1) bytecode"
    if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ] \
        || ! "$VENV/bin/python" -c 'import pytest, xdist, libcosimpy, pinocchio, tqdm' >/dev/null 2>&1; then
        echo "setup-test: installing Python packages from requirements-test.txt"
        # uv, which scripts/setup.sh installed into the venv, with the
        # bytecode written now (setup.sh's install_pins says why).
        "$VENV/bin/uv" pip install --quiet --compile-bytecode --python "$VENV/bin/python" -r "$REQ"
        echo "$want" >"$stamp"
    fi
    echo "setup-test: ok ($("$VENV/bin/python" -c 'import pytest, pinocchio; print("pytest", pytest.__version__, "pinocchio", pinocchio.__version__)'))"
}

# Called as plain commands, not in a && list, where set -e would not stop them.
case "${1:-all}" in
all)
    system_tools
    python_packages
    ;;
system) system_tools ;;
python) python_packages ;;
*)
    echo "usage: bash scripts/setup-test.sh [system|python]" >&2
    exit 2
    ;;
esac
