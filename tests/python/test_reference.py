"""Checks of the MuJoCo reference itself (mujoco_reference.py), so that the
numbers nudyn is compared against cannot be silently wrong.  No nudyn here."""

from __future__ import annotations

import zlib

import mujoco
import numpy as np
import pytest

from conftest import EXAMPLES, example_ids
from nudyn_validation.mujoco_reference import MujocoFactor, Reference, ldl_reverse, rel_err, upper_factor

N_STATES = 3


def states(path):
    """(Reference, list of (qpos, qvel, torque)) for a fixed per-file seed."""
    ref = Reference.from_file(path)
    rng = np.random.default_rng(zlib.crc32(path.stem.encode()) + 7)
    return ref, [ref.random_state(rng) for _ in range(N_STATES)]


@pytest.fixture(scope="module", params=EXAMPLES, ids=example_ids())
def example(request):
    return states(request.param)


def test_examples_present():
    names = {p.stem for p in EXAMPLES}
    assert {"bus_arm7", "flexible_boom", "fixed_rig", "chain60"} <= names


def test_upper_factor_small_known_case():
    # M = m m^T for a hand-made upper-triangular m with positive diagonal.
    m = np.array([[2.0, 0.5, -1.0], [0.0, 1.5, 0.25], [0.0, 0.0, 0.75]])
    assert np.allclose(upper_factor(m @ m.T), m, rtol=0, atol=1e-14)
    L, d = ldl_reverse(m @ m.T)
    assert np.allclose(np.diag(L), 1.0) and np.allclose(np.triu(L, 1), 0.0)
    assert np.allclose(L.T @ np.diag(d) @ L, m @ m.T, atol=1e-14)


def test_factor(example):
    ref, cases = example
    for qpos, _, torque in cases:
        M = ref.mass_matrix(qpos)
        m = upper_factor(M)
        scale = np.max(np.abs(M))
        assert np.max(np.abs(m @ m.T - M)) <= 1e-13 * scale
        assert np.all(np.tril(m, -1) == 0.0), "m must be upper triangular"
        assert np.all(np.diag(m) > 0.0), "m must have a positive diagonal"
        mstar = ref.m_star(qpos)  # diag(sqrt d) L: lower triangular
        assert np.all(np.triu(mstar, 1) == 0.0) and np.all(np.diag(mstar) > 0.0)
        L, d = ldl_reverse(M)
        assert np.allclose(np.diag(L), 1.0, rtol=0, atol=1e-15)
        assert np.allclose(mstar, np.diag(np.sqrt(d)) @ L, rtol=0, atol=1e-12 * scale)
        # MuJoCo's own sparse factor M = L^T D L (computed in mj_fwdPosition):
        # the same d, and the same solve M^-1 T = m^-T m^-1 T.
        assert np.max(np.abs(d * ref.data.qLDiagInv - 1.0)) <= 1e-10
        x = np.zeros(ref.nv)
        mujoco.mj_solveM(ref.model, ref.data, x.reshape(1, -1), torque.reshape(1, -1))
        ours = np.linalg.solve(m.T, ref.eps(qpos, torque))
        assert rel_err(ours, x) <= 1e-10


def test_mujoco_factor_read_from_qLD(example):
    """MujocoFactor's L and d (MuJoCo's sparse qLD) are the dense reverse
    factor of mj_fullM's M, and its nu and m eps are the dense products."""
    ref, cases = example
    factor = MujocoFactor(ref.model)
    rng = np.random.default_rng(3)
    for qpos, qvel, _ in cases:
        M = ref.mass_matrix(qpos)  # leaves ref.data factored at qpos
        L, d = ldl_reverse(M)
        scale = np.max(np.abs(M))
        assert np.max(np.abs(factor.lower(ref.data) - L)) <= 1e-10 * scale
        assert rel_err(factor.sqrt_d(ref.data) ** 2, d) <= 1e-12
        assert rel_err(factor.nu(ref.data, qvel), ref.nu(qpos, qvel)) <= 1e-12
        eps = rng.normal(size=ref.nv)
        assert rel_err(factor.torque(ref.data, eps), ref.torque_from_eps(qpos, eps)) <= 1e-12


def test_nu_energy_and_round_trip(example):
    ref, cases = example
    model = ref.model
    saved = model.opt.enableflags
    model.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_ENERGY)
    try:
        for qpos, qvel, _ in cases:
            nu = ref.nu(qpos, qvel)
            k = ref.kinetic_energy(qpos, qvel)
            d = ref.forward(qpos, qvel)  # energy[1] = MuJoCo's kinetic energy
            assert abs(0.5 * nu @ nu - k) <= 1e-12 * max(1.0, k)
            assert abs(d.energy[1] - k) <= 1e-12 * max(1.0, k)
            assert rel_err(ref.qvel_from_nu(qpos, nu), qvel) <= 1e-12
    finally:
        model.opt.enableflags = saved


