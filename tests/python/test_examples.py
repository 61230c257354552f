"""The example vehicles load in MuJoCo and are what their comments say."""

from __future__ import annotations

import subprocess
import sys

import mujoco
import numpy as np
import pytest

from conftest import EXAMPLES, EXAMPLES_DIR, ROOT, example_ids

FREE, BALL, SLIDE, HINGE = (
    mujoco.mjtJoint.mjJNT_FREE,
    mujoco.mjtJoint.mjJNT_BALL,
    mujoco.mjtJoint.mjJNT_SLIDE,
    mujoco.mjtJoint.mjJNT_HINGE,
)


def load(name):
    return mujoco.MjModel.from_xml_path(str(EXAMPLES_DIR / f"{name}.xml"))


@pytest.mark.parametrize("path", EXAMPLES, ids=example_ids())
def test_loads_and_is_documented(path):
    m = mujoco.MjModel.from_xml_path(str(path))
    assert m.nv > 0 and np.all(m.body_mass[1:] >= 0)
    text = path.read_text()
    assert text.lstrip().startswith("<!--"), "each example opens with a comment saying what it is"
    # Joint limits (" range=", "limited") are outside the supported set;
    # actuators' ctrlrange and forcerange are inside it.
    for banned in ("tendon", "equality", " range=", "limited", "frictionloss", "mesh"):
        assert banned not in text, f"{path.name} uses {banned.strip()}, a feature outside the supported set"


def test_bus_arm7():
    m = load("bus_arm7")
    assert m.jnt_type[0] == FREE and list(m.jnt_type[1:]) == [HINGE] * 7
    assert abs(m.body_mass[1] - 1000) < 1e-9
    assert not np.any(m.opt.gravity)
    assert all(5 <= mass <= 20 for mass in m.body_mass[2:])


def test_flexible_boom():
    m = load("flexible_boom")
    types = list(m.jnt_type)
    assert types[0] == FREE and types.count(BALL) == 2 and types.count(SLIDE) == 1
    assert np.count_nonzero(m.jnt_stiffness) >= 4 and np.count_nonzero(m.dof_damping) >= 4
    assert np.count_nonzero(m.dof_armature) >= 3
    assert np.any(m.qpos_spring != m.qpos0), "some springref differs from ref"
    assert not np.any(m.opt.gravity)


def test_fixed_rig():
    m = load("fixed_rig")
    assert FREE not in list(m.jnt_type) and SLIDE in list(m.jnt_type)
    assert np.allclose(m.opt.gravity, [0, 0, -9.81])
    assert np.count_nonzero(m.qpos0) >= 2, "joints with ref != 0"
    assert 'angle="degree"' in (EXAMPLES_DIR / "fixed_rig.xml").read_text()


def test_chain60_is_generated():
    m = load("chain60")
    assert m.nbody == 62 and m.jnt_type[0] == FREE and list(m.jnt_type[1:]) == [HINGE] * 60
    out = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "gen_chain.py")],
        capture_output=True, text=True, check=True,
    ).stdout
    assert out == (EXAMPLES_DIR / "chain60.xml").read_text(), (
        "examples/chain60.xml is out of date: python3 scripts/gen_chain.py > examples/chain60.xml"
    )


def test_servicer():
    m = load("servicer")
    assert m.jnt_type[0] == FREE and list(m.jnt_type[1:]) == [HINGE] * 7
    assert not np.any(m.opt.gravity)
    site, joint = int(mujoco.mjtTrn.mjTRN_SITE), int(mujoco.mjtTrn.mjTRN_JOINT)
    thrusters = [i for i in range(m.nu) if m.actuator_trntype[i] == site]
    assert len(thrusters) == 8
    for i in thrusters:
        # A thrust along the nozzle site's -z axis, never negative.
        assert list(m.actuator_gear[i]) == [0, 0, -1, 0, 0, 0] and m.actuator_ctrlrange[i][0] == 0
    wheels = [i for i in range(m.nu) if m.actuator_trntype[i] == joint and m.actuator_biastype[i] == 0]
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    # Motors on hinges about the bus's x, y and z axes (the bus sits at the identity).
    axes = np.array([d.xaxis[m.actuator_trnid[i, 0]] for i in wheels])
    np.testing.assert_allclose(axes, np.eye(3), atol=1e-12)
    servos = [i for i in range(m.nu) if m.actuator_gainprm[i, 0] == -m.actuator_biasprm[i, 1] != 0]
    assert len(servos) == 4 and all(m.actuator_biasprm[i, 2] < 0 for i in servos), "position servos with damping"
