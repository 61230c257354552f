"""<replicate> against MuJoCo: tests/fixtures/replicate/ring.xml writes a
ring of four arms on a bus once (each copy moved along the previous one's
axes and turned), with two fingers per arm from a nested replicate; MuJoCo
and nudyn must make the same bodies and joints, with the same names, in
the same order and at the same poses, and the same dynamics."""

from __future__ import annotations

import json
import subprocess

import mujoco
import numpy as np

from conftest import ROOT, run_eval
from nudyn_validation.mujoco_reference import load_model

FIXTURE = ROOT / "tests" / "fixtures" / "replicate" / "ring.xml"


def describe(nudyn, path):
    proc = subprocess.run([nudyn, "describe", "--json", path], capture_output=True, text=True, check=True)
    return json.loads(proc.stdout)


def test_copies_are_mujocos_bodies_and_joints(nudyn):
    model = load_model(FIXTURE)
    described = describe(nudyn, FIXTURE)
    bodies = described["bodies"]
    assert [b["name"] for b in bodies] == [model.body(i).name for i in range(1, model.nbody)]
    assert "finger-1_3" in [b["name"] for b in bodies]
    np.testing.assert_allclose([b["pos"] for b in bodies], model.body_pos[1:], rtol=0, atol=1e-15)
    np.testing.assert_allclose([b["quat"] for b in bodies], model.body_quat[1:], rtol=0, atol=1e-15)
    assert [j["name"] for j in described["joints"]] == [model.joint(i).name for i in range(model.njnt)]
    # The replicate's childclass reached every copy's joints.
    assert np.all(model.dof_damping[6:] == 0.5)


def test_dynamics_match_mujoco(nudyn):
    """θ̈ and sensordata (a frame on a replicated site, a replicated joint,
    a tendon between replicated sites around a replicated geom) at random
    states, with the motor on a replicated joint driven."""
    model = load_model(FIXTURE)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(8)
    references, requests = [], []
    for _ in range(40):
        qpos = model.qpos0.copy()
        q = rng.normal(size=4)
        qpos[:3] += rng.normal(0, 0.3, 3)
        qpos[3:7] = q / np.linalg.norm(q)
        qpos[7:] = rng.uniform(-1, 1, model.nq - 7)
        qvel, ctrl = rng.normal(0, 0.5, model.nv), rng.normal(0, 1, model.nu)
        data.qpos[:], data.qvel[:], data.ctrl[:] = qpos, qvel, ctrl
        mujoco.mj_forward(model, data)
        references.append((data.qacc.copy(), data.sensordata.copy()))
        requests.append({"theta": qpos.tolist(), "qvel": qvel.tolist(), "ctrl": ctrl.tolist()})
    result = run_eval(nudyn, FIXTURE, json.dumps(requests))
    for k, ((qacc, sensordata), answer) in enumerate(zip(references, result.json())):
        scale = max(1.0, float(np.max(np.abs(qacc))))
        assert np.max(np.abs(np.array(answer["qacc"]) - qacc)) / scale < 1e-12, f"state {k}"
        assert np.max(np.abs(np.array(answer["sensordata"]) - sensordata)) < 1e-12, f"state {k}"


BARE_NAMES = ROOT / "tests" / "fixtures" / "replicate" / "bare_names.xml"


def test_actuators_naming_replicated_objects_as_written_are_mujocos_copies(nudyn):
    """bare_names.xml: actuators on joints and sites inside nested and side by
    side replicates, named without the copies' suffixes or with the inner
    one's only, become MuJoCo's copies: its names, targets and order."""
    model = load_model(BARE_NAMES)
    described = describe(nudyn, BARE_NAMES)["actuators"]

    def target(i):
        if model.actuator_trntype[i] == mujoco.mjtTrn.mjTRN_JOINT:
            return model.joint(model.actuator_trnid[i, 0]).name, None
        site, refsite = model.actuator_trnid[i]
        return model.site(site).name, model.site(refsite).name if refsite >= 0 else None

    expected = [(model.actuator(i).name, *target(i)) for i in range(model.nu)]
    assert [(a["name"], a["target"], a["refsite"]) for a in described] == expected
    # Copies of four of the six elements: 12 actuators.
    assert model.nu == 12


def test_sensors_naming_replicated_objects_as_written_read_mujocos_sensordata(nudyn):
    """The sensors of bare_names.xml (joint, frame, force and torque, subtree,
    actuator sensors on copied objects and a copied actuator) in MuJoCo's
    order, and qacc and actuator_force, at random states with every
    actuator driven."""
    model = load_model(BARE_NAMES)
    data = mujoco.MjData(model)
    assert model.nsensor == 21
    rng = np.random.default_rng(47)
    references, requests = [], []
    for _ in range(30):
        qpos = model.qpos0.copy()
        q = rng.normal(size=4)
        qpos[:3] += rng.normal(0, 0.3, 3)
        qpos[3:7] = q / np.linalg.norm(q)
        qpos[7:] = rng.uniform(-0.8, 0.8, model.nq - 7)
        qvel, ctrl = rng.normal(0, 0.5, model.nv), rng.normal(0, 1, model.nu)
        data.qpos[:], data.qvel[:], data.ctrl[:] = qpos, qvel, ctrl
        mujoco.mj_forward(model, data)
        references.append((data.qacc.copy(), data.sensordata.copy(), data.actuator_force.copy()))
        requests.append({"theta": qpos.tolist(), "qvel": qvel.tolist(), "ctrl": ctrl.tolist()})
    result = run_eval(nudyn, BARE_NAMES, json.dumps(requests))
    for k, ((qacc, sensordata, force), answer) in enumerate(zip(references, result.json())):
        scale = max(1.0, float(np.max(np.abs(qacc))))
        assert np.max(np.abs(np.array(answer["qacc"]) - qacc)) / scale < 1e-12, f"state {k}"
        sensor_scale = np.maximum(1.0, np.abs(sensordata))
        assert np.max(np.abs(np.array(answer["sensordata"]) - sensordata) / sensor_scale) < 1e-12, f"state {k}"
        assert np.max(np.abs(np.array(answer["actuator_force"]) - force)) < 1e-12, f"state {k}"
