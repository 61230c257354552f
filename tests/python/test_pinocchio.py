"""`nudyn linearize`'s ∂θ̈/∂(δq, θ̇, T) against Pinocchio's analytic ABA
derivatives (computeABADerivatives), at 100 random states of every example
whose dynamics the derivatives cover (no actuators, tendons or constraints).

Pinocchio's model is built here from MuJoCo's compiled model (body
placements, inertias, joint anchors and axes, armature, gravity), not from
nudyn's, and in MuJoCo's coordinates:

- a free joint is Pinocchio's Translation joint (position and velocity in
  world axes) followed by its Spherical joint (body-frame angular velocity),
  as MuJoCo's qpos and qvel are; Pinocchio's FreeFlyer would take the
  linear velocity in body axes;
- Pinocchio's tangent perturbation (q ⊕ δq: world translation, quaternion
  times exp(δω) in body axes) is MuJoCo's mj_integratePos, which nudyn's
  δq follows;
- springs and dampers are not in Pinocchio's ABA: their joint forces come
  from MuJoCo's qfrc_passive, added to τ, and their derivatives (by central
  differences of qfrc_passive, linear or nearly so) enter through M⁻¹ ∂τ.
"""

from __future__ import annotations

import json
import subprocess
import zlib

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from conftest import EXAMPLES, tangent_jacobian
from nudyn_validation.mujoco_reference import Reference

COVERED = [p for p in EXAMPLES if p.stem in ("bus_arm7", "chain60", "fixed_rig", "flexible_boom")]
STATES = 100
TOLERANCE = 1e-9

FREE, BALL, SLIDE, HINGE = (int(t) for t in (mujoco.mjtJoint.mjJNT_FREE, mujoco.mjtJoint.mjJNT_BALL,
                                             mujoco.mjtJoint.mjJNT_SLIDE, mujoco.mjtJoint.mjJNT_HINGE))


def se3(quat_wxyz=(1.0, 0.0, 0.0, 0.0), pos=(0.0, 0.0, 0.0)) -> pin.SE3:
    w, x, y, z = quat_wxyz
    return pin.SE3(pin.Quaternion(w, x, y, z).normalized().matrix(), np.asarray(pos, dtype=float))


def pinocchio_model(m: mujoco.MjModel) -> tuple[pin.Model, list]:
    """Pinocchio's model of MuJoCo's compiled model, and per MuJoCo joint
    how its qpos maps to Pinocchio's q: (kind, qpos address, q index)."""
    model = pin.Model()
    model.gravity = pin.Motion(np.asarray(m.opt.gravity, dtype=float), np.zeros(3))
    # Per body: the Pinocchio joint it moves with and its frame in that joint's frame.
    joint_of, frame_in_joint = [0] * m.nbody, [pin.SE3.Identity()] * m.nbody
    coordinates = []
    for b in range(1, m.nbody):
        parent = int(m.body_parentid[b])
        joint, frame = joint_of[parent], frame_in_joint[parent] * se3(m.body_quat[b], m.body_pos[b])
        for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b]):
            kind, anchor, axis = int(m.jnt_type[j]), np.asarray(m.jnt_pos[j]), np.asarray(m.jnt_axis[j])
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint{j}"
            if kind == FREE:
                # The pose comes from qpos alone: world-aligned translation, then rotation.
                translation = model.addJoint(joint, pin.JointModelTranslation(), pin.SE3.Identity(), name + ":x")
                model.appendBodyToJoint(translation, pin.Inertia.Zero(), pin.SE3.Identity())
                joint = model.addJoint(translation, pin.JointModelSpherical(), pin.SE3.Identity(), name + ":r")
                frame = pin.SE3.Identity()
            elif kind == SLIDE:
                joint = model.addJoint(joint, pin.JointModelPrismaticUnaligned(axis), frame, name)
                frame = pin.SE3.Identity()
            else:
                model_joint = pin.JointModelSpherical() if kind == BALL else pin.JointModelRevoluteUnaligned(axis)
                joint = model.addJoint(joint, model_joint, frame * se3(pos=anchor), name)
                frame = se3(pos=-anchor)
            # A free joint's two Pinocchio joints are consecutive: q and v start at the first.
            first = model.joints[joint - 1 if kind == FREE else joint]
            dofs = 6 if kind == FREE else model.joints[joint].nv
            coordinates.append((kind, int(m.jnt_qposadr[j]), first.idx_q))
            model.armature[first.idx_v:first.idx_v + dofs] = m.dof_armature[m.jnt_dofadr[j]:m.jnt_dofadr[j] + dofs]
            if j + 1 < m.body_jntadr[b] + m.body_jntnum[b]:
                model.appendBodyToJoint(joint, pin.Inertia.Zero(), pin.SE3.Identity())
        rotation = pin.Quaternion(*m.body_iquat[b]).normalized().matrix()
        inertia = pin.Inertia(float(m.body_mass[b]), np.asarray(m.body_ipos[b]),
                              rotation @ np.diag(m.body_inertia[b]) @ rotation.T)
        model.appendBodyToJoint(joint, inertia, frame)
        joint_of[b], frame_in_joint[b] = joint, frame
    return model, coordinates


