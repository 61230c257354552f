#!/usr/bin/env bash
# Builds the nudyn wheel into target/wheels/:
#
#   bash scripts/build-wheel.sh
#
# The wheel carries the `nudyn` executable, the FMU binaries built so far
# (linux64 always; win64 when scripts/build-windows.sh has run: the wheel
# packs what `nudyn export` would), the example vehicles and campaigns, and
# the Python tools (nudyn-validate, nudyn-campaign, nudyn-control-demo,
# nudyn-thruster-demo). `pip install target/wheels/nudyn-*.whl` needs no
# Rust toolchain. maturin comes from requirements-test.txt (scripts/setup-test.sh).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
WHEEL_DATA="$ROOT/target/wheel/nudyn.data"  # pyproject.toml's [tool.maturin] data
DATA="$WHEEL_DATA/data/share/nudyn"

# The targets scripts/test.sh builds: after the tests this compiles nothing
# again. maturin then builds nudyn-cli alone, whose dependencies
# get the workspace's features through workspace-hack (checked by
# scripts/check-unified-features.py), and the release profile strips the
# executable as the wheel ships it (Cargo.toml), so it compiles nothing.
cargo build --release --locked --workspace --lib --bins --test '*' --examples
rm -rf "$ROOT/target/wheel"
mkdir -p "$DATA/binaries/linux64"
# The same library `nudyn export` packs from target/release, without the
# debug sections it would leave out anyway.
strip --strip-debug -o "$DATA/binaries/linux64/libnudyn_fmu.so" target/release/libnudyn_fmu.so
if [ -f target/share/nudyn/binaries/win64/nudyn_fmu.dll ]; then
    mkdir -p "$DATA/binaries/win64"
    cp target/share/nudyn/binaries/win64/nudyn_fmu.dll "$DATA/binaries/win64/"
fi
cp -r examples "$DATA/examples"
mkdir -p "$WHEEL_DATA/scripts"
for entry in nudyn-validate:nudyn_validation.cli nudyn-campaign:nudyn_campaign.cli \
    nudyn-control-demo:nudyn_control.demo nudyn-thruster-demo:nudyn_servicer.demo; do
    printf '#!python\nimport sys\n\nfrom %s import main\n\nsys.exit(main())\n' "${entry#*:}" \
        >"$WHEEL_DATA/scripts/${entry%%:*}"
    chmod 755 "$WHEEL_DATA/scripts/${entry%%:*}"
done

# --compatibility linux: the executable links this machine's glibc; the tag
# says so rather than claiming a manylinux policy it was not built under.
"$ROOT/.venv/bin/maturin" build --release --locked --compatibility linux --out target/wheels
ls -l target/wheels/
