"""Reference values of nudyn's quantities computed from MuJoCo alone.

Nothing here uses nudyn: these are the independent numbers the tests compare
`nudyn eval` against (docs/DYNAMICS.md §3 and §7).

Conventions (docs/DYNAMICS.md §2, MuJoCo's own):
  theta = qpos (nq), qvel (nv) in MuJoCo's order and meaning.
  M(theta) = m m*  with m upper triangular, positive diagonal (parent-first),
  equivalently MuJoCo's reverse factor M = L^T diag(d) L (L unit lower
  triangular), m = L^T diag(sqrt d):
      nu       = m^T qvel            = diag(sqrt d) L qvel
      eps(T)   = m^-1 T              = diag(sqrt d)^-1 L^-T T
      nu_dot   = m^T(theta) qacc + (d/dt m^T(theta(t))) qvel
      C        = -nu_dot  with gravity, springs, dampers, torques and
                 constraints all off.
  Kinetic energy = 1/2 qvel^T M qvel (M includes joint armature).
  M, m and K are the tree's: tendon armature, which MuJoCo adds to its M
  and energy, is left out as nudyn leaves it out (docs/DYNAMICS.md §9);
  qacc is MuJoCo's, with it.
  Momentum: 6-vector [angular; linear] of all bodies, world axes, angular
  part about the world origin.  Armature (reflected rotor inertia) is not a
  body and carries no momentum here.

Every function that takes (model, ...) works on a `Reference` wrapper that
owns an MjModel with contacts and actuators disabled and a scratch MjData.
The constraints nudyn models (joint friction loss and limits) stay on, their
problem solved to round-off (see load_model).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import mujoco
import numpy as np

# Step used for the central differences of m*(theta) along the motion, as a
# displacement in configuration space (rad, or m): h is scaled so that
# h * |qvel|_inf equals this.  With the 6th-order stencil the truncation error
# is ~ FD_STEP^6 and the rounding error ~ 1e-16 cond / FD_STEP; 1e-3 keeps
# (d/dt m*) qvel within ~1e-11 of |nu_dot| on the examples, where a
# 4th-order stencil at 2e-3 was off by 2e-9 on bus_arm7 (the factor of M is
# far less smooth than M).  test_reference.py checks nu_dot against a
# finite difference of nu along an RK4 trajectory and against a second route.
FD_STEP = 1e-3


def central_diff(f, h: float):
    """f'(0) by the 6th-order central difference with step h."""
    return (
        f(3 * h) - 9 * f(2 * h) + 45 * f(h) - 45 * f(-h) + 9 * f(-2 * h) - f(-3 * h)
    ) / (60 * h)


# MuJoCo's constraint solver stops at a relative cost improvement of
# opt.tolerance (1e-8 by default), so its forces are that far from the
# optimum nudyn solves for exactly; the reference asks for round-off.
SOLVER_TOLERANCE = 1e-15
SOLVER_ITERATIONS = 1000
# MuJoCo's solref where none is given (time constant, damping ratio).
DEFAULT_SOLREF = (0.02, 1.0)


def load_model(path: str | Path) -> mujoco.MjModel:
    """Load an MJCF file with contacts disabled (nudyn models none) and the
    constraint solver run to round-off."""
    model = mujoco.MjModel.from_xml_path(str(path))
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    model.opt.tolerance = SOLVER_TOLERANCE
    model.opt.ls_tolerance = SOLVER_TOLERANCE
    model.opt.iterations = max(model.opt.iterations, SOLVER_ITERATIONS)
    # A file may cap the line search too (Menagerie's MJX files: 8), which
    # left MuJoCo's forces 3 % from the optimum on unitree_g1/g1_mjx.xml.
    model.opt.ls_iterations = max(model.opt.ls_iterations, SOLVER_ITERATIONS)
    return model