def pinocchio_q(m: mujoco.MjModel, model: pin.Model, coordinates, qpos) -> np.ndarray:
    q = np.zeros(model.nq)
    for kind, adr, idx in coordinates:
        if kind == FREE:
            q[idx:idx + 3] = qpos[adr:adr + 3]
            w, x, y, z = qpos[adr + 3:adr + 7] / np.linalg.norm(qpos[adr + 3:adr + 7])
            q[idx + 3:idx + 7] = (x, y, z, w)
        elif kind == BALL:
            w, x, y, z = qpos[adr:adr + 4] / np.linalg.norm(qpos[adr:adr + 4])
            q[idx:idx + 4] = (x, y, z, w)
        else:
            # MuJoCo places the body as modelled at qpos0 (the joint's ref).
            q[idx] = qpos[adr] - m.qpos0[adr]
    return q


def passive_jacobians(ref: Reference, qpos, qvel, h=1e-4):
    """∂qfrc_passive/∂(δq, θ̇) by central differences of mj_forward."""
    passive = lambda d: d.qfrc_passive  # noqa: E731
    torque = np.zeros(ref.nv)
    return tuple(tangent_jacobian(ref, qpos, qvel, torque, passive, which, h) for which in (0, 1))


def relative(a, b):
    return np.abs(a - b).max() / max(1.0, np.abs(b).max())


@pytest.mark.parametrize("vehicle", COVERED, ids=[p.stem for p in COVERED])
def test_qacc_derivatives_agree_with_pinocchio(nudyn, vehicle):
    ref = Reference.from_file(vehicle)
    m, nv = ref.model, ref.nv
    model, coordinates = pinocchio_model(m)
    data = model.createData()
    assert model.nv == nv
    rng = np.random.default_rng(zlib.crc32(vehicle.stem.encode()) + 7)
    worst = {"dq": 0.0, "qvel": 0.0, "T": 0.0}
    for _ in range(STATES):
        qpos, qvel, torque = ref.random_state(rng)
        proc = subprocess.run(
            [str(nudyn), "linearize", str(vehicle), "--inputs", "torque",
             "--qpos", ",".join(map(repr, map(float, qpos))), "--qvel", ",".join(map(repr, map(float, qvel))),
             "--torque", ",".join(map(repr, map(float, torque)))],
            capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, proc.stderr
        out = json.loads(proc.stdout)
        a, b = np.array(out["A"]), np.array(out["B"])

        d = ref.forward(qpos, qvel, torque)
        tau = torque + d.qfrc_passive
        q = pinocchio_q(m, model, coordinates, qpos)
        pin.computeABADerivatives(model, data, q, qvel, tau)
        minv = np.triu(data.Minv) + np.triu(data.Minv, 1).T
        # Pinocchio's θ̈ first: the two models must be the same vehicle.
        assert relative(pin.aba(model, data, q, qvel, tau), d.qacc) < TOLERANCE
        by_q, by_v = passive_jacobians(ref, qpos, qvel)
        theirs = {"dq": data.ddq_dq + minv @ by_q, "qvel": data.ddq_dv + minv @ by_v, "T": minv}
        ours = {"dq": a[nv:, :nv], "qvel": a[nv:, nv:], "T": b[nv:]}
        for what in worst:
            worst[what] = max(worst[what], relative(ours[what], theirs[what]))
    print(f"{vehicle.stem}: ∂qacc/∂dq {worst['dq']:.1e}, ∂qacc/∂qvel {worst['qvel']:.1e}, "
          f"∂qacc/∂T {worst['T']:.1e} from Pinocchio at {STATES} states")
    for what, error in worst.items():
        assert error < TOLERANCE, f"∂qacc/∂{what}: {error:.2e} from Pinocchio's computeABADerivatives"
