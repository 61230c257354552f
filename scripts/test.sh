#!/usr/bin/env bash
# nudyn's whole test suite: setup, formatting and lints (rustfmt, clippy
# with warnings denied), Rust build and tests, Python tests against MuJoCo,
# the FMU's memory and fuzz checks (briefly; see scripts/stress-fmu.sh
# --long), the win64 binary under wine, the wheel in a fresh venv.  Fails if
# any step fails.
#
#   bash scripts/test.sh
#
# On 2 cores the Rust builds leave one core idle for long stretches (one
# crate, or a link, at a time), so the venv's installation, the win64
# cross-build and the fuzz targets' sanitizer build (separate target
# folders) run beside clippy and the main build. The Python tests run on
# every core (pytest-xdist, a test file per worker); the memory checks and
# the fuzz targets run beside them at low priority, on the time the tests
# spend waiting for their subprocesses. Each stage's time is printed at the end.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
LOGS="$ROOT/target/test-logs"
mkdir -p "$LOGS"
TIMES=()

# Runs COMMAND... in a shell of its own that writes, when the command has
# ended, its CPU time (user and system, of everything it started) to FILE:
#   cpu_measured FILE COMMAND...
# Measured inside, not as the script's children's time: bash reaps a
# background stage when it ends, which adds its time to the foreground stage
# running then.
CPU_MEASURED='"${@:2}"; status=$?; times >"$1"; exit $status'
cpu_measured() {
    bash -c "$CPU_MEASURED" _ "$@"
}
# Prints the CPU seconds in FILE: `times`' second line, the children's user
# and system time ("1m2.345s 0m0.678s").
cpu_seconds() {
    sed -n 2p "$1" | tr 'ms' '  ' | awk '{ printf "%d", $1 * 60 + $2 + $3 * 60 + $4 }'
}

# Runs NAME COMMAND... and records how long it took, and its CPU time.
stage() {
    local name=$1 start=$SECONDS
    shift
    echo "test.sh: $name"
    cpu_measured "$LOGS/cpu.txt" "$@"
    TIMES+=("$(printf '%5d s %5d s CPU  %s' $((SECONDS - start)) "$(cpu_seconds "$LOGS/cpu.txt")" "$name")")
}

# Starts NAME COMMAND... in the background, in a process group of its own
# (stopped with the script if a stage fails), its output in
# target/test-logs/NAME.log.
declare -A STARTED PIDS
background() {
    local name=$1
    shift
    echo "test.sh: $name (in the background, log in $LOGS/$name.log)"
    STARTED[$name]=$(date +%s)
    setsid bash -c "$CPU_MEASURED" _ "$LOGS/$name.cpu" "$@" >"$LOGS/$name.log" 2>&1 &
    PIDS[$name]=$!
}
stop_background() {
    local pid
    for pid in "${PIDS[@]}"; do
        kill -- "-$pid" 2>/dev/null || true
    done
}
trap stop_background EXIT

# Waits for a background stage; prints its log's last LINES lines (3 unless
# given) and fails if it failed:
#   finish NAME [LINES]
finish() {
    local name=$1 lines=${2:-3} status=0
    wait "${PIDS[$name]}" || status=$?
    unset "PIDS[$name]"
    if [ "$status" -ne 0 ]; then
        cat "$LOGS/$name.log" >&2
        echo "test.sh: $name failed (exit $status)" >&2
        exit "$status"
    fi
    tail -n "$lines" "$LOGS/$name.log"
    # Its CPU time was written when it ended.
    TIMES+=("$(printf '%5d s %5d s CPU  %s (in the background)' $(($(stat -c %Y "$LOGS/$name.cpu") - STARTED[$name])) \
        "$(cpu_seconds "$LOGS/$name.cpu")" "$name")")
}

# The Rust builds need the Debian packages (libclang for bindgen, mingw) and
# cargo-fuzz; the venv is needed from the wheel on, so it is installed beside them.
stage "setup (Debian packages, cargo-fuzz)" bash scripts/setup-test.sh system
background setup-python bash scripts/setup-test.sh python

