#!/usr/bin/env bash
# Install what the main job (scripts/demo.sh) needs, on a fresh Debian
# machine with the Rust toolchain (run as root, or with sudo available).
# Idempotent: a rerun with everything in place touches nothing and takes
# about a second.
#
#   - Debian: libclang-dev (fmi-sys runs bindgen at build time), and
#     python3-venv if the interpreter cannot make a venv (only what is
#     missing: checked with dpkg -s);
#   - Python: a venv at .venv (repo root) with requirements.txt's pins
#     (mujoco, fmpy, numpy, matplotlib, dask, pyarrow, tqdm), installed
#     by uv (itself pip-installed into the venv); the
#     repository's python/ packages on the venv's path (a .pth file, so
#     that Dask workers started from the venv import them too) and the
#     command .venv/bin/nudyn-campaign.
#
# The tests need more (valgrind, cargo-fuzz, requirements-test.txt):
# scripts/setup-test.sh runs this script and then installs those.
#
#   bash scripts/setup.sh           # both
#   bash scripts/setup.sh system    # the Debian packages only
#   bash scripts/setup.sh python    # the venv only (after `system`)
#
# The halves exist so that scripts/test.sh can build the Rust code, which
# needs only the Debian packages, while the venv is being installed.
#
# Environment: PYTHON (default python3) is the interpreter the venv is made from.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
PYTHON="${PYTHON:-python3}"
VENV="$ROOT/.venv"
REQ="$ROOT/requirements.txt"

as_root() {
    if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi
}

# --- Debian packages --------------------------------------------------------
debian_packages() {
    missing=()
    dpkg -s libclang-dev >/dev/null 2>&1 || missing+=(libclang-dev)
    # Debian's own python3 cannot make a venv without python3-venv (ensurepip).
    "$PYTHON" -c 'import ensurepip, venv' >/dev/null 2>&1 || missing+=(python3-venv)
    if [ "${#missing[@]}" -gt 0 ]; then
        echo "setup: installing ${missing[*]}"
        as_root apt-get update
        as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y "${missing[@]}"
    fi
}

# --- Python venv, the repository's Python packages and nudyn-campaign -------
# uv installs the pins (the versions pip resolves, measured the same) in
# about 5 CPU-s where pip took 40: it fetches in parallel. It is
# pip-installed into the venv first, at its own pin; scripts/setup-test.sh
# uses it too (install_pins). --compile-bytecode: the packages' .pyc are
# written once, here, on every core. uv leaves them to the first import
# otherwise, and where PYTHONDONTWRITEBYTECODE is set (as on the machines
# the suite is timed on) no import writes them: every Python process the
# tests start (pytest's workers, Dask's, validate.py, the campaign and
# bench commands) compiled matplotlib, dask and the rest again, about 1
# CPU-s each. With the .pyc the Python tests took 421 CPU-s where they took
# 492 without (the same pins, pytest -n 2, side by side on a loaded
# 2-core machine, 2026-11-30); writing them here costs about 9.
UV_PIN="uv==0.13.8"
install_pins() {
    if [ "$("$VENV/bin/uv" --version 2>/dev/null | cut -d' ' -f2)" != "${UV_PIN#uv==}" ]; then
        "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check "$UV_PIN"
    fi
    "$VENV/bin/uv" pip install --quiet --compile-bytecode --python "$VENV/bin/python" -r "$1"
}

python_venv() {
    if [ ! -x "$VENV/bin/python" ] || ! "$VENV/bin/python" -c 'import sys' >/dev/null 2>&1; then
        echo "setup: creating $VENV"
        rm -rf "$VENV"
        "$PYTHON" -m venv "$VENV"
    fi

    # Reinstall only when requirements.txt changed since the last successful
    # install, or the packages cannot be imported any more.
    stamp="$VENV/.requirements.sha256"
    # The stamp names the bytecode too: a venv installed before uv wrote it
    # is installed once more, which writes it.
    want="$(sha256sum "$REQ" | cut -d' ' -f1) bytecode"
    if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ] \
        || ! "$VENV/bin/python" -c 'import mujoco, fmpy, numpy, matplotlib, dask.distributed, pyarrow, tqdm' >/dev/null 2>&1; then
        echo "setup: installing Python packages from requirements.txt"
        install_pins "$REQ"
        echo "$want" >"$stamp"
    fi
    site="$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
    if [ "$(cat "$site/nudyn.pth" 2>/dev/null)" != "$ROOT/python" ]; then
        echo "$ROOT/python" >"$site/nudyn.pth"
    fi
    command="$VENV/bin/nudyn-campaign"
    wanted="#!/bin/sh
exec \"$VENV/bin/python\" -m nudyn_campaign \"\$@\""
    if [ "$(cat "$command" 2>/dev/null)" != "$wanted" ]; then
        printf '%s\n' "$wanted" >"$command"
        chmod +x "$command"
    fi
    echo "setup: ok ($("$VENV/bin/python" -c 'import mujoco, numpy; print("mujoco", mujoco.__version__, "numpy", numpy.__version__)'))"
}

case "${1:-all}" in
# Called as plain commands, not in a && list, where set -e would not stop them.
all)
    debian_packages
    python_venv
    ;;
system)
    debian_packages
    echo "setup: Debian packages ok"
    ;;
python) python_venv ;;
*)
    echo "usage: bash scripts/setup.sh [system|python]" >&2
    exit 2
    ;;
esac
