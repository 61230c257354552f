"""`nudyn export --fmi-version 3 --fmi3-scalars`: the FMI 3.0 FMU for hosts
that read no arrays (OMSimulator, PyFMI's FMI 3.0). Every array element is
a scalar under its FMI 2.0 name, derivatives point at their own element,
and the FMU computes what the array export computes, to the bit."""

from __future__ import annotations

import os
import subprocess
import xml.etree.ElementTree as ET
import zipfile

import numpy as np
import pytest
from fmpy import simulate_fmu

from conftest import ROOT

DOCKED = ROOT / "tests" / "fixtures" / "constraints" / "docked_servicer.xml"
OUTPUTS = "qvel,kinetic_energy,momentum,qfrc_constraint"


def export(nudyn, fmu_library, out, *options):
    env = {**os.environ, "NUDYN_FMU_LIB": str(fmu_library)}
    return subprocess.run([str(nudyn), "export", str(DOCKED), "-o", str(out), *options], env=env,
                          capture_output=True, text=True)


@pytest.fixture(scope="module")
def fmus(nudyn, fmu_library, tmp_path_factory):
    """The docked servicer's FMI 2.0, FMI 3.0 and FMI 3.0 scalar FMUs."""
    folder = tmp_path_factory.mktemp("fmi3_scalars")
    paths = {}
    for name, options in [("fmi2", []), ("fmi3", ["--fmi-version", "3"]),
                          ("scalars", ["--fmi-version", "3", "--fmi3-scalars"])]:
        paths[name] = folder / f"{name}.fmu"
        proc = export(nudyn, fmu_library, paths[name], "--outputs", OUTPUTS, *options)
        assert proc.returncode == 0, proc.stderr
    return paths


def variables(fmu):
    with zipfile.ZipFile(fmu) as archive:
        root = ET.fromstring(archive.read("modelDescription.xml"))
    return root.find("ModelVariables")


def test_every_element_is_a_scalar_named_as_in_fmi2(fmus):
    fmi2 = [v.get("name") for v in variables(fmus["fmi2"])]
    scalars = variables(fmus["scalars"])
    assert all(v.find("Dimension") is None for v in scalars)
    names = [v.get("name") for v in scalars]
    assert names == ["time", *fmi2], "the FMI 2.0 names, in their order, after time"
    assert len(set(int(v.get("valueReference")) for v in scalars)) == len(names)
    by_reference = {v.get("valueReference"): v.get("name") for v in scalars}
    derivatives = [(v.get("name"), by_reference[v.get("derivative")]) for v in scalars if v.get("derivative")]
    assert derivatives and all(name == f"der({state})" for name, state in derivatives), derivatives


@pytest.mark.parametrize("interface", ["CoSimulation", "ModelExchange"])
def test_fmpy_runs_it_as_it_runs_the_arrays(fmus, interface):
    """Same binary, same numbers: the scalar export's results equal the array export's to the bit."""
    nv = sum(1 for v in variables(fmus["fmi2"]) if v.get("name").startswith("eps["))
    nu0 = np.zeros(nv)
    nu0[3] = 0.3
    run = dict(stop_time=0.5, output_interval=0.05, fmi_type=interface, validate=True)
    arrays = simulate_fmu(fmus["fmi3"], start_values={"nu": list(nu0), "tolerance": 1e-7},
                          output=["theta", "nu", "kinetic_energy", "qfrc_constraint"], **run)
    scalars = simulate_fmu(fmus["scalars"], start_values={"nu[4]": 0.3, "tolerance": 1e-7},
                           output=["theta[8]", "nu[4]", "kinetic_energy", "qfrc_constraint[10]"], **run)
    assert np.array_equal(arrays["time"], scalars["time"])
    assert np.array_equal(arrays["theta"][:, 7], scalars["theta[8]"])
    assert np.array_equal(arrays["nu"][:, 3], scalars["nu[4]"])
    assert np.array_equal(arrays["kinetic_energy"], scalars["kinetic_energy"])
    assert np.array_equal(arrays["qfrc_constraint"][:, 9], scalars["qfrc_constraint[10]"])
    assert np.any(scalars["nu[4]"] != 0.3), "the vehicle moves"


def test_scalars_need_fmi3(nudyn, fmu_library, tmp_path):
    proc = export(nudyn, fmu_library, tmp_path / "x.fmu", "--fmi3-scalars")
    assert proc.returncode != 0
    assert "--fmi3-scalars declares FMI 3.0 variables: it needs --fmi-version 3" in proc.stderr
    assert not (tmp_path / "x.fmu").exists()


def test_the_controller_exports_scalars_too(nudyn, fmu_library, tmp_path):
    fmu = tmp_path / "controller.fmu"
    proc = export(nudyn, fmu_library, fmu, "--controller", "--end-effector", "forearm", "--fmi-version", "3",
                  "--fmi3-scalars")
    assert proc.returncode == 0, proc.stderr
    names = [v.get("name") for v in variables(fmu)]
    assert {"target_position[3]", "target_quaternion[4]", "eps[1]", "potential"} <= set(names)
    start = {"nu[1]": 0.1}
    result = simulate_fmu(fmu, stop_time=0.02, output_interval=0.01, start_values=start, output=["eps[1]"],
                          validate=True)
    assert np.all(np.isfinite(result["eps[1]"]))
