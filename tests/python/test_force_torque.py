"""The force and torque sensors (MuJoCo's interaction force of a body with
its parent, `cfrc_int`) through the FMU, against MuJoCo 4.0.

test_sensors.py compares them with `mj_forward` at random states on
tests/fixtures/sensors/force_torque.xml (an arm under gravity, a body
welded to a link, a site thruster) and test_constraints.py on
docked_servicer.xml (welds, a connect, a joint coupling, limits and
friction loss). Here both files fly through their FMU (RK4 at 1e-4 s on
both sides): docked_servicer for 5 s of random ctrl (the issue's figure),
force_torque under random ctrl and under random wrench inputs (MuJoCo's
xfrc_applied, which the sensors must take out as MuJoCo does) on a link,
on the body welded to it and on the tool, and through FMI 3.0 and model
exchange.
"""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest

from conftest import ROOT
from nudyn_validation.compare import Settings, validate_model
from nudyn_validation.mujoco_reference import load_model
from nudyn_validation.scenarios import FORCED_TOLERANCE

DOCKED = ROOT / "tests" / "fixtures" / "constraints" / "docked_servicer.xml"
ARM = ROOT / "tests" / "fixtures" / "sensors" / "force_torque.xml"


def force_torque_columns(model: mujoco.MjModel) -> list[int]:
    """The sensordata entries of the force and torque sensors."""
    kinds = (int(mujoco.mjtSensor.mjSENS_FORCE), int(mujoco.mjtSensor.mjSENS_TORQUE))
    return [
        model.sensor_adr[k] + j
        for k in range(model.nsensor)
        if int(model.sensor_type[k]) in kinds
        for j in range(model.sensor_dim[k])
    ]


def check(model_path, scenario, fmu_path, nudyn, **settings):
    """One scenario through the FMU: θ, ν and every sensordata entry within
    the issue's 1e-6 (relative to max(1, |value|)); returns the result."""
    result = validate_model(model_path, fmu_path, nudyn, [scenario], Settings(**settings)).results[0]
    x = result.summary()
    report = json.dumps(x, indent=1)
    assert x["max_theta_error"] <= FORCED_TOLERANCE and x["max_nu_error"] <= FORCED_TOLERANCE, report
    assert x["max_sensordata_error"] <= FORCED_TOLERANCE, report
    return result


def test_docked_servicer_reads_its_forces_like_mujoco_over_5_s(nudyn, tmp_path):
    """5 s of random ctrl into the limits, welds and connect holding: the
    force and torque sensors along the arm agree with MuJoCo's, and they
    read forces worth reading (the connect pulls on the gripper)."""
    result = check(DOCKED, "actuated", tmp_path / "docked.fmu", nudyn, duration=5.0)
    model = load_model(DOCKED)
    columns = force_torque_columns(model)
    assert len(columns) == 30
    readings = result.mujoco.sensordata[:, columns]
    assert np.max(np.abs(readings)) > 10.0
    scaled = np.abs(result.fmu.sensordata[:, columns] - readings) / np.maximum(1.0, np.abs(readings))
    assert np.max(scaled) <= FORCED_TOLERANCE


@pytest.mark.parametrize(
    "scenario, settings",
    [
        ("actuated", {}),
        ("wrenched", {"wrench_bodies": ("forearm", "camera", "tool")}),
        ("actuated", {"fmi_version": 3}),
        ("actuated", {"interface": "me"}),
    ],
    ids=["actuated", "wrenched", "fmi3", "model_exchange"],
)
def test_an_arm_under_gravity_reads_its_forces_like_mujoco(scenario, settings, nudyn, tmp_path):
    """Under gravity, with a thruster on the tool, and with wrench inputs on
    a link, on the body welded to it and on the tool: every force and torque
    sensor (on the world, the pedestal fixed to it, each link, the welded
    camera) agrees with MuJoCo's through the flight, through FMI 2.0 and 3.0
    co-simulation and model exchange (FMPy's CVODE)."""
    result = check(ARM, scenario, tmp_path / "arm.fmu", nudyn, **settings)
    columns = force_torque_columns(load_model(ARM))
    assert np.max(np.abs(result.mujoco.sensordata[:, columns])) > 10.0

