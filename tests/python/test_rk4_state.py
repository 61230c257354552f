"""nudyn's RK4 is the Runge–Kutta–Munthe-Kaas step applied to (θ, θ̇),
MuJoCo's (qpos, qvel): the same step on the same state, so the two agree
to round-off, and nudyn's ν at the end is m*(θ) θ̇ of MuJoCo's result.
The integrator advanced the paper's (θ, ν) until the session of
2026-11-25; on a free-flying bus carrying an arm that state's error
constant is about 60× larger at equal steps (docs/integration.md, "The
integrated state").

The test is independent of nudyn's code: MuJoCo's RK4, and an RKMK on
(qpos, qvel) written here with MuJoCo's qacc as the vector field, which
reproduces it. As a control, an RKMK on (qpos, ν) written the same way
(θ̇ = m*⁻¹ν, ν̇ = m* q̈ + ṁ* θ̇ with m from MuJoCo's dense M and ṁ* by a
central difference along the motion) gives a different 4th-order
solution, so the agreement could not hold by accident."""

from __future__ import annotations

import json

import mujoco
import numpy as np

from conftest import EXAMPLES_DIR
from nudyn_driver.cli import Nudyn
from nudyn_validation.mujoco_reference import upper_factor

MODEL = EXAMPLES_DIR / "bus_arm7.xml"
STEP = 0.05
STEPS = 10
QVEL0 = np.array([0.01, 0.02, -0.01, 0.1, -0.05, 0.08, 0.2, -0.3, 0.25, 0.1, -0.2, 0.3, 0.15])
RK4_A = [[], [0.5], [0.0, 0.5], [0.0, 0.0, 1.0]]
RK4_B = [1 / 6, 1 / 3, 1 / 3, 1 / 6]


class Mujoco:
    def __init__(self):
        self.m = mujoco.MjModel.from_xml_path(str(MODEL))
        self.m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
        self.d = mujoco.MjData(self.m)
        # Body-frame rotation rates: a ball's 3 dofs, a free joint's last 3.
        self.rotations = []
        for j in range(self.m.njnt):
            dof = self.m.jnt_dofadr[j]
            if self.m.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL:
                self.rotations.append(dof)
            elif self.m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
                self.rotations.append(dof + 3)

    def qpos0(self):
        return self.m.qpos0.copy()

    def qacc(self, qpos, qvel):
        self.d.qpos[:] = qpos
        self.d.qvel[:] = qvel
        mujoco.mj_forward(self.m, self.d)
        return self.d.qacc.copy()

    def upper_factor(self, qpos):
        """m: M = m mᵀ, m upper triangular with a positive diagonal."""
        self.d.qpos[:] = qpos
        mujoco.mj_forward(self.m, self.d)
        mass = np.zeros((self.m.nv, self.m.nv))
        mujoco.mj_fullM(self.m, self.d, mass)
        return upper_factor(mass)

    def retract(self, qpos, delta):
        moved = qpos.copy()
        mujoco.mj_integratePos(self.m, moved, delta, 1.0)
        return moved

    def rk4(self, qvel0):
        self.m.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
        self.m.opt.timestep = STEP
        mujoco.mj_resetData(self.m, self.d)
        self.d.qvel[:] = qvel0
        for _ in range(STEPS):
            mujoco.mj_step(self.m, self.d)
        return self.d.qpos.copy(), self.d.qvel.copy()


def dexp_inv(rotation, omega):
    """Rate of the body-frame rotation vector Θ of q = qₙ·exp(Θ)."""
    angle2 = rotation @ rotation
    c = 1 / 12 + angle2 / 720 if angle2 < 1e-6 else (1 - 0.5 * np.sqrt(angle2) / np.tan(0.5 * np.sqrt(angle2))) / angle2
    cross = np.cross(rotation, omega)
    return omega + 0.5 * cross + c * np.cross(rotation, cross)


def rkmk(mj, qpos, velocity, rates):
    """STEPS RK4 steps of (qpos, velocity); rates(qpos, velocity) -> (qvel, velocity rate)."""
    for _ in range(STEPS):
        k_delta, k_velocity = [], []
        for row in RK4_A:
            delta = sum((STEP * a * k for a, k in zip(row, k_delta)), np.zeros(mj.m.nv))
            stage_velocity = velocity + sum((STEP * a * k for a, k in zip(row, k_velocity)), np.zeros(mj.m.nv))
            qvel, velocity_rate = rates(mj.retract(qpos, delta), stage_velocity)
            for dof in mj.rotations:
                qvel[dof : dof + 3] = dexp_inv(delta[dof : dof + 3], qvel[dof : dof + 3])
            k_delta.append(qvel)
            k_velocity.append(velocity_rate)
        qpos = mj.retract(qpos, sum(STEP * b * k for b, k in zip(RK4_B, k_delta)))
        velocity = velocity + sum(STEP * b * k for b, k in zip(RK4_B, k_velocity))
    return qpos, velocity


def nu_rates(mj, qpos, nu):
    factor = mj.upper_factor(qpos)
    qvel = np.linalg.solve(factor.T, nu)
    shift = 1e-5
    factor_rate = (mj.upper_factor(mj.retract(qpos, shift * qvel)) - mj.upper_factor(mj.retract(qpos, -shift * qvel))) / (2 * shift)
    return qvel.copy(), factor.T @ mj.qacc(qpos, qvel) + factor_rate.T @ qvel


def nudyn_rk4(nudyn, nu0):
    stop = STEP * STEPS
    stdout = Nudyn(nudyn).run("simulate", MODEL, "--step", str(stop), "--stop", str(stop), "--method", "rk4",
                              "--max-step", str(STEP), stdin=json.dumps({"nu": list(nu0)}))
    out = json.loads(stdout)
    return np.array(out["theta"][-1]), np.array(out["nu"][-1])


def test_nudyn_rk4_is_mujoco_rk4_on_qpos_qvel(nudyn):
    mj = Mujoco()
    qpos0 = mj.qpos0()
    nu0 = mj.upper_factor(qpos0).T @ QVEL0

    mujoco_qpos, mujoco_qvel = mj.rk4(QVEL0)
    qvel_qpos, qvel_qvel = rkmk(mj, qpos0, QVEL0, lambda q, v: (v.copy(), mj.qacc(q, v)))
    assert np.abs(mujoco_qpos - qvel_qpos).max() < 1e-12
    assert np.abs(mujoco_qvel - qvel_qvel).max() < 1e-12

    nudyn_qpos, nudyn_nu = nudyn_rk4(nudyn, nu0)
    assert np.abs(nudyn_qpos - mujoco_qpos).max() < 1e-12
    mujoco_nu = mj.upper_factor(mujoco_qpos).T @ mujoco_qvel
    assert np.abs(nudyn_nu - mujoco_nu).max() < 1e-12 * np.abs(nu0).max()

    # The control: the same step on (qpos, ν) is another 4th-order solution.
    nu_qpos, _ = rkmk(mj, qpos0, nu0, lambda q, nu: nu_rates(mj, q, nu))
    assert np.abs(nu_qpos - mujoco_qpos).max() > 1e-6