stage rustfmt cargo fmt --all --check
stage "rustfmt (fuzz)" bash -c 'cd fuzz && cargo fmt --check'
# cargo fuzz build updates a stale lock file silently; this says so instead.
stage "lock file (fuzz)" bash -c 'cd fuzz && cargo metadata --locked --format-version 1 >/dev/null'
# The wheel and one Python test build a crate alone: workspace-hack must give
# them the workspace's features, or they compile the tree a second time.
stage "unified features" python3 scripts/check-unified-features.py

# The win64 FMU binary: every FMU the tests export carries it, and
# tests/python/test_win64.py runs it under wine.
background build-windows bash scripts/build-windows.sh
# The fuzz targets' build (address sanitizer): scripts/stress-fmu.sh runs them.
background build-fuzz bash scripts/stress-fmu.sh --build

stage clippy cargo clippy --release --workspace --all-targets -- -D warnings
# Every target the tests use but the crates' unit tests (below), at once:
# the libraries and binaries are built with the same features as the tests
# (dev-dependencies add features to shared crates), so `cargo test` below
# reuses them instead of building the tree a second time. Not the criterion
# benchmark (bench/benches), which nothing here runs: clippy above checks it.
stage "cargo build" cargo build --release --workspace --lib --bins --test '*' --examples
stage "cargo test" cargo test --release --workspace --test '*'
stage "cargo test (doc)" cargo test --release --workspace --doc
# The crates' unit tests (their #[cfg(test)] modules) compile each crate a
# second time, in test mode: at opt-level 3 that took about 95 CPU-s (49
# the core crate's), at 0 it takes 42 and the tests run in 4 (the same
# tests, and the same numbers: Rust's floating point does not depend on the
# optimization level). Cargo's
# bench profile is the release profile and shares its folder, so the
# dependencies are reused; only the workspace's own crates are built again,
# at opt-level 0. On the command line, not in Cargo.toml: `cargo bench`
# (the criterion benchmark) must keep the crates optimized.
unit_test_config=()
for package in nudyn nudyn-contract nudyn-fmu nudyn-cli modeldescription workspace-hack; do
    unit_test_config+=(--config "profile.bench.package.$package.opt-level=0")
done
# nudyn-bench: no unit tests (its Cargo.toml), and its binary would be built optimized.
stage "cargo test (unit tests)" cargo test --profile bench --workspace --exclude nudyn-bench --lib --bins \
    "${unit_test_config[@]}"

finish setup-python
finish build-windows
# The wheel (both platforms' binaries): tests/python/test_wheel.py installs it.
stage wheel bash scripts/build-wheel.sh

# Valgrind and the fuzz targets (a fixed number of inputs each, not a time:
# scripts/stress-fmu.sh) at the lowest priority, beside the Python tests:
# they take the cores the tests leave idle. `nice` alone would not do: each
# background stage is a session of its own (setsid), and where the kernel
# groups the CPU by session (sched_autogroup), a session's share is set by
# its group's niceness (/proc/self/autogroup), not by its processes'.
finish build-fuzz
background stress-fmu bash -c 'echo 19 2>/dev/null >/proc/self/autogroup; exec nice -n 19 bash scripts/stress-fmu.sh'

# NUDYN_FMU_LIB: the FMU library just built (the tests' fixture would
# otherwise build it again for nudyn-fmu alone, with other features).
stage "Python tests" env NUDYN_BIN=target/release/nudyn NUDYN_FMU_LIB="$ROOT/target/release/libnudyn_fmu.so" \
    .venv/bin/python -m pytest tests/python -q --durations=25 --numprocesses auto --dist loadfile \
    --no-loadscope-reorder

finish stress-fmu 20

times >"$LOGS/cpu.txt"
echo "test.sh: ok; times (wall, CPU):"
printf '%s\n' "${TIMES[@]}"
printf '%5d s %5d s CPU  in all\n' "$SECONDS" "$(cpu_seconds "$LOGS/cpu.txt")"
