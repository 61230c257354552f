"""`nudyn describe`: the joints and their θ/ν addresses, which scripts use
instead of reading variable descriptions, are MuJoCo's own."""

from __future__ import annotations

import json
import subprocess

import mujoco
import numpy as np
import pytest

from conftest import EXAMPLES, IMPORTER_FIXTURES, ROOT, example_ids

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


TENDON_FIXTURES = sorted((ROOT / "tests" / "fixtures" / "tendons").glob("*.xml"))


@pytest.mark.parametrize("path", TENDON_FIXTURES, ids=lambda p: p.stem)
def test_tendons_are_mujocos(nudyn, path):
    """Each tendon's kind, joints and coefficients or path, qpos0 length,
    spring lengths, stiffness, damping, friction loss and range, against
    MuJoCo's compiled model."""
    proc = subprocess.run([str(nudyn), "describe", str(path), "--json"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    tendons = json.loads(proc.stdout)["tendons"]
    m = mujoco.MjModel.from_xml_path(str(path))
    assert len(tendons) == m.ntendon > 0
    wrap_kinds = {int(mujoco.mjtWrap.mjWRAP_JOINT): "joint", int(mujoco.mjtWrap.mjWRAP_SITE): "site",
                  int(mujoco.mjtWrap.mjWRAP_SPHERE): "geom", int(mujoco.mjtWrap.mjWRAP_CYLINDER): "geom",
                  int(mujoco.mjtWrap.mjWRAP_PULLEY): "pulley"}
    for t, tendon in enumerate(tendons):
        assert tendon["name"] == (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_TENDON, t) or None)
        wraps = range(m.tendon_adr[t], m.tendon_adr[t] + m.tendon_num[t])
        kinds = [wrap_kinds[int(m.wrap_type[w])] for w in wraps]
        if tendon["kind"] == "fixed":
            assert set(kinds) == {"joint"} and not tendon["path"]
            assert [j["joint"] for j in tendon["joints"]] == [m.joint(m.wrap_objid[w]).name for w in wraps]
            np.testing.assert_array_equal([j["coef"] for j in tendon["joints"]], m.wrap_prm[list(wraps)])
        else:
            assert [p["type"] for p in tendon["path"]] == kinds and not tendon["joints"]
            for w, point in zip(wraps, tendon["path"]):
                if point["type"] == "site":
                    assert point["name"] == (m.site(m.wrap_objid[w]).name or None)
                elif point["type"] == "geom":
                    assert point["radius"] == m.geom_size[m.wrap_objid[w]][0]
                    assert point["shape"] == ("cylinder" if m.wrap_type[w] == mujoco.mjtWrap.mjWRAP_CYLINDER else "sphere")
                else:
                    assert point["divisor"] == m.wrap_prm[w]
        assert tendon["length0"] == pytest.approx(m.tendon_length0[t], rel=1e-13, abs=1e-15)
        np.testing.assert_allclose(tendon["springlength"], m.tendon_lengthspring[t], rtol=1e-13, atol=1e-15)
        assert (tendon["stiffness"], tendon["damping"]) == (m.tendon_stiffness[t], m.tendon_damping[t])
        assert tendon["frictionloss"] == m.tendon_frictionloss[t]
        assert tendon["range"] == (list(m.tendon_range[t]) if m.tendon_limited[t] else None)


def test_each_column_starts_where_its_heading_does(nudyn):
    """The joints' table is as wide as its longest entry: a modal row's
    name (`array_right:mode2, 10.062 Hz`, 28 characters) does not push its
    row's later columns off their headings."""
    path = ROOT / "examples" / "flexible_spacecraft" / "flexible_spacecraft.xml"
    text = subprocess.run([str(nudyn), "describe", str(path)], capture_output=True, text=True, check=True).stdout
    lines = text.splitlines()
    header = lines.index(next(line for line in lines if line.startswith("joint ")))
    body, kind = lines[header].index("body"), lines[header].index("kind")
    rows = lines[header + 1:lines.index("", header)]
    assert any(row.startswith("array_right:mode2, 10.062 Hz ") for row in rows)
    for row in rows:
        assert row[body - 1] == " " and row[body] != " " and row[kind:].split()[0] in ("free", "hinge", "mode"), row
