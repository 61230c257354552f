"""The win64 binary in every FMU, run under wine.

tests/memory/fmu_runs.c, the plain C importer of the memory checks, is
built twice: with gcc for Linux and with mingw for Windows. Both run the
same FMU (unzipped into a folder whose name needs percent-encoding in the
resource URI) through the same call sequence: the misuse subset (wrong
GUID, a resource location that is not a file URI, a call out of sequence,
NULL arrays, an unknown value reference, a NaN input: each refused with a
message), then instantiate, start values, initialize, steps with inputs,
get/set and serialized FMU states, reset, terminate, free, and model
exchange. Every Real value after every step, and the model exchange
states, must agree between the two binaries to 1e-12.

Needs scripts/build-windows.sh to have run (scripts/test.sh runs it), and
Debian's wine64 (scripts/setup-test.sh installs it). Wine 8.0 lacks
bcryptprimitives.dll, which Rust's standard library imports on Windows:
tests/wine/bcryptprimitives.c stands in for it, beside the importer only.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
from conftest import EXAMPLES_DIR, ROOT
from fmpy import read_model_description
from nudyn_driver.package import FmuPackage

pytestmark = pytest.mark.usefixtures("every_platform_built")

WIN64_DLL = ROOT / "target" / "share" / "nudyn" / "binaries" / "win64" / "nudyn_fmu.dll"
WINE_PREFIX = ROOT / "target" / "wine"  # kept between runs: creating it takes seconds
STEPS = 300


def windows_path(path: Path) -> str:
    """`path` as a program under wine sees it: wine maps / to drive Z:."""
    return "Z:" + str(path).replace("/", "\\")


@pytest.fixture(scope="module")
def importers(tmp_path_factory):
    """(the Linux importer, a command prefix running the Windows importer under wine)."""
    if not WIN64_DLL.is_file():
        pytest.fail(f"{WIN64_DLL} is missing: run scripts/build-windows.sh", pytrace=False)
    for tool in ("wine", "x86_64-w64-mingw32-gcc"):
        if shutil.which(tool) is None:
            pytest.fail(f"{tool} is missing: run scripts/setup-test.sh and scripts/build-windows.sh", pytrace=False)
    out = tmp_path_factory.mktemp("importers")
    source = ROOT / "tests" / "memory" / "fmu_runs.c"
    flags = ["-O1", "-Wall", "-Wextra", "-Werror"]
    subprocess.run(["gcc", *flags, "-o", str(out / "fmu_runs"), str(source), "-ldl", "-lm"], check=True)
    subprocess.run(["x86_64-w64-mingw32-gcc", *flags, "-o", str(out / "fmu_runs.exe"), str(source), "-lm"],
                   check=True)
    subprocess.run(["x86_64-w64-mingw32-gcc", *flags, "-shared", "-o", str(out / "bcryptprimitives.dll"),
                    str(ROOT / "tests" / "wine" / "bcryptprimitives.c"), "-ladvapi32"], check=True)
    return out / "fmu_runs", ["wine", str(out / "fmu_runs.exe")]


def wine_env() -> dict[str, str]:
    WINE_PREFIX.mkdir(parents=True, exist_ok=True)
    return {**os.environ, "WINEPREFIX": str(WINE_PREFIX), "WINEDEBUG": "-all", "WINEDLLOVERRIDES": "mscoree,mshtml="}


def run_both(importers, fmu: Path, workdir: Path, inputs: list[int], nx: int) -> tuple[np.ndarray, np.ndarray]:
    """Runs `fmu` through the Linux and the Windows importer; their traces."""
    folder = workdir / "an fmu at 100% "  # a space and a '%': the URI percent-encodes both
    package = FmuPackage.unzip(fmu, folder)
    reals = [package.vr[name] for name in package.reals]
    assert reals == list(range(1, len(reals) + 1)), "the importer reads value references 1..n"
    linux, wine = importers
    arguments = [package.model_identifier, package.guid, str(len(reals)), str(nx), "2", str(STEPS),
                 ",".join(map(str, inputs)) or "-"]
    linux_trace, windows_trace = workdir / "linux.bin", workdir / "windows.bin"
    on_linux = subprocess.run([str(linux), str(folder), *arguments, str(linux_trace)], capture_output=True,
                              text=True, timeout=300)
    assert on_linux.returncode == 0, on_linux.stderr
    on_windows = subprocess.run([*wine, windows_path(folder), *arguments, windows_path(windows_trace)],
                                capture_output=True, text=True, timeout=300, env=wine_env())
    assert on_windows.returncode == 0, on_windows.stdout + on_windows.stderr
    # The same calls refused, each with its message, on both.
    assert on_windows.stdout.strip() == on_linux.stdout.strip(), (on_windows.stdout, on_linux.stdout)
    expected_size = 8 * (STEPS * len(reals) + nx)
    for trace in (linux_trace, windows_trace):
        assert trace.stat().st_size == expected_size, trace
    return np.fromfile(linux_trace), np.fromfile(windows_trace)


def assert_agree(linux: np.ndarray, windows: np.ndarray):
    scaled = np.abs(windows - linux) / np.maximum(1.0, np.abs(linux))
    assert np.all(np.isfinite(windows))
    assert scaled.max() <= 1e-12, f"win64 differs from linux64 by {scaled.max():.3g} (at {scaled.argmax()})"


def export(cli, tmp_path, example: str, **options) -> Path:
    fmu = cli.export(EXAMPLES_DIR / example, tmp_path / "vehicle.fmu", **options)
    with zipfile.ZipFile(fmu) as archive:
        names = archive.namelist()
    assert any(n.startswith("binaries/win64/") and n.endswith(".dll") for n in names), names
    return fmu


@pytest.mark.parametrize("example, options", [
    ("bus_arm7.xml", {"outputs": ["qvel", "kinetic_energy", "power", "momentum"]}),
    ("servicer.xml", {"wrench_inputs": ["bus"]}),
])
def test_the_plant_runs_the_same_on_win64(cli, importers, tmp_path, example, options):
    fmu = export(cli, tmp_path, example, **options)
    package = FmuPackage.unzip(fmu, tmp_path / "inspect")
    inputs = package.refs("eps") + package.refs("ctrl") + package.refs("xfrc_applied")
    linux, windows = run_both(importers, fmu, tmp_path, inputs, package.nq + package.nv)
    assert_agree(linux, windows)


def test_the_controller_runs_the_same_on_win64(cli, importers, tmp_path):
    fmu = export(cli, tmp_path, "bus_arm7.xml", controller=True)
    package = FmuPackage.unzip(fmu, tmp_path / "inspect")
    linux, windows = run_both(importers, fmu, tmp_path, package.refs("theta") + package.refs("nu"), 0)
    assert_agree(linux, windows)


def test_fmi3_runs_the_same_on_x86_64_windows(cli, importers, tmp_path):
    """The FMI 3.0 importer of the memory checks, on binaries/x86_64-windows."""
    fmu = cli.export(EXAMPLES_DIR / "bus_arm7.xml", tmp_path / "vehicle3.fmu", fmi_version=3)
    folder = tmp_path / "fmi 3 at 100% "
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(folder)
        assert "binaries/x86_64-windows/bus_arm7.dll" in archive.namelist()
    description = read_model_description(str(fmu))
    variables = {v.name: v for v in description.modelVariables}
    size = {name: int(variables[name].dimensions[0].start) for name in ("theta", "nu")}
    out = tmp_path / "importers3"
    out.mkdir()
    source = ROOT / "tests" / "memory" / "fmu3_runs.c"
    flags = ["-O1", "-Wall", "-Wextra", "-Werror"]
    subprocess.run(["gcc", *flags, "-o", str(out / "fmu3_runs"), str(source), "-ldl", "-lm"], check=True)
    subprocess.run(["x86_64-w64-mingw32-gcc", *flags, "-o", str(out / "fmu3_runs.exe"), str(source), "-lm"],
                   check=True)
    shutil.copy(importers[0].parent / "bcryptprimitives.dll", out)
    arguments = [description.coSimulation.modelIdentifier, description.instantiationToken,
                 str(variables["theta"].valueReference), str(size["theta"]), str(variables["nu"].valueReference),
                 str(size["nu"]), str(variables["der(nu)"].valueReference), "2", str(STEPS)]
    on_linux = subprocess.run([str(out / "fmu3_runs"), str(folder), *arguments, str(tmp_path / "linux3.bin")],
                              capture_output=True, text=True, timeout=300)
    assert on_linux.returncode == 0, on_linux.stderr
    on_windows = subprocess.run(["wine", str(out / "fmu3_runs.exe"), windows_path(folder), *arguments,
                                 windows_path(tmp_path / "windows3.bin")],
                                capture_output=True, text=True, timeout=300, env=wine_env())
    assert on_windows.returncode == 0, on_windows.stdout + on_windows.stderr
    assert on_windows.stdout.strip() == on_linux.stdout.strip()
    linux, windows = np.fromfile(tmp_path / "linux3.bin"), np.fromfile(tmp_path / "windows3.bin")
    assert linux.size == (STEPS + 1) * (size["theta"] + size["nu"])
    assert_agree(linux, windows)
