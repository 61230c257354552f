"""The exported FMU, run in FMPy, against MuJoCo's RK4 simulation of the same
MJCF (nudyn_validation, the code behind scripts/validate.py): every example,
every scenario that applies, 2 s.  The issue's tolerances decide it:
max |θ error| and |ν error| ≤ 1e-8 with ε = 0, ≤ 1e-6 with inputs."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from fmpy import read_model_description

from conftest import EXAMPLES, ROOT
from nudyn_validation.compare import Settings, validate_model
from nudyn_validation.judgement import judge
from nudyn_validation.mujoco_reference import load_model
from nudyn_validation.mujoco_run import MujocoVehicle
from nudyn_validation.scenarios import FORCED_TOLERANCE, UNFORCED_TOLERANCE, default_scenarios

CASES = [(path, name) for path in EXAMPLES for name in default_scenarios(load_model(path))]


@pytest.fixture(scope="module")
def validated(nudyn, tmp_path_factory):
    """validated(path): the default validation of an example, run once,
    without MuJoCo's twins: the tests assert the errors against the
    tolerance, and the verdict from the twins is tested in test_corpus.py."""
    done = {}

    def get(path):
        if path not in done:
            fmu = tmp_path_factory.mktemp("validation") / f"{path.stem}.fmu"
            done[path] = {r.scenario.name: r for r in validate_model(path, fmu, nudyn, None, Settings(twins=0)).results}
        return done[path]

    return get


def test_every_kind_of_scenario_is_run():
    assert {name for _, name in CASES} == {"tumble", "sine", "damping", "gravity", "actuated"}
    assert ("fixed_rig", "gravity") in {(p.stem, n) for p, n in CASES}


@pytest.mark.parametrize("path, scenario", CASES, ids=[f"{p.stem}-{n}" for p, n in CASES])
def test_fmu_moves_like_mujoco(path, scenario, validated):
    result = validated(path)[scenario]
    x = result.summary()
    tolerance = UNFORCED_TOLERANCE if scenario in ("tumble", "gravity") else FORCED_TOLERANCE
    assert x["tolerance"] == tolerance
    report = json.dumps(x, indent=1)
    assert x["max_theta_error"] <= tolerance, report
    assert x["max_nu_error"] <= tolerance, report
    assert x["max_sensordata_error"] <= tolerance, report
    # K and the momentum follow from θ and ν: the same tolerance, relative
    # to their size.
    k_scale = max(1.0, float(np.max(result.mujoco.kinetic_energy)))
    assert x["max_kinetic_energy_error"] <= tolerance * k_scale, report
    h_scale = max(1.0, float(np.max(np.abs(result.mujoco.momentum))))
    assert x["max_momentum_error"] <= tolerance * h_scale, report
    moved = np.max(np.abs(result.mujoco.theta[-1] - result.mujoco.theta[0]))
    assert moved > 1e-2, "the vehicle must actually move"
    if scenario in ("sine", "damping"):
        assert np.max(np.abs(result.eps)) > 0.0


def test_energy_drift_where_energy_is_conserved(validated):
    """bus_arm7 has no dampers, springs or gravity: K is conserved in free
    tumbling, on both sides, to far below the tolerance."""
    result = validated(ROOT / "examples" / "bus_arm7.xml")["tumble"]
    x = result.summary()
    k = x["kinetic_energy_start"]
    assert k > 1.0
    assert x["energy_drift_fmu"] <= 1e-10 * k and x["energy_drift_mujoco"] <= 1e-10 * k


def test_comparison_detects_a_wrong_input_mapping(nudyn, tmp_path, monkeypatch):
    """If MuJoCo were given T = ε instead of T = m(θ) ε, the sine scenario
    would fail by far: the check can fail."""

    def apply_eps_as_torque(self, model, data):
        data.qfrc_applied[:] = self.held_eps

    monkeypatch.setattr(MujocoVehicle, "_apply_held_eps", apply_eps_as_torque)
    settings = Settings(duration=0.2)
    validation = validate_model(ROOT / "examples/bus_arm7.xml", tmp_path / "bus.fmu", nudyn, ["sine"], settings)
    assert validation.results[0].summary()["max_nu_error"] > 1e3 * FORCED_TOLERANCE
    assert not validation.passed


def test_without_twins_the_verdict_is_the_tolerances(nudyn, tmp_path):
    """Settings(twins=0) runs MuJoCo once: no twin divergence, so an error
    within the tolerance agrees and one beyond it disagrees (never "chaotic")."""
    validation = validate_model(ROOT / "examples/fixed_rig.xml", tmp_path / "rig.fmu", nudyn, ["sine"],
                                Settings(duration=0.1, twins=0))
    result = validation.results[0]
    assert result.twins == [] and np.array_equal(result.twin_divergence(), np.zeros(len(result.time)))
    x = result.summary()
    assert x["max_twin_divergence"] == 0.0 and x["verdict"] == "agrees" and validation.passed, x
    assert judge(2 * x["tolerance"], x["max_twin_divergence"], x["tolerance"]) == "disagrees"


def test_actuators_act_on_neither_side(nudyn, tmp_path):
    """nudyn ignores actuators, so the validation silences MuJoCo's: a
    position servo (which pulls even at ctrl = 0) changes nothing."""
    model = tmp_path / "servo.xml"
    model.write_text(
        '<mujoco><option gravity="0 0 -9.81"/><worldbody><body pos="0 0 1"><joint name="j" axis="0 1 0"/>'
        '<geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.05"/></body></worldbody>'
        '<actuator><position joint="j" kp="50"/></actuator></mujoco>'
    )
    validation = validate_model(model, tmp_path / "servo.fmu", nudyn, ["gravity"], Settings(duration=0.5))
    assert validation.passed, validation.results[0].summary()


def run_command(*args):
    cmd = [sys.executable, str(ROOT / "scripts" / "validate.py"), *map(str, args)]
    return subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)


def test_command_writes_picture_table_and_numbers(nudyn, tmp_path):
    out = tmp_path / "rig"
    proc = run_command(ROOT / "examples/fixed_rig.xml", "--duration", "0.2", "--out", out, "--nudyn", nudyn)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    for name in ("fixed_rig.png", "fixed_rig.fmu", "table.md", "results.json"):
        assert (out / name).is_file() and str(out / name) in proc.stdout
    numbers = json.loads((out / "results.json").read_text())
    assert numbers["passed"] and [s["scenario"] for s in numbers["scenarios"]] == [
        "tumble",
        "sine",
        "damping",
        "gravity",
    ]
    # MuJoCo's twin started 1e-13 away and stayed far inside the tolerance.
    for scenario in numbers["scenarios"]:
        assert 0.0 < scenario["max_twin_divergence"] < 1e-10 and scenario["verdict"] == "agrees", scenario
    table = (out / "table.md").read_text()
    assert table.count("| agrees |") == 4 and table in proc.stdout


def test_command_passes_on_the_importers_message(nudyn, tmp_path):
    model = tmp_path / "tendon.xml"
    model.write_text(
        '<mujoco><worldbody><body><joint name="j"/><geom name="g" size="0.1"/><site name="s"/></body>'
        '<site name="w" pos="1 0 0"/></worldbody><tendon><spatial name="t"><site site="s"/>'
        '<geom geom="g" sidesite="w"/><site site="w"/></spatial></tendon></mujoco>'
    )
    proc = run_command(model, "--out", tmp_path / "out", "--nudyn", nudyn)
    assert proc.returncode == 2
    assert "sidesite" in proc.stderr and "line 1" in proc.stderr


@pytest.mark.parametrize(
    "args, message",
    [
        (["--mujoco-step", "3e-3"], "must divide the communication step"),
        (["--method", "no_such_method"], "has no integration method 'no_such_method' (it has: "),
        (["--fmu-parameter", "maxstep=1e-3"], "has no Real parameter maxstep"),
        (["--scenario", "gravity"], "needs a model with gravity"),
    ],
    ids=["mujoco_step", "method", "parameter", "scenario"],
)
def test_command_refuses_bad_settings(nudyn, tmp_path, args, message):
    proc = run_command(ROOT / "examples/bus_arm7.xml", "--duration", "0.1", "--out", tmp_path, "--nudyn", nudyn, *args)
    assert proc.returncode == 2 and message in proc.stderr, proc.stderr


@pytest.mark.parametrize("fmi_version, interface", [(3, "cs"), (2, "me"), (3, "me")])
def test_other_versions_and_interfaces_meet_the_tolerances(nudyn, tmp_path, fmi_version, interface):
    """scripts/validate.py --fmi-version 3 and --interface me (FMPy's CVODE at
    its default rtol) against MuJoCo on the bus with its arm, every scenario:
    within 1e-8 free, 1e-6 with inputs (measured on 2 s: FMI 3.0 co-simulation
    gives FMI 2.0's 1e-13; CVODE at 1e-11 up to 1.5e-9 free, 1.3e-8 with inputs).
    Without MuJoCo's twins a pass is an error within the tolerance itself."""
    settings = Settings(duration=0.5, fmi_version=fmi_version, interface=interface, twins=0)
    validation = validate_model(ROOT / "examples/bus_arm7.xml", tmp_path / "bus.fmu", nudyn, None, settings)
    assert [r.scenario.name for r in validation.results] == ["tumble", "sine", "damping"]
    for result in validation.results:
        summary = result.summary()
        assert summary["passed"], (result.scenario.name, summary)
    if fmi_version == 3:
        assert read_model_description(str(validation.fmu_path)).fmiVersion == "3.0"
