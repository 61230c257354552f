#!/usr/bin/env bash
# The FMU's memory and fuzz checks (the misuse suite and the concurrency
# test are in tests/python/test_fmu_misuse.py):
#
#   - memory: tests/memory/fmu_runs.c and fmu3_runs.c, plain C importers of
#     the FMI 2.0 and FMI 3.0 FMU (co-simulation and model exchange), under valgrind:
#     instantiate → 1000 steps (with FMU states, refused calls, huge counts) → free,
#     1 time and RUNS times; nothing lost, and the memory in use at exit the
#     same for both (no growth with the number of runs);
#   - fuzzing: each cargo fuzz target (fuzz/), seeded with the examples, for
#     a fixed number of inputs (about what one quiet core ran in 15 s), or
#     600 s each with --long; a crash leaves its input in fuzz/artifacts/
#     and fails the script.
#
# The memory checks and the fuzz targets run as many at once as there are
# cores, each on one. A number of inputs, not a time, is the CI's measure of
# fuzzing: scripts/test.sh runs this script at low priority beside the
# Python tests, where a time limit would shrink the work to what the tests
# leave over.
#
#   bash scripts/stress-fmu.sh           # CI: RUNS=3, FUZZ_INPUTS per target
#   bash scripts/stress-fmu.sh --long    # RUNS=20, 600 s per target
#   bash scripts/stress-fmu.sh --build   # only build the fuzz targets
#
# Needs what scripts/setup.sh installs (valgrind, cargo-fuzz) and the
# release build (target/release/nudyn, libnudyn_fmu.so).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
RUNS=3
# Inputs per target: what each ran in 15 s on one core of a quiet 2-core CI
# machine (2026-11-30), rounded down; the FMI targets step FMUs, hence far fewer.
declare -A FUZZ_INPUTS=([mjcf_import]=50000 [resource_loader]=50000 [state_deserializer]=900
    [call_sequence]=500 [call_sequence_fmi3]=5000)
FUZZ_SECONDS=
# libFuzzer's -timeout per input is wall-clock time. Beside the Python tests
# at the lowest priority a fuzzer may get a few per cent of a core, so an
# input that takes 0.6 s (the 1500-deep seed chain, instrumented) ran past
# 20 s there while other builds shared the machine; the CI's short run allows
# 120 s, which still stops a hang. --long, a core per target, keeps 20 s and
# so still finds the slow inputs.
INPUT_TIMEOUT=120
if [ "${1:-}" = "--long" ]; then
    RUNS=20
    FUZZ_SECONDS=600
    INPUT_TIMEOUT=20
fi

# cargo fuzz needs nightly flags (-Zsanitizer); the stable toolchain accepts
# them with RUSTC_BOOTSTRAP=1.
export RUSTC_BOOTSTRAP=1
# libFuzzer itself: clang's prebuilt runtime where libclang-dev brought it
# (Debian's libclang-rt-NN-dev, which it recommends), instead of
# libfuzzer-sys compiling its copy of libFuzzer's C++ sources (33 CPU-s).
# Set for the build and the runs alike: when it changes, libfuzzer-sys
# rebuilds and every target relinks.
runtime="$(ls /usr/lib/llvm-*/lib/clang/*/lib/linux/libclang_rt.fuzzer-x86_64.a 2>/dev/null | sort -V | tail -1)"
[ -z "$runtime" ] || export CUSTOM_LIBFUZZER_PATH="$runtime"
# The targets without line tables (cargo fuzz asks for them): with the
# sanitizers' instrumentation they took 34 of the build's 167 CPU-s
# (2026-11-30). A crash's report still names the functions (symbols stay);
# its input, rerun by `cargo fuzz run TARGET fuzz/artifacts/...` without
# this, gives the lines. Set for the build and the runs alike, as above.
export RUSTFLAGS="${RUSTFLAGS:+$RUSTFLAGS }-Cdebuginfo=0"
if [ "${1:-}" = "--build" ]; then
    cd fuzz
    exec nice cargo fuzz build --release
fi

WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT

# --- memory ---------------------------------------------------------------------
target/release/nudyn export examples/bus_arm7.xml -o "$WORK/bus.fmu" --outputs qvel,kinetic_energy,power,momentum \
    >/dev/null