def set_timestep(model: mujoco.MjModel, step: float) -> None:
    """Give `model` another time step without moving its constraints'
    reference: with refsafe on, MuJoCo floors every positive time constant
    at twice the *current* timestep, and the FMU keeps the file's floor.
    The floor of the file's timestep is applied to the solrefs here (a
    mixed-sign solref first replaced by MuJoCo's default, as MuJoCo does)
    and MuJoCo's own refsafe turned off, so that the step changes nothing
    but the integration. filterexact activations become filter, the same
    ODE: MuJoCo's RK4 takes τ(1 − e^(−h/τ)) for h in a filterexact's last
    update, which makes it first order there. An `actearly` actuator looks
    ahead by MuJoCo's step, the FMU by the file's: such a vehicle agrees
    only to the file's step."""
    if not model.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_REFSAFE):
        floor = 2 * model.opt.timestep
        for solref in (model.jnt_solref, model.dof_solref, model.eq_solref,
                       model.tendon_solref_lim, model.tendon_solref_fri):
            mixed = (solref[:, 0] > 0) != (solref[:, 1] > 0)
            solref[mixed] = DEFAULT_SOLREF
            timed = solref[:, 0] > 0
            solref[timed, 0] = np.maximum(solref[timed, 0], floor)
        model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_REFSAFE)
    exact = model.actuator_dyntype == int(mujoco.mjtDyn.mjDYN_FILTEREXACT)
    model.actuator_dyntype[exact] = int(mujoco.mjtDyn.mjDYN_FILTER)
    model.opt.timestep = step


def without_tendon_armature(model: mujoco.MjModel) -> mujoco.MjModel | None:
    """A copy of `model` whose M is the tree's (its tendons' armature set to
    0: MuJoCo adds it to M, nudyn's m leaves it out, docs/DYNAMICS.md §9);
    None when no tendon has armature."""
    if not (model.ntendon and model.tendon_armature.any()):
        return None
    tree = copy.deepcopy(model)
    tree.tendon_armature[:] = 0
    return tree


