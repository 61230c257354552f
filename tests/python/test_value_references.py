"""Every variable's FMI 2.0 value reference, FMI 3.0 value reference (array
element, or scalar with --fmi3-scalars) and the FMU's get and set agree,
through the C API, for vehicles and option sets: a value set by one
version's reference is read back, element for element, under the same
name by every version's, and every output reads the same number."""

from __future__ import annotations

import os
import shutil
import subprocess
import zlib

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

from conftest import ROOT

DOCKED = "tests/fixtures/constraints/docked_servicer.xml"
CASES = [
    ("examples/bus_arm7.xml", []),
    ("examples/servicer.xml", ["--outputs", "qvel,kinetic_energy,power,momentum", "--wrench-inputs", "bus"]),
    (DOCKED, ["--outputs", "qvel,power,momentum,energy_residual,qfrc_constraint", "--wrench-inputs", "forearm,bus"]),
    ("examples/fixed_rig.xml", ["--outputs", "qfrc_constraint,kinetic_energy"]),
]
# Settable before initialization without changing which state is reached: inputs, parameters, ν.
SET = ("eps[", "ctrl[", "xfrc_applied[", "nu[", "tolerance", "max_step")


def value_of(name: str) -> float:
    """A distinct value per name, small enough for any vehicle to take."""
    return 1e-3 * (1 + zlib.crc32(name.encode()) % 997)


def elements(md):
    """(FMI 2.0-style element name, value reference, element index or None) of every Float64 but time."""
    for variable in md.modelVariables:
        if variable.type not in ("Real", "Float64") or variable.causality == "independent":
            continue
        if variable.dimensions:
            base, wrapped = variable.name, variable.name.startswith("der(")
            inner = base[4:-1] if wrapped else base
            size = int(variable.dimensions[0].start)
            for k in range(size):
                name = f"der({inner}[{k + 1}])" if wrapped else f"{inner}[{k + 1}]"
                yield name, variable.valueReference, k
        else:
            yield variable.name, variable.valueReference, None


def run(path, version):
    """Instantiates the FMU, sets every SET variable to value_of(its name)
    by its own references, initializes, and reads every Real element back."""
    md = read_model_description(path)
    unzipped = extract(path)
    try:
        cls = FMU2Slave if version == 2 else FMU3Slave
        fmu = cls(guid=md.guid if version == 2 else md.instantiationToken, unzipDirectory=unzipped,
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="vr")
        fmu.instantiate()
        listed = list(elements(md))
        by_reference = {}
        for name, vr, k in listed:
            by_reference.setdefault(vr, []).append((k, name))
        for vr, entries in by_reference.items():
            names = [name for _, name in sorted(entries, key=lambda e: e[0] or 0)]
            if not all(name.startswith(SET) for name in names):
                continue
            values = [value_of(name) for name in names]
            if version == 2:
                fmu.setReal([vr], values)
            else:
                fmu.setFloat64([vr], values)
        if version == 2:
            fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        read = {}
        for vr, entries in by_reference.items():
            got = fmu.getReal([vr]) if version == 2 else fmu.getFloat64([vr], nValues=len(entries))
            for (k, name), value in zip(sorted(entries, key=lambda e: e[0] or 0), got):
                read[name] = value
        fmu.terminate()
        fmu.freeInstance()
        return read
    finally:
        shutil.rmtree(unzipped, ignore_errors=True)


@pytest.mark.parametrize("model, options", CASES, ids=[f"{m.split('/')[-1]}-{len(o)}" for m, o in CASES])
def test_fmi2_and_fmi3_references_get_and_set_agree(nudyn, fmu_library, model, options, tmp_path):
    env = {**os.environ, "NUDYN_FMU_LIB": str(fmu_library)}
    results = {}
    for label, version, extra in [("fmi2", 2, []), ("fmi3", 3, ["--fmi-version", "3"]),
                                  ("scalars", 3, ["--fmi-version", "3", "--fmi3-scalars"])]:
        path = tmp_path / f"{label}.fmu"
        subprocess.run([str(nudyn), "export", str(ROOT / model), "-o", str(path), *options, *extra], check=True,
                       capture_output=True, env=env)
        results[label] = run(path, version)
    fmi2 = results["fmi2"]
    assert any(name.startswith("der(") for name in fmi2) or "energy_residual" in fmi2
    for label in ("fmi3", "scalars"):
        assert sorted(results[label]) == sorted(fmi2), label
        for name, value in fmi2.items():
            assert results[label][name] == value or (np.isnan(value) and np.isnan(results[label][name])), \
                f"{label}: {name} reads {results[label][name]}, FMI 2.0 {value}"
    for name, value in fmi2.items():
        if name.startswith(SET):
            assert value == value_of(name), f"{name} was set to {value_of(name)} and reads {value}"


def test_describe_lists_the_value_references_of_the_export(nudyn, cli, tmp_path):
    """`nudyn describe` ends with the plant FMU's variables, rendered from
    the contract's table: each Real block it lists has, in the FMU exported
    without options, the value references it prints for its first and last
    element, and together they are every Real."""
    import re

    fmu = cli.export(ROOT / DOCKED, tmp_path / "docked.fmu")
    vr = {v.name: v.valueReference for v in read_model_description(str(fmu)).modelVariables if v.type == "Real"}
    out = subprocess.run([str(nudyn), "describe", str(ROOT / DOCKED)], capture_output=True, text=True,
                         check=True).stdout
    listed = 0
    for row in (line for line in out.splitlines() if line.startswith("| `") and "| Real, " in line):
        name, numbers = (cell.strip() for cell in row.strip("|").split("|")[:2])
        first, _, last = numbers.removeprefix("Real, ").partition("–")
        match = re.fullmatch(r"`(der\()?(\w+)(?:\[1\.\.(\d+)\])?\)?`", name)
        assert match, row
        der, base, n = match.groups()
        element = (lambda k: f"der({base}[{k}])" if der else f"{base}[{k}]") if n else (lambda _: base)
        assert vr[element(1)] == int(first), row
        assert vr[element(int(n or 1))] == int(last or first), row
        listed += int(n or 1)
    assert listed == len(vr) and "constraint_switch" in out
