#!/usr/bin/env bash
# Builds the FMU binary for Windows (x86-64), so that `nudyn export` packs
# binaries/win64/<id>.dll (FMI 3.0: binaries/x86_64-windows/) beside linux64:
#
#   bash scripts/build-windows.sh
#
# writes target/share/nudyn/binaries/win64/nudyn_fmu.dll (stripped), where
# `nudyn export` looks for it. Installs what it needs from Debian's packages
# (only what is missing):
#
#   - rustc-web, cargo-web and rust-web-src: Debian's Rust 1.96 and the
#     source of its standard library. rustup's toolchain has no Windows
#     standard library and cannot fetch one here, so the standard library
#     is built from source with cargo's -Zbuild-std (RUSTC_BOOTSTRAP=1
#     allows the unstable flag on a stable compiler);
#   - gcc-mingw-w64-x86-64: the linker and the Windows C runtime;
#   - libclang-dev: fmi-sys's bindgen, which also needs clang's own include
#     folder (mm_malloc.h) for the Windows target.
#
# Debian's cargo and rustc are called by their full paths: rustup's proxies
# come first on the PATH. The build has its own target folder
# (target/windows), so it does not disturb the Linux build's; a rerun with
# nothing changed takes seconds.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
TARGET=x86_64-pc-windows-gnu
OUT="$ROOT/target/share/nudyn/binaries/win64"

as_root() {
    if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi
}

missing=()
for package in rustc-web cargo-web rust-web-src gcc-mingw-w64-x86-64 libclang-dev; do
    dpkg -s "$package" >/dev/null 2>&1 || missing+=("$package")
done
if [ ${#missing[@]} -gt 0 ]; then
    echo "build-windows: installing ${missing[*]}"
    as_root apt-get update
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y "${missing[@]}"
fi

clang_include="$(dirname "$(ls /usr/lib/llvm-*/lib/clang/*/include/mm_malloc.h | sort -V | tail -1)")"

echo "build-windows: building nudyn_fmu.dll with $(/usr/bin/rustc --version)"
# The DLL is stripped below, so it is built (standard library included)
# without debug information, and the standard library without the
# `backtrace` feature: it only symbolizes backtraces, which a stripped DLL
# cannot (panic-unwind stays: the FMU catches panics at its C boundary).
RUSTC_BOOTSTRAP=1 RUSTC=/usr/bin/rustc \
    BINDGEN_EXTRA_CLANG_ARGS_x86_64_pc_windows_gnu="-isystem $clang_include" \
    /usr/bin/cargo build --release --locked -p nudyn-fmu --target "$TARGET" \
    -Zbuild-std=std -Zbuild-std-features=panic-unwind --config profile.release.debug=false \
    --target-dir target/windows \
    --config "target.$TARGET.linker=\"x86_64-w64-mingw32-gcc\"" \
    --config "target.$TARGET.ar=\"x86_64-w64-mingw32-ar\""

mkdir -p "$OUT"
# Exports live in the DLL's export table, not its symbol table: --strip-all keeps them.
x86_64-w64-mingw32-strip --strip-all -o "$OUT/nudyn_fmu.dll.tmp" "target/windows/$TARGET/release/nudyn_fmu.dll"
mv "$OUT/nudyn_fmu.dll.tmp" "$OUT/nudyn_fmu.dll"
echo "build-windows: $OUT/nudyn_fmu.dll ($(stat -c %s "$OUT/nudyn_fmu.dll") bytes)"
