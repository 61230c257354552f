"""What `nudyn export` packs: the binary of every platform built (and it
says which), without debug sections, and a modelDescription that says
which nudyn generated it and when."""

from __future__ import annotations

import datetime
import os
import re
import subprocess
import xml.etree.ElementTree as ET
import zipfile

import fmpy
import pytest
from conftest import EXAMPLES_DIR, ROOT

pytestmark = pytest.mark.usefixtures("every_platform_built")

MODEL = EXAMPLES_DIR / "bus_arm7.xml"
WIN64_DLL = ROOT / "target" / "share" / "nudyn" / "binaries" / "win64" / "nudyn_fmu.dll"


def export(nudyn, fmu_library, output, *options, env=None):
    env = {**os.environ, "NUDYN_FMU_LIB": str(fmu_library), **(env or {})}
    return subprocess.run([str(nudyn), "export", str(MODEL), "-o", str(output), *options], capture_output=True,
                          text=True, env=env)


def binaries(fmu) -> list[str]:
    with zipfile.ZipFile(fmu) as archive:
        return sorted(name for name in archive.namelist() if name.startswith("binaries/"))


def test_every_platform_built_is_packed_and_named(nudyn, fmu_library, tmp_path):
    assert WIN64_DLL.is_file(), "scripts/build-windows.sh builds it (scripts/test.sh runs it)"
    for version, folders in [("2", ["linux64/bus_arm7.so", "win64/bus_arm7.dll"]),
                             ("3", ["x86_64-linux/bus_arm7.so", "x86_64-windows/bus_arm7.dll"])]:
        fmu = tmp_path / f"bus{version}.fmu"
        proc = export(nudyn, fmu_library, fmu, "--fmi-version", version)
        assert proc.returncode == 0, proc.stderr
        assert proc.stdout.strip() == f"wrote {fmu} with binaries for linux64, win64"
        assert binaries(fmu) == [f"binaries/{folder}" for folder in folders]
    # FMPy, which picks the binary a host loads, sees both platforms.
    assert sorted(fmpy.supported_platforms(str(tmp_path / "bus2.fmu"))) == ["linux64", "win64"]
    controller = tmp_path / "controller.fmu"
    proc = export(nudyn, fmu_library, controller, "--controller")
    assert proc.returncode == 0, proc.stderr
    assert binaries(controller) == ["binaries/linux64/bus_arm7_controller.so", "binaries/win64/bus_arm7_controller.dll"]


def test_a_platform_not_built_is_left_out_and_said(nudyn, fmu_library, tmp_path):
    empty = tmp_path / "no-binaries"
    empty.mkdir()
    fmu = tmp_path / "bus.fmu"
    proc = export(nudyn, fmu_library, fmu, env={"NUDYN_FMU_BINARIES": str(empty)})
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == (f"wrote {fmu} with binaries for linux64 "
                                   "(not built: win64; scripts/build-windows.sh builds win64)")
    assert binaries(fmu) == ["binaries/linux64/bus_arm7.so"]


def test_a_win64_binary_that_is_not_a_windows_dll_is_refused(nudyn, fmu_library, tmp_path):
    folder = tmp_path / "binaries"
    (folder / "win64").mkdir(parents=True)
    impostor = folder / "win64" / "nudyn_fmu.dll"
    impostor.write_bytes(fmu_library.read_bytes())
    fmu = tmp_path / "bus.fmu"
    proc = export(nudyn, fmu_library, fmu, env={"NUDYN_FMU_BINARIES": str(folder)})
    assert proc.returncode == 1
    assert (f"{impostor} cannot be the FMU's binary: it is a Elf file for X86_64, "
            "not an x86_64 Windows (PE) DLL") in proc.stderr, proc.stderr
    assert not fmu.exists()


def sections(library) -> dict[str, int]:
    """The ELF sections and their sizes, as binutils' readelf lists them
    ("  [ 1] .text  PROGBITS  <address> <offset> <size> ...")."""
    listing = subprocess.run(["readelf", "-S", "-W", str(library)], capture_output=True, text=True, check=True).stdout
    return {name: int(size, 16) for name, size in
            re.findall(r"^\s*\[\s*\d+\]\s+(\S+)\s+\S+\s+\S+\s+\S+\s+([0-9a-f]+)", listing, flags=re.MULTILINE)}


def test_the_fmu_is_small_without_debug_sections(nudyn, fmu_library, tmp_path):
    """The FMU carries the code only: its library is the built one less any
    debug sections. The release profile builds none; a debug build, or a
    release build with line tables for a profiler, has them
    (cli/tests/fmu_export.rs checks their removal on such a library)."""
    built = sections(fmu_library)
    debug_size = sum(size for name, size in built.items() if name.startswith(".debug_"))
    fmu = tmp_path / "bus.fmu"
    assert export(nudyn, fmu_library, fmu).returncode == 0
    with zipfile.ZipFile(fmu) as archive:
        archive.extract("binaries/linux64/bus_arm7.so", tmp_path)
    packed = tmp_path / "binaries" / "linux64" / "bus_arm7.so"
    names = list(sections(packed))
    assert not [name for name in names if name.startswith(".debug_")], names
    assert ".text" in names and ".dynsym" in names
    # The section headers and the string of section names shrink too; nothing else does.
    assert packed.stat().st_size <= fmu_library.stat().st_size - debug_size + 4096
    # 4.5 MB (2026-11-30): the passes in f64 with their specialized
    # instances (rigid sweeps, modal blocks of 1 to 6 modes at fixed sizes)
    # and in dual numbers (exact derivatives) with the general ones alone.
    assert fmu.stat().st_size < 5_000_000, "a few MB at most, both platforms included"


def generation(fmu) -> tuple[str, str]:
    with zipfile.ZipFile(fmu) as archive:
        root = ET.fromstring(archive.read("modelDescription.xml"))
    return root.get("generationTool"), root.get("generationDateAndTime")


def test_the_model_description_says_who_generated_it_and_when(nudyn, fmu_library, tmp_path):
    version = subprocess.run([str(nudyn), "--version"], capture_output=True, text=True, check=True).stdout.split()[-1]
    before = datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0)
    for fmi_version in ("2", "3"):
        fmu = tmp_path / f"now{fmi_version}.fmu"
        assert export(nudyn, fmu_library, fmu, "--fmi-version", fmi_version).returncode == 0
        tool, when = generation(fmu)
        assert tool == f"nudyn {version}"
        assert when.endswith("Z"), when
        generated = datetime.datetime.fromisoformat(when.replace("Z", "+00:00"))
        assert before <= generated <= datetime.datetime.now(datetime.timezone.utc)
    # SOURCE_DATE_EPOCH fixes the time: the same export twice is the same file, byte for byte.
    fixed = {"SOURCE_DATE_EPOCH": "1764064800"}
    first, second = tmp_path / "first.fmu", tmp_path / "second.fmu"
    for fmu in (first, second):
        assert export(nudyn, fmu_library, fmu, env=fixed).returncode == 0
    assert generation(first)[1] == "2025-11-25T10:00:00Z"
    assert first.read_bytes() == second.read_bytes()