PYTHONPATH=python .venv/bin/python - "$WORK/bus.fmu" "$WORK/bus" >"$WORK/fmu.txt" <<'EOF'
import sys
from nudyn_driver.package import FmuPackage
fmu = FmuPackage.unzip(sys.argv[1], sys.argv[2])
print(fmu.model_identifier, fmu.guid, len(fmu.reals), fmu.nq + fmu.nv)
EOF
read -r IDENTIFIER GUID REALS NX <"$WORK/fmu.txt"
gcc -O1 -g -Wall -Wextra -Werror -o "$WORK/fmu_runs" tests/memory/fmu_runs.c -ldl -lm

# FMI 3.0: the same vehicle, co-simulation and model exchange.
target/release/nudyn export examples/bus_arm7.xml -o "$WORK/bus3.fmu" --fmi-version 3 \
    --outputs qvel,kinetic_energy,power,momentum >/dev/null
.venv/bin/python - "$WORK/bus3.fmu" "$WORK/bus3" >"$WORK/fmu3.txt" <<'EOF'
import math, sys
from fmpy import extract, read_model_description
extract(sys.argv[1], sys.argv[2])
md = read_model_description(sys.argv[1])
v = {x.name: x for x in md.modelVariables}
size = lambda name: math.prod(int(d.start) for d in v[name].dimensions)
print(md.coSimulation.modelIdentifier, md.instantiationToken, v["theta"].valueReference, size("theta"),
      v["nu"].valueReference, size("nu"), v["der(nu)"].valueReference)
EOF
read -r IDENTIFIER3 TOKEN3 THETA_VR NQ NU_VR NV DER_NU_VR <"$WORK/fmu3.txt"
gcc -O1 -g -Wall -Wextra -Werror -o "$WORK/fmu3_runs" tests/memory/fmu3_runs.c -ldl -lm

# Runs an importer under valgrind: NAME RUNS, then the importer's command
# line before its RUNS STEPS arguments. Prints the bytes in use at exit;
# fails on any error or lost byte.
in_use_after() {
    local name=$1 runs=$2
    shift 2
    local log="$WORK/valgrind-$name-$runs.txt"
    if ! valgrind --leak-check=full --show-leak-kinds=definite,indirect,possible \
        --errors-for-leak-kinds=definite,indirect,possible --error-exitcode=99 \
        "$@" "$runs" 1000 >"$log" 2>&1; then
        cat "$log" >&2
        echo "stress-fmu: valgrind found errors or leaks in $runs runs of $name" >&2
        return 1
    fi
    grep -o 'in use at exit: [0-9,]* bytes' "$log" | tr -dc '0-9'
}
# The 1-run and RUNS-run checks of one FMI version (run beside the fuzzers below).
check_memory() {
    local version=$1 importer one many
    if [ "$version" = fmi2 ]; then
        importer=("$WORK/fmu_runs" "$WORK/bus" "$IDENTIFIER" "$GUID" "$REALS" "$NX")
    else
        importer=("$WORK/fmu3_runs" "$WORK/bus3" "$IDENTIFIER3" "$TOKEN3" "$THETA_VR" "$NQ" "$NU_VR" "$NV" "$DER_NU_VR")
    fi
    one=$(in_use_after "$version" 1 "${importer[@]}")
    many=$(in_use_after "$version" "$RUNS" "${importer[@]}")
    echo "stress-fmu: valgrind ($version): no errors, nothing lost; in use at exit after 1 run: $one bytes," \
        "after $RUNS runs: $many bytes"
    if [ "$one" != "$many" ]; then
        echo "stress-fmu: memory in use at exit grows with the number of runs ($version)" >&2
        return 1
    fi
}
# --- fuzzing --------------------------------------------------------------------
SEEDS="$WORK/seeds"
mkdir -p "$SEEDS/mjcf_import" "$SEEDS/resource_loader" "$SEEDS/state_deserializer" "$SEEDS/call_sequence" \
    "$SEEDS/call_sequence_fmi3"
