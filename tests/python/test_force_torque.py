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

from conftest import ROOT, run_eval
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
    the issue's 1e-6 (relative to max(1, |value|)); returns the result. No
    MuJoCo twin: only these errors are asserted, and the twins feed the
    verdict, which test_corpus.py tests."""
    result = validate_model(model_path, fmu_path, nudyn, [scenario], Settings(twins=0, **settings)).results[0]
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



TENDONS = ROOT / "tests" / "fixtures" / "sensors" / "tendon_force_torque.xml"


def test_spatial_tendons_pull_on_the_bodies_their_sensors_read_as_mujoco(nudyn):
    """tendon_force_torque.xml: spatial tendons pulling subtrees from outside
    (spring, damper, armature, friction loss, limit, a tendon equality, a
    motor; a wrap and a pulley), which MuJoCo 4.0 counts as external forces at their
    path points. sensordata (the tendons' lengths too), qacc and actuator_force at random
    states, the solver run to round-off on MuJoCo's side. (Leaving the
    tendons' forces out of nudyn's sensors put state 0 off by 100 % of its
    largest reading, and leaving the armature's −a·L̈ out put it 6e-4 off,
    both measured by hand.)"""
    model = load_model(TENDONS)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(263)
    references, requests = [], []
    for k in range(40):
        qpos = model.qpos0.copy()
        q = rng.normal(size=4)
        qpos[:3] += rng.normal(0, 0.3, 3)
        qpos[3:7] = q / np.linalg.norm(q)
        qpos[7:] += rng.normal(0, 0.02 if k % 4 == 0 else 0.7, model.nq - 7)
        qvel = rng.normal(0, 0.02 if k % 4 == 0 else 0.6, model.nv)
        ctrl = rng.uniform(-1.2, 1.2, model.nu)
        data.qpos[:], data.qvel[:], data.ctrl[:] = qpos, qvel, ctrl
        mujoco.mj_forward(model, data)
        references.append((data.qacc.copy(), data.sensordata.copy(), data.actuator_force.copy(),
                           data.efc_type.copy()))
        requests.append({"theta": qpos.tolist(), "qvel": qvel.tolist(), "ctrl": ctrl.tolist()})
    result = run_eval(nudyn, TENDONS, json.dumps(requests))
    kinds = set()
    for k, ((qacc, sensordata, force, efc_type), answer) in enumerate(zip(references, result.json())):
        kinds.update(int(t) for t in efc_type)
        scale = max(1.0, float(np.max(np.abs(qacc))))
        assert np.max(np.abs(np.array(answer["qacc"]) - qacc)) / scale < 1e-12, f"state {k}"
        sensor_scale = max(1.0, float(np.max(np.abs(sensordata))))
        error = np.max(np.abs(np.array(answer["sensordata"]) - sensordata)) / sensor_scale
        assert error < 1e-12, f"state {k}: {error}"
        assert np.max(np.abs(np.array(answer["actuator_force"]) - force)) < 1e-12, f"state {k}"
    # Every kind of tendon row was active in some state.
    for kind in (mujoco.mjtConstraint.mjCNSTR_EQUALITY, mujoco.mjtConstraint.mjCNSTR_FRICTION_TENDON,
                 mujoco.mjtConstraint.mjCNSTR_LIMIT_TENDON):
        assert int(kind) in kinds, kind
