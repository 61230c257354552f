#!/usr/bin/env bash
# Builds the FMU binary for Windows (x86-64), so that `nudyn export` packs
# binaries/win64/<id>.dll (FMI 3.0: binaries/x86_64-windows/) beside linux64:
#
#   bash scripts/build-windows.sh
#
# writes target/share/nudyn/binaries/win64/nudyn_fmu.dll (stripped), where
# `nudyn export` looks for it. Installs what it needs (only what is missing):
#
#   - the standard library for x86_64-pc-windows-gnu: rustup's prebuilt one
#     (`rustup target add`), for the toolchain that builds the Linux side.
#     Where rustup is missing or cannot download it, Debian's rustc-web,
#     cargo-web and rust-web-src (Rust 1.96 and the source of its standard
#     library) build it from source with cargo's -Zbuild-std
#     (RUSTC_BOOTSTRAP=1 allows the unstable flag on a stable compiler):
#     an equivalent DLL, for about 150 CPU-s more (287 against 130 CPU-s);
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

# rustup's prebuilt standard library when it can have it; otherwise Debian's
# Rust builds one from source.
if command -v rustup >/dev/null 2>&1 \
    && { rustup target list --installed | grep -qx "$TARGET" || rustup target add "$TARGET" >/dev/null 2>&1; }; then
    cargo=(cargo)
    packages=(gcc-mingw-w64-x86-64 libclang-dev)
else
    echo "build-windows: no prebuilt standard library for $TARGET from rustup; building it from source"
    # The DLL is stripped below, so the standard library is built without the
    # `backtrace` feature: it only symbolizes backtraces, which a stripped DLL
    # cannot (panic-unwind stays: the FMU catches panics at its C boundary).
    cargo=(env RUSTC_BOOTSTRAP=1 RUSTC=/usr/bin/rustc /usr/bin/cargo -Zbuild-std=std
        -Zbuild-std-features=panic-unwind)
    packages=(rustc-web cargo-web rust-web-src gcc-mingw-w64-x86-64 libclang-dev)
fi
missing=()
for package in "${packages[@]}"; do
    dpkg -s "$package" >/dev/null 2>&1 || missing+=("$package")
done
if [ ${#missing[@]} -gt 0 ]; then
    echo "build-windows: installing ${missing[*]}"
    as_root apt-get update
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y "${missing[@]}"
fi

clang_include="$(dirname "$(ls /usr/lib/llvm-*/lib/clang/*/include/mm_malloc.h | sort -V | tail -1)")"

echo "build-windows: building nudyn_fmu.dll with $("${cargo[@]}" --version)"
# Without debug information: the DLL is stripped below.
BINDGEN_EXTRA_CLANG_ARGS_x86_64_pc_windows_gnu="-isystem $clang_include" \
    "${cargo[@]}" build --release --locked -p nudyn-fmu --target "$TARGET" \
    --config profile.release.debug=false --target-dir target/windows \
    --config "target.$TARGET.linker=\"x86_64-w64-mingw32-gcc\"" \
    --config "target.$TARGET.ar=\"x86_64-w64-mingw32-ar\""

mkdir -p "$OUT"
# Exports live in the DLL's export table, not its symbol table: --strip-all keeps them.
x86_64-w64-mingw32-strip --strip-all -o "$OUT/nudyn_fmu.dll.tmp" "target/windows/$TARGET/release/nudyn_fmu.dll"
mv "$OUT/nudyn_fmu.dll.tmp" "$OUT/nudyn_fmu.dll"
echo "build-windows: $OUT/nudyn_fmu.dll ($(stat -c %s "$OUT/nudyn_fmu.dll") bytes)"
