"""Joints with `springdamper`: the stiffness and damping MuJoCo derives
(its compiler's AutoSpringDamper, from dof_invweight0 in qpos0) act in
nudyn as in MuJoCo (dm_control's dog uses them; they were refused)."""

from __future__ import annotations

import json

import mujoco
import numpy as np

from conftest import ROOT, run_eval

FIXTURE = ROOT / "tests" / "fixtures" / "springs" / "springdamper.xml"


def test_springdamper_joints_move_as_in_mujoco(nudyn):
    model = mujoco.MjModel.from_xml_path(str(FIXTURE))
    assert np.all(model.jnt_stiffness[1:] > 0) and np.all(model.dof_damping[6:] > 0)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(7)
    states, references = [], []
    for _ in range(20):
        data.qpos[:] = model.qpos0
        for j in range(1, model.njnt):
            a = model.jnt_qposadr[j]
            if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL:
                q = rng.normal(size=4)
                data.qpos[a : a + 4] = q / np.linalg.norm(q)
            else:
                data.qpos[a] = rng.normal(0, 0.3)
        data.qvel[:] = rng.normal(0, 0.5, model.nv)
        mujoco.mj_forward(model, data)
        states.append({"theta": data.qpos.tolist(), "qvel": data.qvel.tolist()})
        references.append(data.qacc.copy())
    out = run_eval(nudyn, FIXTURE, json.dumps(states)).json()
    for k, (answer, qacc) in enumerate(zip(out, references)):
        assert np.max(np.abs(np.array(answer["qacc"]) - qacc)) <= 1e-10 * max(1.0, np.max(np.abs(qacc))), k
    # The springs matter: without them MuJoCo's qacc is far from this.
    model.jnt_stiffness[:] = 0
    model.dof_damping[:] = 0
    data.qpos[:], data.qvel[:] = states[-1]["theta"], states[-1]["qvel"]
    mujoco.mj_forward(model, data)
    assert np.max(np.abs(data.qacc - references[-1])) > 1.0
