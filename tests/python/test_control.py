"""Noninteracting control (issue: the paper's controllers as an FMU):
the controller FMU against FMPy's validation, its FMI layer against misuse,
and both demos closed-loop in FMPy and in libcosim, checked against MuJoCo:
the controller's ε is the law (computed from MuJoCo alone) at the state it
was sampled from, V = K + U stays within the sample-and-hold bound, the
detumble reaches |ν| < 1e-6 and the arm its target within 1e-5 m and 1e-5 rad."""

from __future__ import annotations

import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

import controller_misuse
from conftest import ROOT
from nudyn_driver.errors import CommandError
from nudyn_driver.package import FmuPackage
from nudyn_control import demo, scenarios
from nudyn_control.analysis import analyse
from nudyn_control.simulators import export, run_fmpy, run_libcosim, system_structure

EXPECTED_DELAY = {"FMPy": 0, "libcosim": 1}


@pytest.fixture(scope="module")
def demos(nudyn, tmp_path_factory):
    """Both demos, each in both simulators: {scenario: (scenario, [analyses], workdir)}."""
    results = {}
    for name, make in scenarios.SCENARIOS.items():
        scenario = make()
        workdir = tmp_path_factory.mktemp(name)
        analyses, _ = demo.run(scenario, nudyn, workdir)
        results[name] = (scenario, analyses, workdir)
    return results


@pytest.mark.parametrize("simulator", ["FMPy", "libcosim"])
@pytest.mark.parametrize("name", ["detumble", "arm"])
def test_demo_closed_loop(demos, name, simulator):
    scenario, analyses, _ = demos[name]
    analysis = next(a for a in analyses if a.simulator == simulator)
    summary = json.dumps(analysis.summary(), indent=1, default=float)
    assert analysis.delay == EXPECTED_DELAY[simulator], summary
    failed = [check for check, ok in demo.checks(scenario, analysis).items() if not ok]
    assert not failed, f"{failed}\n{summary}"


def test_aggressive_rate_gain_raises_v_within_the_bound(nudyn, tmp_path):
    """c1 h = 0.5: with libcosim's step of delay the sampled loop rings and V
    does rise within steps; every rise stays within both bounds."""
    scenario = scenarios.detumble()
    scenario.duration = 1.0
    scenario.controller = {f"c1[{k}]": 50.0 for k in range(1, 14)}
    plant, controller = export(nudyn, scenario, tmp_path)
    law = demo.law_of(scenario, controller)
    for runner in (run_fmpy, run_libcosim):
        analysis = analyse(runner(plant, controller, scenario, tmp_path), law)
        summary = json.dumps(analysis.summary(), indent=1, default=float)
        assert analysis.bound_violation <= demo.BOUND_SLACK, summary
        assert np.all(analysis.increase <= analysis.ch_bound), summary
        if analysis.simulator == "libcosim":
            assert np.sum(analysis.increase > 0) >= 10, f"V should rise in some steps\n{summary}"
            assert 0.3 < np.max(analysis.increase / analysis.bound) <= 1.0, summary


def test_the_controller_closes_the_loop_on_a_vehicle_with_actuators(nudyn, tmp_path):
    """The servicer's plant has ctrl inputs and sensordata outputs besides
    eps, theta and nu: the controller's eps still connects by name, and its
    rate feedback detumbles the vehicle while the arm servos hold the arm
    (ctrl 0) — in FMPy and in libcosim."""
    mjcf = ROOT / "examples/servicer.xml"
    # Free joint (linear world, angular body), three wheels, four arm joints.
    qvel = [0.02, -0.01, 0.03, 0.2, -0.15, 0.1, 3.0, -2.0, 1.0, 0.2, -0.1, 0.15, 0.3]
    scenario = scenarios.Scenario(
        name="servicer_detumble", title="servicer detumble", mjcf=mjcf, end_effector=None, duration=2.0,
        step=0.01, substeps=2, plant_start=scenarios._nu_start(mjcf, qvel),
    )
    plant, controller = export(nudyn, scenario, tmp_path)
    plant_variables = {v.name for v in read_model_description(str(plant)).modelVariables}
    assert {"ctrl[1]", "sensordata[1]", "eps[13]"} <= plant_variables
    for runner in (run_fmpy, run_libcosim):
        trajectory = runner(plant, controller, scenario, tmp_path)
        start, end = np.linalg.norm(trajectory.nu[0]), np.linalg.norm(trajectory.nu[-1])
        # c1 = 5/s on every dof: |nu| would fall by e^-10 in 2 s; the servos pulling the arm back slow it.
        assert end < 1e-2 * start, f"{trajectory.simulator}: |nu| from {start:.3g} to {end:.3g}"
        assert np.all(np.isfinite(trajectory.eps)) and np.any(trajectory.eps != 0.0)


