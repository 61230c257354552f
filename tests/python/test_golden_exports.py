"""The text files `nudyn export` and `nudyn system` write, frozen as golden
files under tests/golden/: modelDescription.xml (FMI 2.0 and 3.0) and
documentation/index.html of every example vehicle's plant FMU, of the
controller FMU and of a few option sets, and an SSP's SystemStructure.ssd,
parameter files and inner FMUs' text files.

These files were frozen from the exporter's output on purpose, before the
exporter was rebuilt as renderers of one variable table (issue 46): the
refactor must not change what users' scripts read (names, value references,
causalities, start values, dependencies). The test re-exports and compares
byte for byte. A change meant to alter an export regenerates the files with
NUDYN_UPDATE_GOLDEN=1 and names the change in its commit.

The GUID is left out of the comparison (replaced by a placeholder): it
hashes the compiled model's serialization in resources/model.json, which
the importer and model work may change without changing any variable; the
variables' names and value references it also hashes are compared here in
the text itself."""

from __future__ import annotations

import io
import os
import re
import subprocess
import zipfile
from pathlib import Path

import pytest

from conftest import ROOT

GOLDEN = ROOT / "tests" / "golden"
UPDATE = os.environ.get("NUDYN_UPDATE_GOLDEN") == "1"
DOCKED = "tests/fixtures/constraints/docked_servicer.xml"

# (case name, arguments after `nudyn export MODEL -o FMU`)
EXPORTS = [
    *(
        (f"{model.stem}-fmi{version}", [f"examples/{model.name}", "--fmi-version", version])
        for model in sorted((ROOT / "examples").glob("*.xml"))
        for version in ("2", "3")
    ),
    *(
        (
            f"docked_servicer-outputs-fmi{version}",
            [
                DOCKED,
                "--fmi-version",
                version,
                "--outputs",
                "qvel,kinetic_energy,power,momentum,qfrc_constraint",
                "--wrench-inputs",
                "bus,forearm",
                "--method",
                "rk4",
            ],
        )
        for version in ("2", "3")
    ),
    *(
        (
            f"bus_arm7-energy_residual-fmi{version}",
            ["examples/bus_arm7.xml", "--fmi-version", version, "--outputs", "energy_residual,power"],
        )
        for version in ("2", "3")
    ),
    # --fmi3-scalars, added with the option (frozen from its first output).
    (
        "docked_servicer-outputs-fmi3-scalars",
        [DOCKED, "--fmi-version", "3", "--fmi3-scalars", "--outputs", "qvel,momentum", "--wrench-inputs", "forearm"],
    ),
    (
        "servicer-controller-pose-fmi3-scalars",
        ["examples/servicer.xml", "--controller", "--end-effector", "bus", "--fmi-version", "3", "--fmi3-scalars"],
    ),
    ("docked_servicer-disable-fmi2", [DOCKED, "--disable", "limit,frictionloss", "--method", "auto"]),
    *(
        (f"bus_arm7-controller-fmi{version}", ["examples/bus_arm7.xml", "--controller", "--fmi-version", version])
        for version in ("2", "3")
    ),
    *(
        (
            f"servicer-controller-pose-fmi{version}",
            ["examples/servicer.xml", "--controller", "--end-effector", "bus", "--fmi-version", version],
        )
        for version in ("2", "3")
    ),
]

# (case name, arguments after `nudyn system MODEL -o SSP`)
SYSTEMS = [
    ("bus_arm7-system", ["examples/bus_arm7.xml"]),
    (
        "docked_servicer-system",
        [
            DOCKED,
            "--end-effector",
            "forearm",
            "--outputs",
            "kinetic_energy",
            "--step",
            "0.005",
            "--stop",
            "2",
            "--set",
            "plant.nu[4]=0.25",
            "--set",
            "controller.c1=2",
        ],
    ),
]


def without_guid(text: str) -> str:
    return re.sub(r"(guid|instantiationToken)=\"\{[0-9a-f-]+\}\"", r'\1="{GUID}"', text)


def text_entries(archive: bytes, prefix: str = "") -> dict[str, str]:
    """The archive's text entries (modelDescription, documentation, SSD,
    SSV), and those of the FMUs inside it, by path; binaries and the
    resource JSON are not frozen here."""
    entries = {}
    with zipfile.ZipFile(io.BytesIO(archive)) as zip_file:
        for name in zip_file.namelist():
            data = zip_file.read(name)
            if name.endswith(".fmu"):
                entries.update(text_entries(data, f"{prefix}{name}/"))
            elif name.endswith((".xml", ".html", ".ssd", ".ssv")):
                entries[prefix + name] = without_guid(data.decode())
    return entries


def check_against_golden(case: str, entries: dict[str, str]):
    folder = GOLDEN / case
    if UPDATE:
        for name, text in entries.items():
            path = folder / name
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
    frozen = sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())
    assert frozen == sorted(entries), f"{case}: the archive's text files differ from {folder}"
    for name, text in entries.items():
        expected = (folder / name).read_text()
        if text != expected:
            first = next(
                (k for k, (a, b) in enumerate(zip(text.splitlines(), expected.splitlines())) if a != b),
                min(len(text.splitlines()), len(expected.splitlines())),
            )
            line = lambda t: t.splitlines()[first] if first < len(t.splitlines()) else "<end>"  # noqa: E731
            pytest.fail(
                f"{case}/{name} differs from the golden file at line {first + 1}:\n"
                f"  exported: {line(text)}\n  golden:   {line(expected)}",
                pytrace=False,
            )


def run_nudyn(nudyn, fmu_library, arguments):
    env = {**os.environ, "NUDYN_FMU_LIB": str(fmu_library), "SOURCE_DATE_EPOCH": "1764374400"}
    proc = subprocess.run([str(nudyn), *map(str, arguments)], cwd=ROOT, env=env, capture_output=True, text=True)
    assert proc.returncode == 0, f"nudyn {' '.join(map(str, arguments))}:\n{proc.stderr}"


@pytest.mark.parametrize("case, arguments", EXPORTS, ids=[case for case, _ in EXPORTS])
def test_export_matches_golden_files(nudyn, fmu_library, case, arguments, tmp_path):
    fmu = tmp_path / f"{case}.fmu"
    run_nudyn(nudyn, fmu_library, ["export", arguments[0], "-o", fmu, *arguments[1:]])
    check_against_golden(case, text_entries(fmu.read_bytes()))


@pytest.mark.parametrize("case, arguments", SYSTEMS, ids=[case for case, _ in SYSTEMS])
def test_system_matches_golden_files(nudyn, fmu_library, case, arguments, tmp_path):
    ssp = tmp_path / f"{case}.ssp"
    run_nudyn(nudyn, fmu_library, ["system", arguments[0], "-o", ssp, *arguments[1:]])
    check_against_golden(case, text_entries(ssp.read_bytes()))