@dataclass
class Reference:
    """MuJoCo model + scratch data, and the reference quantities."""

    model: mujoco.MjModel
    data: mujoco.MjData

    @classmethod
    def from_file(cls, path: str | Path) -> "Reference":
        """The reference of an MJCF file, its actuators off: nudyn's eval
        without ctrl applies no actuator force, while MuJoCo's position and
        velocity actuators pull even at ctrl = 0. (mjDSBL_ACTUATION also
        skips mjcb_control, which the reference does not use.)"""
        model = load_model(path)
        model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_ACTUATION)
        return cls(model, mujoco.MjData(model))

    @property
    def nq(self) -> int:
        return self.model.nq

    @property
    def nv(self) -> int:
        return self.model.nv

    # ------------------------------------------------------------------ #
    # state handling
    # ------------------------------------------------------------------ #
    def forward(self, qpos, qvel=None, torque=None) -> mujoco.MjData:
        """mj_forward at (qpos, qvel) with qfrc_applied = torque."""
        d = self.data
        mujoco.mj_resetData(self.model, d)
        d.qpos[:] = qpos
        d.qvel[:] = 0.0 if qvel is None else qvel
        d.qfrc_applied[:] = 0.0 if torque is None else torque
        mujoco.mj_forward(self.model, d)
        return d

    @cached_property
    def _tree(self) -> tuple[mujoco.MjModel, mujoco.MjData]:
        """The model whose M is the tree's: without tendon armature, which
        MuJoCo adds to its M and nudyn's m leaves out (docs/DYNAMICS.md §9)."""
        tree = without_tendon_armature(self.model)
        return (self.model, self.data) if tree is None else (tree, mujoco.MjData(tree))

    def mass_matrix(self, qpos) -> np.ndarray:
        """Dense M(theta) of the tree (joint armature included) from
        MuJoCo's CRB."""
        model, d = self._tree
        mujoco.mj_resetData(model, d)
        d.qpos[:] = qpos
        mujoco.mj_fwdPosition(model, d)
        M = np.zeros((self.nv, self.nv))
        mujoco.mj_fullM(model, d, M)  # MuJoCo 4: (m, d, dst)
        return M

    # ------------------------------------------------------------------ #
    # the factor
    # ------------------------------------------------------------------ #
    def m_upper(self, qpos) -> np.ndarray:
        """m(theta): upper triangular, positive diagonal, m m^T = M."""
        return upper_factor(self.mass_matrix(qpos))

    def m_star(self, qpos) -> np.ndarray:
        """m*(theta) = m^T = diag(sqrt d) L: lower triangular."""
        return self.m_upper(qpos).T

    def nu(self, qpos, qvel) -> np.ndarray:
        return self.m_star(qpos) @ np.asarray(qvel, float)

    def qvel_from_nu(self, qpos, nu) -> np.ndarray:
        return np.linalg.solve(self.m_star(qpos), np.asarray(nu, float))

    def eps(self, qpos, torque) -> np.ndarray:
        """eps = m^-1 T: the diagonalized generalized force of torques T."""
        return np.linalg.solve(self.m_upper(qpos), np.asarray(torque, float))

    def torque_from_eps(self, qpos, eps) -> np.ndarray:
        return self.m_upper(qpos) @ np.asarray(eps, float)

    # ------------------------------------------------------------------ #
    # time derivative of nu along MuJoCo's motion
    # ------------------------------------------------------------------ #
    def qacc(self, qpos, qvel, torque=None) -> np.ndarray:
        """MuJoCo's forward dynamics (gravity, springs, dampers included)."""
        return self.forward(qpos, qvel, torque).qacc.copy()

    def _fd_step(self, qvel) -> float:
        return FD_STEP / max(1e-12, float(np.max(np.abs(qvel))))

    def m_star_dot(self, qpos, qvel) -> np.ndarray:
        """d/dt m*(theta(t)) where theta moves with velocity qvel.

        6th-order central difference along theta(h) = theta (+) h qvel
        (mj_integratePos, exact on quaternions)."""
        qvel = np.asarray(qvel, float)
        if not np.any(qvel):
            return np.zeros((self.nv, self.nv))
        h = self._fd_step(qvel)

        def at(t):
            q = np.array(qpos, float)
            mujoco.mj_integratePos(self.model, q, qvel, t)
            return self.m_star(q)

        return central_diff(at, h)

    def m_star_dot_via_mdot(self, qpos, qvel) -> np.ndarray:
        """Same as m_star_dot by another route (a cross-check): from
        M = m m^T, m^-1 Mdot m^-T = X + X^T with X = m^-1 mdot upper
        triangular, so mdot = m Phi(m^-1 Mdot m^-T) (Phi: upper triangle,
        diagonal halved); Mdot by central differences of M."""
        qvel = np.asarray(qvel, float)
        h = self._fd_step(qvel)

        def at(t):
            q = np.array(qpos, float)
            mujoco.mj_integratePos(self.model, q, qvel, t)
            return self.mass_matrix(q)

        Mdot = central_diff(at, h)
        m = self.m_upper(qpos)
        minv = np.linalg.inv(m)
        S = minv @ Mdot @ minv.T
        X = np.triu(S) - 0.5 * np.diag(np.diag(S))
        return (m @ X).T

    def nu_dot(self, qpos, qvel, torque=None) -> np.ndarray:
        """nu_dot = m*(theta) qacc + (d/dt m*) qvel under torque T."""
        qacc = self.qacc(qpos, qvel, torque)
        return self.m_star(qpos) @ qacc + self.m_star_dot(qpos, qvel) @ qvel

    def coriolis(self, qpos, qvel) -> np.ndarray:
        """C(theta, nu): -nu_dot with gravity, springs, dampers and constraints disabled."""
        opt = self.model.opt
        saved = opt.disableflags
        opt.disableflags = saved | (
            int(mujoco.mjtDisableBit.mjDSBL_GRAVITY)
            | int(mujoco.mjtDisableBit.mjDSBL_SPRING)
            | int(mujoco.mjtDisableBit.mjDSBL_DAMPER)
            | int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
        )
        try:
            return -self.nu_dot(qpos, qvel)
        finally:
            opt.disableflags = saved

    # ------------------------------------------------------------------ #
    # energy and momentum
    # ------------------------------------------------------------------ #
    def kinetic_energy(self, qpos, qvel) -> float:
        qvel = np.asarray(qvel, float)
        return 0.5 * float(qvel @ self.mass_matrix(qpos) @ qvel)

    def body_velocities(self, qpos, qvel) -> np.ndarray:
        """(nbody, 6): [omega; v_com] of each body, both in WORLD axes,
        v_com the velocity of the body's centre of mass (d.xipos).

        mj_objectVelocity(mjOBJ_BODY, flg_local=0) shifts MuJoCo's cvel
        (which is expressed at the subtree root's centre of mass) to the
        body's inertial frame origin d.xipos and leaves world orientation."""
        d = self.forward(qpos, qvel)
        out = np.zeros((self.model.nbody, 6))
        for b in range(1, self.model.nbody):
            mujoco.mj_objectVelocity(
                self.model, d, int(mujoco.mjtObj.mjOBJ_BODY), b, out[b], 0
            )
        return out

    def momentum(self, qpos, qvel) -> np.ndarray:
        """[angular; linear] momentum of all bodies, world axes, about the
        world origin:  h = sum R I R^T omega + c x (mass v_c),  p = sum mass v_c,
        with R = d.ximat (principal axes), I = diag(m.body_inertia),
        c = d.xipos."""
        vel = self.body_velocities(qpos, qvel)  # leaves d at this state
        d, m = self.data, self.model
        h = np.zeros(3)
        p = np.zeros(3)
        for b in range(1, m.nbody):
            R = d.ximat[b].reshape(3, 3)
            w, v = vel[b, :3], vel[b, 3:]
            pb = m.body_mass[b] * v
            h += R @ (m.body_inertia[b] * (R.T @ w)) + np.cross(d.xipos[b], pb)
            p += pb
        return np.concatenate([h, p])

    def momentum_via_subtree(self, qpos, qvel) -> np.ndarray:
        """The same momentum from MuJoCo's mj_subtreeVel (a cross-check):
        world subtree angular momentum about the total centre of mass, moved
        to the origin."""
        return subtree_momentum(self.model, self.forward(qpos, qvel))

    # ------------------------------------------------------------------ #
    # random states
    # ------------------------------------------------------------------ #
    def random_state(self, rng: np.random.Generator):
        """A random (qpos, qvel, torque) of realistic size for a space robot.

        free: position ~ N(0, 2 m), random unit quaternion, linear velocity
              ~ N(0, 0.2 m/s), angular velocity ~ N(0, 0.05 rad/s); force
              ~ N(0, 20 N), torque ~ N(0, 20 N m);
        ball: random unit quaternion, ~ N(0, 0.3 rad/s), ~ N(0, 10 N m);
        hinge: U(-pi, pi) rad, ~ N(0, 0.3 rad/s), ~ N(0, 10 N m);
        slide: qpos0 + U(-0.2, 0.2) m, ~ N(0, 0.1 m/s), ~ N(0, 20 N)."""
        m = self.model
        qpos = m.qpos0.copy()
        qvel = np.zeros(m.nv)
        tau = np.zeros(m.nv)
        for j in range(m.njnt):
            a, v = m.jnt_qposadr[j], m.jnt_dofadr[j]
            t = m.jnt_type[j]
            if t == mujoco.mjtJoint.mjJNT_FREE:
                qpos[a : a + 3] = rng.normal(0, 2.0, 3)
                qpos[a + 3 : a + 7] = random_quat(rng)
                qvel[v : v + 3] = rng.normal(0, 0.2, 3)
                qvel[v + 3 : v + 6] = rng.normal(0, 0.05, 3)
                tau[v : v + 6] = rng.normal(0, 20.0, 6)
            elif t == mujoco.mjtJoint.mjJNT_BALL:
                qpos[a : a + 4] = random_quat(rng)
                qvel[v : v + 3] = rng.normal(0, 0.3, 3)
                tau[v : v + 3] = rng.normal(0, 10.0, 3)
            elif t == mujoco.mjtJoint.mjJNT_HINGE:
                qpos[a] = rng.uniform(-np.pi, np.pi)
                qvel[v] = rng.normal(0, 0.3)
                tau[v] = rng.normal(0, 10.0)
            else:  # slide
                qpos[a] = m.qpos0[a] + rng.uniform(-0.2, 0.2)
                qvel[v] = rng.normal(0, 0.1)
                tau[v] = rng.normal(0, 20.0)
        return qpos, qvel, tau