@pytest.fixture(scope="module")
def controller_fmus(cli, tmp_path_factory):
    directory = tmp_path_factory.mktemp("controllers")
    model = ROOT / "examples/bus_arm7.xml"
    return {
        "joints": cli.export(model, directory / "joints.fmu", controller=True),
        "pose": cli.export(model, directory / "pose.fmu", controller=True, end_effector="end_effector"),
        "plant": cli.export(model, directory / "plant.fmu"),
    }


def test_controller_fmus_validate_and_match_the_plant_by_name(controller_fmus):
    plant = read_model_description(str(controller_fmus["plant"]))
    plant_variables = {v.name: v for v in plant.modelVariables}
    for label in ("joints", "pose"):
        path = controller_fmus[label]
        assert validate_fmu(str(path)) == [], label
        description = read_model_description(str(path))
        variables = {v.name: v for v in description.modelVariables}
        for name, variable in variables.items():
            if name.startswith(("theta[", "nu[")):
                assert variable.causality == "input" and plant_variables[name].causality == "output", name
            if name.startswith("eps["):
                assert (variable.causality, variable.initial) == ("output", "calculated"), name
                assert plant_variables[name].causality == "input", name
            if name.startswith(("c1[", "c2[", "target[", "target_position[", "target_quaternion[")):
                assert (variable.causality, variable.variability, variable.initial) == ("parameter", "tunable", "exact")
        assert {n for n in plant_variables if n.startswith(("theta[", "nu[", "eps["))} == \
            {n for n in variables if n.startswith(("theta[", "nu[", "eps["))}
        assert sum(n.startswith("c1[") for n in variables) == 13
        assert not description.coSimulation.canGetAndSetFMUstate
        # ε depends on θ and ν at once (direct feedthrough).
        eps = next(u for u in description.outputs if u.variable.name == "eps[1]")
        assert {v.name for v in eps.dependencies} == {n for n in variables if n.startswith(("theta[", "nu["))}
    pose = {v.name for v in read_model_description(str(controller_fmus["pose"])).modelVariables}
    assert {"target_position[3]", "target_quaternion[4]", "c2[6]", "potential", "target_error[6]"} <= pose
    joints = {v.name for v in read_model_description(str(controller_fmus["joints"])).modelVariables}
    assert {"target[7]", "c2[7]"} <= joints and "target[8]" not in joints


def test_controller_fmi_layer_refuses_misuse(controller_fmus, tmp_path):
    controller = FmuPackage.unzip(controller_fmus["pose"], tmp_path / "controller")
    plant = FmuPackage.unzip(controller_fmus["plant"], tmp_path / "plant")
    proc = subprocess.run([sys.executable, controller_misuse.__file__, str(controller.directory), str(plant.directory)],
                          capture_output=True, text=True, timeout=120, cwd=Path(controller_misuse.__file__).parent)
    assert proc.returncode >= 0, f"crashed with signal {-proc.returncode}:\n{proc.stderr[-4000:]}"
    assert proc.returncode == 0, proc.stderr[-4000:]
    counts = json.loads(proc.stdout)
    assert counts["refused"] >= 40, counts


def test_bad_controller_requests_are_clear_errors(cli, tmp_path):
    def export_fails(**options) -> str:
        with pytest.raises(CommandError) as failure:
            cli.export(ROOT / "examples/bus_arm7.xml", tmp_path / "x.fmu", **options)
        return failure.value.stderr

    assert "no body named 'gripper'" in export_fails(controller=True, end_effector="gripper")
    assert "--controller" in export_fails(end_effector="end_effector")
    assert "cannot be used with" in export_fails(controller=True, outputs=("qvel",))


def test_system_structure_connects_every_variable_name_to_name():
    scenario = scenarios.arm()
    root = ET.fromstring(system_structure(scenario, 14, 13))
    namespace = {"osp": "http://opensimulationplatform.com/MSMI/OSPSystemStructure"}
    pairs = [[(v.get("simulator"), v.get("name")) for v in c.findall("osp:Variable", namespace)]
             for c in root.find("osp:Connections", namespace)]
    assert len(pairs) == 14 + 13 + 13
    assert all(source[1] == target[1] for source, target in pairs)
    assert sum(source[0] == "controller" for source, _ in pairs) == 13