def test_eps_power(example):
    """nu . eps(T) = qvel . T: eps is the force dual to nu."""
    ref, cases = example
    for qpos, qvel, torque in cases:
        power = ref.nu(qpos, qvel) @ ref.eps(qpos, torque)
        assert abs(power - qvel @ torque) <= 1e-11 * max(1.0, np.abs(qvel) @ np.abs(torque))
        assert rel_err(ref.torque_from_eps(qpos, ref.eps(qpos, torque)), torque) <= 1e-12


def nu_dot_along_rk4(ref: Reference, qpos, qvel, torque, dt=1e-4):
    """(qpos, qvel) at the centre of a 7-point RK4 trajectory under torque,
    and nu_dot there by a 6th-order central difference of nu_ref(t)."""
    model = ref.model
    saved = (model.opt.integrator, model.opt.timestep)
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    model.opt.timestep = dt
    d = mujoco.MjData(model)
    try:
        d.qpos[:] = qpos
        d.qvel[:] = qvel
        d.qfrc_applied[:] = torque
        traj = []
        for _ in range(7):
            traj.append((d.qpos.copy(), d.qvel.copy()))
            mujoco.mj_step(model, d)
    finally:
        model.opt.integrator, model.opt.timestep = saved
    f = [ref.nu(q, v) for q, v in traj]
    fd = (f[6] - 9 * f[5] + 45 * f[4] - 45 * f[2] + 9 * f[1] - f[0]) / (60 * dt)
    return traj[3], fd


def test_nu_dot_matches_trajectory(example):
    """nu_dot_ref = m* qacc + (d/dt m*) qvel equals the time derivative of
    nu_ref along MuJoCo's own (RK4, dt = 1e-4) motion, and agrees with the
    second route to d/dt m* through dM/dt."""
    ref, cases = example
    for qpos, qvel, torque in cases:
        (q, v), fd = nu_dot_along_rk4(ref, qpos, qvel, torque)
        nudot = ref.nu_dot(q, v, torque)
        assert rel_err(nudot, fd) <= 1e-9, (rel_err(nudot, fd), nudot, fd)
        alt = ref.m_star(q) @ ref.qacc(q, v, torque) + ref.m_star_dot_via_mdot(q, v) @ v
        assert rel_err(nudot, alt) <= 1e-10


def test_coriolis_is_workless(example):
    ref, cases = example
    for qpos, qvel, _ in cases:
        nu = ref.nu(qpos, qvel)
        c = ref.coriolis(qpos, qvel)
        assert abs(nu @ c) <= 1e-9 * np.linalg.norm(nu) * np.linalg.norm(c)


def test_momentum_two_routes(example):
    ref, cases = example
    for qpos, qvel, _ in cases:
        h = ref.momentum(qpos, qvel)
        assert rel_err(h, ref.momentum_via_subtree(qpos, qvel)) <= 1e-12


def free_flyers():
    """The examples that float in space: free root joint, zero gravity."""
    out = []
    for path in EXAMPLES:
        m = mujoco.MjModel.from_xml_path(str(path))
        if not np.any(m.opt.gravity) and m.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE:
            out.append(path)
    return out


def test_free_flyers_found():
    names = {p.stem for p in free_flyers()}
    assert {"bus_arm7", "flexible_boom", "chain60"} <= names
    assert "fixed_rig" not in names


@pytest.mark.parametrize("path", free_flyers(), ids=lambda p: p.stem)
def test_momentum_conserved(path):
    """With no gravity and no applied force, the bodies' momentum about the
    world origin is constant along MuJoCo's motion (internal springs,
    dampers and joint armature do not change it); RK4, dt = 2.5e-4, 0.1 s."""
    ref, cases = states(path)
    model = ref.model
    qpos, qvel, _ = cases[0]
    h0 = ref.momentum(qpos, qvel)
    saved = (model.opt.integrator, model.opt.timestep)
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    model.opt.timestep = 2.5e-4
    d = mujoco.MjData(model)
    try:
        d.qpos[:] = qpos
        d.qvel[:] = qvel
        for _ in range(400):
            mujoco.mj_step(model, d)
        q1, v1 = d.qpos.copy(), d.qvel.copy()
    finally:
        model.opt.integrator, model.opt.timestep = saved
    assert rel_err(ref.momentum(q1, v1), h0) <= 1e-10
    assert rel_err(qvel, v1) > 1e-6, "the vehicle should have moved"
