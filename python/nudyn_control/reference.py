"""The control law and its Lyapunov function computed from MuJoCo alone.

For the law eps = -c1 nu + l(theta) J^T c2 (Yhat - Y(theta)) the
configuration term is l(theta) T with T = -dU/dtheta, U = 1/2 sum c2 (Yhat - Y)^2
(the generalized force of the potential, in qvel coordinates). Here U comes
from MuJoCo's kinematics (joint values, or the body's xpos and xquat), T from
4th-order central differences of U along mj_integratePos, and l = m^-1 from
MuJoCo's dense mass matrix: no code is shared with nudyn's O(N) passes or its
SO(3) Jacobian.

The orientation error is phi = log(Rhat^T R), MuJoCo's mju_subQuat(q, qhat)
(qhat * exp(phi) = q), the error Yhat - Y = -phi."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from nudyn_validation.mujoco_reference import Reference

# Step of the central differences of U (rad or m): U is smooth, so the
# 4th-order stencil's truncation error ~1e-16 and its rounding ~1e-12 U.
GRADIENT_STEP = 1e-4


@dataclass
class LawParameters:
    c1: np.ndarray
    c2: np.ndarray
    target: np.ndarray  # joint values, or position (3) then quaternion w, x, y, z (4)


class ReferenceLaw:
    """The law for one MJCF file: joint targets (every hinge and slide), or
    the pose of `body`."""

    def __init__(self, mjcf: Path, body: str | None, parameters: LawParameters):
        self.reference = Reference.from_file(mjcf)
        self.model = self.reference.model
        self.data = mujoco.MjData(self.model)
        self.parameters = parameters
        if body is None:
            kinds = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
            joints = [j for j in range(self.model.njnt) if int(self.model.jnt_type[j]) in kinds]
            self.qpos_indices = np.array([self.model.jnt_qposadr[j] for j in joints], dtype=int)
            self.body = None
        else:
            self.body = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, body)
            if self.body < 0:
                raise ValueError(f"no body named {body!r} in {mjcf}")

    @property
    def nv(self) -> int:
        return self.model.nv

    def pose(self, qpos) -> tuple[np.ndarray, np.ndarray]:
        """Position and quaternion (w, x, y, z) of the body at qpos."""
        self.data.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, self.data)
        return self.data.xpos[self.body].copy(), self.data.xquat[self.body].copy()

    def error(self, qpos) -> np.ndarray:
        """Yhat - Y(qpos)."""
        target = self.parameters.target
        if self.body is None:
            return target - np.asarray(qpos)[self.qpos_indices]
        position, quaternion = self.pose(qpos)
        phi = np.zeros(3)
        unit_target = target[3:] / np.linalg.norm(target[3:])
        mujoco.mju_subQuat(phi, quaternion, unit_target)
        return np.concatenate([target[:3] - position, -phi])

    def potential(self, qpos) -> float:
        e = self.error(qpos)
        return 0.5 * float(np.sum(self.parameters.c2 * e * e))

    def generalized_force(self, qpos) -> np.ndarray:
        """T = -dU/dtheta (qvel coordinates), by central differences."""
        qpos = np.asarray(qpos, float)
        force = np.zeros(self.nv)
        if not np.any(self.parameters.c2):
            return force
        moved = np.empty_like(qpos)
        direction = np.zeros(self.nv)

        def potential_at(s: float) -> float:
            moved[:] = qpos
            mujoco.mj_integratePos(self.model, moved, direction, s)
            return self.potential(moved)

        h = GRADIENT_STEP
        for k in range(self.nv):
            direction[:] = 0.0
            direction[k] = 1.0
            slope = (8 * (potential_at(h) - potential_at(-h)) - (potential_at(2 * h) - potential_at(-2 * h))) / (12 * h)
            force[k] = -slope
        return force

    def configuration_eps(self, qpos) -> np.ndarray:
        """l(theta) T: the configuration term of the law."""
        return self.reference.eps(qpos, self.generalized_force(qpos))

    def eps(self, qpos, nu) -> np.ndarray:
        """The whole law at (theta, nu)."""
        return -self.parameters.c1 * np.asarray(nu) + self.configuration_eps(qpos)

    def lyapunov(self, qpos, nu) -> float:
        """V = K + U, K = 1/2 |nu|^2."""
        return 0.5 * float(np.dot(nu, nu)) + self.potential(qpos)
