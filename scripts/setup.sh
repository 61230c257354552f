#!/usr/bin/env bash
# Install what nudyn's build and tests need, on a fresh Debian machine (run
# as root, or with sudo available).  Idempotent: a rerun with everything in
# place touches nothing and takes about a second.
#
#   - Debian: libclang-dev, valgrind (only if missing: checked with dpkg -s);
#   - cargo-fuzz (cargo install --locked, only if `cargo fuzz` is missing);
#   - Python: a venv at .venv (repo root) with requirements.txt's pins.
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
missing=()
dpkg -s libclang-dev >/dev/null 2>&1 || missing+=(libclang-dev)
dpkg -s valgrind >/dev/null 2>&1 || missing+=(valgrind)
# Debian's own python3 cannot make a venv without python3-venv (ensurepip).
"$PYTHON" -c 'import ensurepip, venv' >/dev/null 2>&1 || missing+=(python3-venv)
if [ "${#missing[@]}" -gt 0 ]; then
    echo "setup: installing ${missing[*]}"
    as_root apt-get update
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y "${missing[@]}"
fi

# --- cargo-fuzz (scripts/stress-fmu.sh) ----------------------------------------
if ! cargo fuzz --version >/dev/null 2>&1; then
    echo "setup: installing cargo-fuzz"
    cargo install --locked cargo-fuzz
fi

# --- Python venv --------------------------------------------------------------
if [ ! -x "$VENV/bin/python" ] || ! "$VENV/bin/python" -c 'import sys' >/dev/null 2>&1; then
    echo "setup: creating $VENV"
    rm -rf "$VENV"
    "$PYTHON" -m venv "$VENV"
fi

# Reinstall only when requirements.txt changed since the last successful
# install, or the packages cannot be imported any more.
stamp="$VENV/.requirements.sha256"
want="$(sha256sum "$REQ" | cut -d' ' -f1)"
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ] \
    || ! "$VENV/bin/python" -c 'import mujoco, fmpy, numpy, pytest, matplotlib, libcosimpy, pinocchio, tqdm' >/dev/null 2>&1; then
    echo "setup: installing Python packages from requirements.txt"
    "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -r "$REQ"
    echo "$want" >"$stamp"
fi
echo "setup: ok ($("$VENV/bin/python" -c 'import mujoco, numpy; print("mujoco", mujoco.__version__, "numpy", numpy.__version__)'))"
