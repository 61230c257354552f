"""The plant FMU's actuator inputs `ctrl[1..nu]`: MuJoCo's d.ctrl, in its
actuator order, added to ε through the vehicle's actuators.

Decided against MuJoCo: the 'actuated' scenario of scripts/validate.py
(random ctrl inside ctrlrange, held over each communication step, both
sides at RK4 1e-4 s for 2 s) on the actuator fixtures (every kind,
transmission, gear, clamp and default rule; the examples with actuators
run it in test_validation.py), within 1e-6 on θ and ν, and through FMI 3.0
and model exchange; the FMU's own rules (clamping, NaN, FMU states, input
ramps) against itself and `nudyn simulate`."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
import zipfile

import mujoco
import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException

from conftest import EXAMPLES, ROOT
from nudyn_driver.instance import Instance
from nudyn_driver.package import FmuPackage
from nudyn_validation.compare import Settings, validate_model
from nudyn_validation.mujoco_reference import load_model
from nudyn_validation.scenarios import FORCED_TOLERANCE

FIXTURES = sorted((ROOT / "tests" / "fixtures" / "actuators").glob("*.xml")) + sorted(
    (ROOT / "tests" / "fixtures" / "sensors").glob("*.xml")
)
ACTUATED = [path for path in FIXTURES if load_model(path).nu > 0]
SERVICER = ROOT / "examples" / "servicer.xml"


def check_actuated(model_path, fmu_path, nudyn, settings=None):
    # No MuJoCo twin: only the FMU's errors against MuJoCo are asserted
    # here; the twins feed the verdict, which test_corpus.py tests.
    settings = settings or Settings(twins=0)
    result = validate_model(model_path, fmu_path, nudyn, ["actuated"], settings).results[0]
    x = result.summary()
    report = json.dumps(x, indent=1)
    assert x["tolerance"] == FORCED_TOLERANCE
    assert x["max_theta_error"] <= FORCED_TOLERANCE and x["max_nu_error"] <= FORCED_TOLERANCE, report
    # Every sensordata entry, MuJoCo's evaluated at the state reached with the ctrl held.
    nsensordata = load_model(model_path).nsensordata
    assert result.fmu.sensordata.shape == result.mujoco.sensordata.shape == (201, nsensordata)
    assert x["max_sensordata_error"] <= FORCED_TOLERANCE, report
    assert result.ctrl.shape == (200, load_model(model_path).nu) and np.any(result.ctrl != 0.0)
    return result


def test_every_actuator_file_is_covered():
    # Every actuator fixture has actuators; the sensor fixtures may have none.
    actuator_files = sorted((ROOT / "tests" / "fixtures" / "actuators").glob("*.xml"))
    assert set(actuator_files) <= set(ACTUATED) and len(ACTUATED) >= 4
    assert any(load_model(path).nu > 0 for path in EXAMPLES), "test_validation.py runs 'actuated' on an example"



@pytest.mark.parametrize("path", ACTUATED, ids=[p.stem for p in ACTUATED])
def test_actuated_fmu_moves_like_mujoco(path, nudyn, tmp_path):
    check_actuated(path, tmp_path / f"{path.stem}.fmu", nudyn)


@pytest.mark.parametrize("fmi_version, interface", [(3, "cs"), (2, "me"), (3, "me")])
def test_actuated_through_every_interface(fmi_version, interface, nudyn, tmp_path):
    settings = Settings(fmi_version=fmi_version, interface=interface, twins=0)
    check_actuated(SERVICER, tmp_path / "servicer.fmu", nudyn, settings)


def test_the_controls_move_the_vehicle(nudyn, tmp_path):
    """The same start with ctrl held at 0 ends elsewhere: the comparison
    above compares motions that the controls shape."""
    actuated = check_actuated(SERVICER, tmp_path / "a.fmu", nudyn)
    at_rest = validate_model(SERVICER, tmp_path / "b.fmu", nudyn, ["tumble"], Settings(twins=0)).results[0]
    assert np.max(np.abs(actuated.fmu.nu[-1] - at_rest.fmu.nu[-1])) > 1e-2


@pytest.fixture(scope="module")
def servicer(cli, tmp_path_factory):
    directory = tmp_path_factory.mktemp("servicer")
    fmu = cli.export(SERVICER, directory / "servicer.fmu")
    return fmu, FmuPackage.unzip(fmu, directory / "unzipped")


def test_ports_are_mujocos_actuators_in_order(servicer):
    fmu, _ = servicer
    model = load_model(SERVICER)
    description = read_model_description(str(fmu))
    by_name = {v.name: v for v in description.modelVariables}
    controls = [v for v in description.modelVariables if v.name.startswith("ctrl[")]
    assert [v.name for v in controls] == [f"ctrl[{k}]" for k in range(1, model.nu + 1)]
    for k, variable in enumerate(controls):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, k)
        assert (variable.causality, variable.variability, float(variable.start)) == ("input", "continuous", 0.0)
        assert f"'{name}'" in variable.description, variable.description
        low, high = model.actuator_ctrlrange[k]
        assert f"clamped to ctrlrange [{low:g}, {high:g}]" in variable.description, variable.description
    assert "motor 'thr_aft_pp': site 'thr_aft_pp', gear (0, 0, -1, 0, 0, 0)" in controls[0].description
    assert "position 'elbow': joint 'elbow'" in controls[13].description
    # ν̇ and the accelerometer depend on every control; θ̇, θ, ν, the other
    # sensors and the optional outputs on none.
    names = [v.name for v in description.modelVariables]
    control_indices = {names.index(v.name) + 1 for v in controls}
    with zipfile.ZipFile(fmu) as archive:
        structure = ET.fromstring(archive.read("modelDescription.xml")).find("ModelStructure")
    unknowns = [*structure.find("Derivatives"), *structure.find("Outputs")]
    for unknown in unknowns:
        dependencies = set(map(int, (unknown.get("dependencies") or "").split()))
        variable = description.modelVariables[int(unknown.get("index")) - 1]
        # The accelerometer feeds through from the controls, as ν̇ does.
        if variable.name.startswith("der(nu[") or "'specific_force'" in (variable.description or ""):
            assert control_indices <= dependencies
        else:
            assert not control_indices & dependencies
    assert by_name["ctrl[1]"].valueReference == by_name["eps[1]"].valueReference + model.nv


def test_fmi3_ctrl_is_one_array(cli, tmp_path):
    fmu = cli.export(SERVICER, tmp_path / "servicer3.fmu", fmi_version=3)
    ctrl = {v.name: v for v in read_model_description(str(fmu)).modelVariables}["ctrl"]
    assert ctrl.causality == "input" and [int(d.start) for d in ctrl.dimensions] == [load_model(SERVICER).nu]


def instance(package, name, ctrl=None):
    slave = Instance(package, name=name, start={"method": "rk4", "max_step": 1e-3})
    if ctrl is not None:
        slave.set_array("ctrl", ctrl)
    return slave


def advance(slave, steps, size=0.01):
    for _ in range(steps):
        slave.step(size)


def test_out_of_range_ctrl_is_clamped_as_mujoco_does(servicer):
    """A thrust of 1000 N on a thruster limited to 22 N, a wheel torque of
    -5 N m limited to -0.2: MuJoCo clamps ctrl to ctrlrange, and so does the FMU."""
    _, package = servicer
    nu = load_model(SERVICER).nu
    beyond, at_limit = np.zeros(nu), np.zeros(nu)
    beyond[0], at_limit[0] = 1000.0, 22.0
    beyond[8], at_limit[8] = -5.0, -0.2
    with instance(package, "beyond", beyond) as a, instance(package, "at", at_limit) as b:
        advance(a, 5)
        advance(b, 5)
        assert np.array_equal(a.array("ctrl"), beyond), "ctrl reads back as set"
        assert np.array_equal(a.array("nu"), b.array("nu")) and np.array_equal(a.array("theta"), b.array("theta"))
        assert np.max(np.abs(a.array("nu"))) > 1e-3


def test_non_finite_ctrl_is_discarded_and_changes_nothing(servicer):
    _, package = servicer
    with instance(package, "nan") as slave:
        advance(slave, 1)
        before = slave.all_reals()
        for value in (float("nan"), float("inf")):
            with pytest.raises(FMICallException) as discarded:
                slave.set({"ctrl[3]": value})
            assert discarded.value.status == 2 and "ctrl[3] =" in slave.log.text()
            assert np.array_equal(slave.all_reals(), before)
        advance(slave, 1)


def test_fmu_state_carries_the_controls(servicer):
    _, package = servicer
    nu = load_model(SERVICER).nu
    first, second = np.linspace(0.0, 1.0, nu), np.linspace(1.0, -1.0, nu)
    with instance(package, "state", first) as slave:
        advance(slave, 2)
        state = slave.fmu.getFMUstate()
        blob = slave.fmu.serializeFMUstate(state)
        advance(slave, 3)
        after = slave.all_reals()
        slave.set_array("ctrl", second)
        restored = slave.fmu.deSerializeFMUstate(blob)
        slave.fmu.setFMUstate(restored)
        assert np.array_equal(slave.array("ctrl"), first)
        slave.time = 0.02
        advance(slave, 3)
        assert np.array_equal(slave.all_reals(), after)
        slave.fmu.freeFMUstate(restored)
        slave.fmu.freeFMUstate(state)


def test_ctrl_ramp_is_a_first_order_hold(servicer):
    """fmi2SetRealInputDerivatives on ctrl ramps it within the next step:
    one step of 0.01 s with (c, r) equals two of 0.005 s with (c, r) and
    (c + r·0.005, r), internal steps falling on the same times."""
    _, package = servicer
    nu = load_model(SERVICER).nu
    ctrl, rate = np.full(nu, 0.1), np.linspace(-20.0, 20.0, nu)
    refs = package.refs("ctrl")
    with instance(package, "one", ctrl) as one, instance(package, "two", ctrl) as two, instance(package, "held", ctrl) as held:
        one.fmu.setRealInputDerivatives(refs, [1] * nu, list(rate))
        one.step(0.01)
        two.fmu.setRealInputDerivatives(refs, [1] * nu, list(rate))
        two.step(0.005)
        two.set_array("ctrl", ctrl + rate * 0.005)
        two.fmu.setRealInputDerivatives(refs, [1] * nu, list(rate))
        two.step(0.005)
        held.step(0.01)
        np.testing.assert_allclose(one.array("nu"), two.array("nu"), rtol=1e-13, atol=1e-13)
        assert np.max(np.abs(one.array("nu") - held.array("nu"))) > 1e-6, "the ramp changes the step"


def test_fmu_equals_core_integration_with_ctrl(servicer, cli):
    """`nudyn simulate` with the same held ctrl and internal step, without the FMI layer."""
    _, package = servicer
    nu = load_model(SERVICER).nu
    ctrl = np.random.default_rng(3).uniform(-0.2, 0.2, nu)
    with instance(package, "core", ctrl) as slave:
        state = {p: [float(x) for x in slave.array(p)] for p in ("theta", "nu")}
        slave.step(0.004)
        request = json.dumps({**state, "ctrl": [float(c) for c in ctrl]})
        core = json.loads(cli.run("simulate", SERVICER, "--method", "rk4", "--step", "1e-3", "--stop", "4e-3", stdin=request))
        np.testing.assert_allclose(slave.array("theta"), core["theta"][-1], rtol=1e-14, atol=1e-14)
        np.testing.assert_allclose(slave.array("nu"), core["nu"][-1], rtol=1e-14, atol=1e-14)