def subtree_momentum(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """[angular; linear] momentum of all bodies, world axes, about the world
    origin, from MuJoCo's mj_subtreeVel at the state mj_forward left in data:
    the world subtree's angular momentum about its centre of mass, moved to
    the origin."""
    mujoco.mj_subtreeVel(model, data)
    p = model.body_subtreemass[0] * data.subtree_linvel[0]
    h = data.subtree_angmom[0] + np.cross(data.subtree_com[0], p)
    return np.concatenate([h, p])


class MujocoFactor:
    """MuJoCo's own factor M = L^T diag(d) L, as mj_factorM (called by
    mj_fwdPosition) leaves it in data.qLD, and the products with
    m = L^T diag(sqrt d) that the validation needs at every RK4 stage.

    qLD is stored in the sparse row format of M (model.M_rownnz, M_rowadr,
    M_colind): row i holds L[i, j] for the dofs j < i that M couples to i,
    and d[i] at column i.  The index arrays are built once; each product is
    then two vectorized gathers and a bincount (O(nnz), no dense matrix).

    With tendon armature MuJoCo's M holds the tendons' inertia too, while
    nudyn's ν = m*θ̇ and ε = m⁻¹T are the tree's (docs/DYNAMICS.md §9): the
    factor is then that of the same model without the tendons' armature,
    built by MuJoCo at each state."""

    def __init__(self, model: mujoco.MjModel):
        self.nv = model.nv
        rows = np.repeat(np.arange(model.nv), model.M_rownnz)
        cols = np.asarray(model.M_colind)
        on_diagonal = rows == cols
        self._diag = np.flatnonzero(on_diagonal)
        if not np.array_equal(rows[self._diag], np.arange(model.nv)):
            raise ValueError("qLD does not hold one diagonal entry per dof: MuJoCo's layout changed")
        self._off = np.flatnonzero(~on_diagonal)
        self._off_rows = rows[self._off]
        self._off_cols = cols[self._off]
        tree = without_tendon_armature(model)
        self._tree = None if tree is None else (tree, mujoco.MjData(tree))

    def _tree_at(self, data: mujoco.MjData) -> mujoco.MjData:
        """The model without tendon armature at data's qpos, its M factored."""
        tree, scratch = self._tree
        scratch.qpos[:] = data.qpos
        mujoco.mj_kinematics(tree, scratch)
        mujoco.mj_comPos(tree, scratch)
        mujoco.mj_makeM(tree, scratch)
        mujoco.mj_factorM(tree, scratch)
        return scratch

    def _ld(self, data: mujoco.MjData) -> np.ndarray:
        """qLD of the tree's M at data's qpos."""
        return data.qLD if self._tree is None else self._tree_at(data).qLD

    def kinetic_energy(self, data: mujoco.MjData) -> float:
        """½θ̇ᵀMθ̇ with the tree's M, as nudyn's K = ½|ν|² counts it: MuJoCo's
        own energy[1] (mjENBL_ENERGY), or, with tendon armature, which
        MuJoCo's energy includes, the product by the tree's M."""
        if self._tree is None:
            return float(data.energy[1])
        product = np.zeros(self.nv)
        mujoco.mj_mulM(self._tree[0], self._tree_at(data), product, data.qvel)
        return 0.5 * float(data.qvel @ product)

    def sqrt_d(self, data: mujoco.MjData) -> np.ndarray:
        return np.sqrt(self._ld(data)[self._diag])

    def lower(self, data: mujoco.MjData) -> np.ndarray:
        """Dense L (unit lower triangular), for checks."""
        L = np.eye(self.nv)
        L[self._off_rows, self._off_cols] = self._ld(data)[self._off]
        return L

    def nu(self, data: mujoco.MjData, qvel) -> np.ndarray:
        """nu = m* qvel = diag(sqrt d) L qvel."""
        qvel = np.asarray(qvel, float)
        ld = self._ld(data)
        below = ld[self._off] * qvel[self._off_cols]
        return np.sqrt(ld[self._diag]) * (qvel + np.bincount(self._off_rows, below, self.nv))

    def torque(self, data: mujoco.MjData, eps) -> np.ndarray:
        """T = m eps = L^T diag(sqrt d) eps: the joint torques whose
        diagonalized force is eps."""
        ld = self._ld(data)
        scaled = np.sqrt(ld[self._diag]) * np.asarray(eps, float)
        above = ld[self._off] * scaled[self._off_rows]
        return scaled + np.bincount(self._off_cols, above, self.nv)


def random_quat(rng: np.random.Generator) -> np.ndarray:
    """Uniformly distributed unit quaternion (w, x, y, z), w >= 0."""
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def upper_factor(M: np.ndarray) -> np.ndarray:
    """The unique m, upper triangular with positive diagonal, m m^T = M.

    With J the reversal permutation, J M J = C C^T (ordinary lower Cholesky)
    gives M = (J C J)(J C J)^T and J C J is upper triangular with positive
    diagonal.  In MuJoCo's terms m = L^T diag(sqrt d) for M = L^T diag(d) L."""
    C = np.linalg.cholesky(M[::-1, ::-1])
    return np.ascontiguousarray(C[::-1, ::-1])


def ldl_reverse(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's factor M = L^T diag(d) L: returns (L unit lower, d)."""
    m = upper_factor(M)
    sqrt_d = np.diag(m).copy()
    L = (m / sqrt_d[None, :]).T
    return L, sqrt_d**2


def rel_err(actual, expected) -> float:
    """max |actual - expected| / max(1, |expected|_inf)."""
    a = np.asarray(actual, float)
    e = np.asarray(expected, float)
    return float(np.max(np.abs(a - e), initial=0.0) / max(1.0, np.max(np.abs(e), initial=0.0)))