for file in examples/*.xml tests/fixtures/{mjcf,actuators,sensors}/*.xml; do
    # Named by directory too: fixture names repeat across directories.
    cp "$file" "$SEEDS/mjcf_import/$(basename "$(dirname "$file")")_$(basename "$file")"
done
# Deep trees (bodies and default classes 1500 levels deep) and orientations
# at the edges of floating point.
.venv/bin/python - "$SEEDS/mjcf_import" <<'SEEDS'
import sys
from pathlib import Path
out = Path(sys.argv[1])
depth = 1500
bodies = "".join(f'<body pos="0 0 .1"><joint axis="1 0 0"/><geom size=".05"/>' for _ in range(depth))
out.joinpath("deep_chain.xml").write_text(
    f'<mujoco><worldbody><body><freejoint/><geom size=".1"/>{bodies}{"</body>" * (depth + 1)}</worldbody></mujoco>')
classes = "".join(f'<default class="c{i}">' for i in range(depth))
out.joinpath("deep_defaults.xml").write_text(
    f'<mujoco><default><joint damping="1"/>{classes}{"</default>" * (depth + 1)}'
    f'<worldbody><body><joint class="c{depth - 1}"/><geom size=".1"/></body></worldbody></mujoco>')
def bodies_turned(orientations):
    return "<mujoco><worldbody>" + "".join(
        f'<body {o}><joint type="ball"/><geom size=".1"/></body>' for o in orientations) + "</worldbody></mujoco>"
out.joinpath("extreme_orientations.xml").write_text(bodies_turned(
    ['quat="1e300 0 0 1e300"', 'quat="1e-12 0 1e-12 0"', 'zaxis="1e200 0 1e200"', 'axisangle="1e300 0 0 30"',
     'xyaxes="1e200 0 0 0 1e200 0"']))
out.joinpath("tiny_quaternion.xml").write_text(bodies_turned(['quat="1e-16 0 0 5e-324"']))
SEEDS
cp "$WORK/bus/resources/model.json" "$SEEDS/resource_loader/bus_arm7.json"
# The servicer with its actuators, sensors and wrench inputs: every part of
# a model file the loader validates.
for example in fixed_rig flexible_boom servicer; do
    wrenches=()
    [ "$example" = servicer ] && wrenches=(--wrench-inputs bus,hand)
    target/release/nudyn export "examples/$example.xml" -o "$WORK/$example.fmu" "${wrenches[@]}" >/dev/null
    .venv/bin/python -c "import sys, zipfile; sys.stdout.buffer.write(zipfile.ZipFile(sys.argv[1]).read('resources/model.json'))" \
        "$WORK/$example.fmu" >"$SEEDS/resource_loader/$example.json"
done
printf '\x81' >"$SEEDS/state_deserializer/valid"
printf 'call sequence seed: any bytes decode to calls' >"$SEEDS/call_sequence/text"
printf 'fmi3 call sequence seed: any bytes decode to calls' >"$SEEDS/call_sequence_fmi3/text"

# Fuzzes one target (FUZZ_SECONDS, else its FUZZ_INPUTS); fails if it found a crash.
fuzz_one() {
    local target=$1 limit
    mkdir -p "fuzz/corpus/$target"
    if [ -n "$FUZZ_SECONDS" ]; then
        limit=-max_total_time="$FUZZ_SECONDS"
        echo "stress-fmu: fuzzing $target for $FUZZ_SECONDS s"
    else
        limit=-runs="${FUZZ_INPUTS[$target]}"
        echo "stress-fmu: fuzzing $target for ${FUZZ_INPUTS[$target]} inputs"
    fi
    (cd fuzz && nice cargo fuzz run --release "$target" "corpus/$target" "$SEEDS/$target" -- \
        "$limit" -timeout="$INPUT_TIMEOUT" -rss_limit_mb=4096 -print_final_stats=1 \
        2>"$WORK/fuzz-$target.txt") || {
        tail -n 60 "$WORK/fuzz-$target.txt" >&2
        echo "stress-fmu: $target crashed; the input is in fuzz/artifacts/$target/" >&2
        return 1
    }
    grep -E '^stat::number_of_executed_units|^stat::average_exec_per_sec' "$WORK/fuzz-$target.txt" \
        | sed "s/^/stress-fmu: $target: /"
}
# Runs each JOB (a function and its arguments), as many at once as there are
# cores, the next as soon as one ends: valgrind and each fuzzer use one core
# (with --long, libFuzzer's time is wall-clock time: each target gets a core
# of its own for its FUZZ_SECONDS). Fails if any failed, once all have ended.
#   run_on_every_core JOB...
run_on_every_core() {
    local cores running=0 status=0 job
    cores=$(nproc)
    for job in "$@"; do
        if [ "$running" -ge "$cores" ]; then
            wait -n || status=1
            running=$((running - 1))
        fi
        $job &
        running=$((running + 1))
    done
    for ((; running > 0; running--)); do
        wait -n || status=1
    done
    return "$status"
}
run_on_every_core "check_memory fmi2" "check_memory fmi3" "fuzz_one mjcf_import" "fuzz_one resource_loader" \
    "fuzz_one state_deserializer" "fuzz_one call_sequence" "fuzz_one call_sequence_fmi3"
echo "stress-fmu: ok"
