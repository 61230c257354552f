"""A vehicle with a flexible body as an FMU (docs/flexible.md; issue 49,
items 3 and 4): the modal coordinates are states and outputs after the
joints' in theta and nu, `modal_strain_energy` is an optional output, and
`nudyn describe` names each mode.

Fixture: tests/fixtures/flex/bench_vehicle.xml (a bus with a bench on a
hinge, its three modes in bench.json). The conservation case copies both
files with the modes' damping set to 0."""

from __future__ import annotations

import json
import shutil

import fmpy
import numpy as np
from conftest import ROOT

FIXTURES = ROOT / "tests" / "fixtures" / "flex"
# The bench's modes are theta[9..11] and nu[8..10] (1-based, as the FMU names them).
START = {"theta[9]": 0.05, "theta[10]": -0.02, "theta[11]": 0.01, "nu[4]": 0.1, "nu[7]": 0.3, "nu[8]": -0.2}


def undamped(tmp_path):
    shutil.copy(FIXTURES / "bench_vehicle.xml", tmp_path / "bench_vehicle.xml")
    modal = json.loads((FIXTURES / "bench.json").read_text())
    for mode in modal["modes"]:
        mode["damping_ratio"] = 0.0
    (tmp_path / "bench.json").write_text(json.dumps(modal))
    return tmp_path / "bench_vehicle.xml"


def test_describe_names_each_mode_after_the_joints(cli):
    description = json.loads(cli.run("describe", FIXTURES / "bench_vehicle.xml", "--json"))
    assert (description["nq"], description["nv"]) == (11, 10)
    modes = description["modes"]
    assert [m["name"] for m in modes] == ["bench:mode1", "bench:mode2", "bench:mode3"]
    assert [m["qpos_adr"] for m in modes] == [8, 9, 10] and [m["dof_adr"] for m in modes] == [7, 8, 9]
    # bench.json gives 1.5, 4 and 9 Hz.
    assert np.allclose([m["frequency"] for m in modes], [1.5, 4.0, 9.0], rtol=1e-12)
    text = cli.run("describe", FIXTURES / "bench_vehicle.xml")
    assert "bench:mode3, 9.000 Hz" in text


def test_the_modes_keep_the_mechanical_energy_in_co_simulation_and_model_exchange(cli, tmp_path):
    """Undamped, free-floating, eps = 0: K + modal_strain_energy stays what
    it was (dop853 at 1e-10 per second inside the FMU; CVODE at 1e-10 for
    model exchange), while strain energy and K exchange; the two interfaces
    agree within their tolerances."""
    model = undamped(tmp_path)
    fmu = cli.export(model, tmp_path / "bench.fmu", outputs=["kinetic_energy", "modal_strain_energy"])
    names = ["kinetic_energy", "modal_strain_energy"] + [f"theta[{k}]" for k in range(1, 12)]
    runs = {}
    for interface in ("CoSimulation", "ModelExchange"):
        runs[interface] = fmpy.simulate_fmu(
            fmu, fmi_type=interface, stop_time=3.0, output_interval=0.01, start_values={**START, "tolerance": 1e-10},
            relative_tolerance=1e-10, output=names,
        )
    cs = runs["CoSimulation"]
    energy = cs["kinetic_energy"] + cs["modal_strain_energy"]
    assert cs["modal_strain_energy"].max() - cs["modal_strain_energy"].min() > 0.1 * energy[0]
    drift = np.abs(energy - energy[0]).max() / energy[0]
    assert drift < 1e-8, drift
    me = runs["ModelExchange"]
    difference = max(np.abs(cs[n] - me[n]).max() for n in names[2:])
    assert difference < 1e-6, difference


def test_a_rigid_vehicle_reports_no_strain_energy(cli, tmp_path):
    fmu = cli.export(ROOT / "examples" / "bus_arm7.xml", tmp_path / "bus.fmu", outputs=["modal_strain_energy"])
    result = fmpy.simulate_fmu(fmu, stop_time=0.1, output=["modal_strain_energy"])
    assert np.all(result["modal_strain_energy"] == 0.0)
