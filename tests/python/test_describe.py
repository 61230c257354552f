"""`nudyn describe`: the joints and their θ/ν addresses, which scripts use
instead of reading variable descriptions, are MuJoCo's own."""

from __future__ import annotations

import json
import subprocess

import mujoco
import numpy as np
import pytest

from conftest import EXAMPLES, IMPORTER_FIXTURES, example_ids

KINDS = {
    int(mujoco.mjtJoint.mjJNT_FREE): "free",
    int(mujoco.mjtJoint.mjJNT_BALL): "ball",
    int(mujoco.mjtJoint.mjJNT_SLIDE): "slide",
    int(mujoco.mjtJoint.mjJNT_HINGE): "hinge",
}
SIZES = {"free": (7, 6), "ball": (4, 3), "slide": (1, 1), "hinge": (1, 1)}


@pytest.mark.parametrize("path", EXAMPLES + IMPORTER_FIXTURES, ids=lambda p: p.stem)
def test_joints_and_addresses_are_mujocos(nudyn, path):
    proc = subprocess.run([str(nudyn), "describe", str(path), "--json"], capture_output=True, text=True)
    if proc.returncode != 0:
        pytest.skip(f"nudyn does not import {path.name}: {proc.stderr.strip()}")
    described = json.loads(proc.stdout)
    m = mujoco.MjModel.from_xml_path(str(path))
    assert (described["nq"], described["nv"]) == (m.nq, m.nv)
    np.testing.assert_allclose(described["qpos0"], m.qpos0, rtol=0, atol=1e-12)
    gravity_off = m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_GRAVITY
    np.testing.assert_allclose(described["gravity"], 0.0 * m.opt.gravity if gravity_off else m.opt.gravity, atol=0)
    assert len(described["joints"]) == m.njnt
    for j, joint in enumerate(described["joints"]):
        kind = KINDS[int(m.jnt_type[j])]
        assert joint["kind"] == kind
        assert (joint["qpos_adr"], joint["dof_adr"]) == (m.jnt_qposadr[j], m.jnt_dofadr[j])
        assert (joint["nq"], joint["nv"]) == SIZES[kind]
        body = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, m.jnt_bodyid[j])
        if body is not None:  # nudyn names the unnamed ones
            assert joint["body"] == body
        expected_quaternion = {"free": m.jnt_qposadr[j] + 3, "ball": m.jnt_qposadr[j]}.get(kind)
        assert joint["quaternion_adr"] == expected_quaternion
