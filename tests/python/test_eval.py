"""`nudyn eval` against MuJoCo (the reference in nudyn_validation.mujoco_reference).

For every example vehicle, N_STATES random states (fixed seed per file):
random unit quaternions, joint angles, velocities and torques of realistic
size.  Each state is sent to one `nudyn eval` call per example (an array of
requests), and every quantity is compared with MuJoCo's.

Tolerances are relative to max(1, |reference|_inf) unless said otherwise.
"""

from __future__ import annotations

import json
import zlib

import numpy as np
import pytest

from conftest import EXAMPLES, IMPORTER_FIXTURES, example_ids, run_eval
from nudyn_validation.mujoco_reference import Reference, rel_err

N_STATES = 4
KEYS = ["theta", "qvel", "nu", "nu_dot", "coriolis", "eps", "kinetic_energy", "momentum"]


class Case:
    """One random state and everything MuJoCo says about it."""

    def __init__(self, ref: Reference, rng: np.random.Generator):
        self.qpos, self.qvel, self.torque = ref.random_state(rng)
        self.eps_in = rng.normal(0.0, 1.0, ref.nv)  # an extra eps input
        self.nu = ref.nu(self.qpos, self.qvel)
        self.eps_torque = ref.eps(self.qpos, self.torque)
        self.nu_dot_torque = ref.nu_dot(self.qpos, self.qvel, self.torque)
        self.nu_dot_free = ref.nu_dot(self.qpos, self.qvel)
        # eps_in is the same as a torque m eps_in
        both = self.torque + ref.torque_from_eps(self.qpos, self.eps_in)
        self.nu_dot_both = ref.nu_dot(self.qpos, self.qvel, both)
        self.coriolis = ref.coriolis(self.qpos, self.qvel)
        self.kinetic_energy = ref.kinetic_energy(self.qpos, self.qvel)
        self.momentum = ref.momentum(self.qpos, self.qvel)

    def requests(self):
        """The four requests sent for this state, in this order."""
        q, v = self.qpos.tolist(), self.qvel.tolist()
        return [
            {"theta": q, "qvel": v, "torque": self.torque.tolist()},  # 0
            {"theta": q, "nu": self.nu.tolist()},  # 1
            {"theta": q, "qvel": v, "eps": self.eps_in.tolist(), "torque": self.torque.tolist()},  # 2
            {"theta": q, "qvel": v},  # 3
        ]


class ExampleRun:
    def __init__(self, path, nudyn):
        self.path = path
        self.ref = Reference.from_file(path)
        rng = np.random.default_rng(zlib.crc32(path.stem.encode()))
        self.cases = [Case(self.ref, rng) for _ in range(N_STATES)]
        requests = [r for c in self.cases for r in c.requests()]
        self.result = run_eval(nudyn, path, json.dumps(requests))
        out = self.result.json()
        assert isinstance(out, list) and len(out) == len(requests), (
            f"expected an array of {len(requests)} results\n{self.result.describe()}"
        )
        for o in out:
            missing = [k for k in KEYS if k not in o]
            assert not missing, f"output lacks {missing}: {o}"
        self.outputs = [out[4 * i : 4 * i + 4] for i in range(N_STATES)]

    def each(self):
        """(index, Case, its four outputs as numpy arrays)."""
        for i, (case, outs) in enumerate(zip(self.cases, self.outputs)):
            yield i, case, [{k: np.asarray(o[k], float) for k in KEYS} for o in outs]


@pytest.fixture(scope="module", params=EXAMPLES + IMPORTER_FIXTURES, ids=example_ids() + [f"fixture-{p.stem}" for p in IMPORTER_FIXTURES])
def run(request, nudyn):
    return ExampleRun(request.param, nudyn)


def check(what, run, i, err, tol):
    assert err <= tol, f"{run.path.stem} state {i}: {what} off by {err:.3e} (tolerance {tol:g})"


def test_shapes_and_echo(run):
    nq, nv = run.ref.nq, run.ref.nv
    for i, case, outs in run.each():
        for o in outs:
            assert o["theta"].shape == (nq,) and o["momentum"].shape == (6,)
            for k in ("qvel", "nu", "nu_dot", "coriolis", "eps"):
                assert o[k].shape == (nv,), f"{k} has shape {o[k].shape}, expected ({nv},)"
            assert o["kinetic_energy"].shape == ()
            check("theta echo", run, i, rel_err(o["theta"], case.qpos), 1e-12)
        check("qvel echo", run, i, rel_err(outs[0]["qvel"], case.qvel), 1e-12)


def test_nu_from_qvel(run):
    for i, case, outs in run.each():
        for k in (0, 2, 3):
            check("nu (given qvel)", run, i, rel_err(outs[k]["nu"], case.nu), 1e-10)


def test_qvel_from_nu_round_trip(run):
    for i, case, outs in run.each():
        check("qvel (given nu)", run, i, rel_err(outs[1]["qvel"], case.qvel), 1e-10)
        check("nu echo", run, i, rel_err(outs[1]["nu"], case.nu), 1e-12)


def test_eps_of_torque(run):
    for i, case, outs in run.each():
        check("eps = l T", run, i, rel_err(outs[0]["eps"], case.eps_torque), 1e-10)
        check("eps = eps_in + l T", run, i, rel_err(outs[2]["eps"], case.eps_in + case.eps_torque), 1e-10)
        check("eps default 0", run, i, rel_err(outs[1]["eps"], 0.0 * case.nu), 1e-10)
        check("eps default 0", run, i, rel_err(outs[3]["eps"], 0.0 * case.nu), 1e-10)


def test_nu_dot(run):
    for i, case, outs in run.each():
        check("nu_dot under torque", run, i, rel_err(outs[0]["nu_dot"], case.nu_dot_torque), 1e-6)
        check("nu_dot (given nu, no torque)", run, i, rel_err(outs[1]["nu_dot"], case.nu_dot_free), 1e-6)
        check("nu_dot under eps + torque", run, i, rel_err(outs[2]["nu_dot"], case.nu_dot_both), 1e-6)
        check("nu_dot (no torque)", run, i, rel_err(outs[3]["nu_dot"], case.nu_dot_free), 1e-6)


def test_kinetic_energy(run):
    for i, case, outs in run.each():
        for o in outs:
            k = float(o["kinetic_energy"])
            scale = max(1.0, case.kinetic_energy)
            check("kinetic energy vs 1/2 qvel'M qvel", run, i, abs(k - case.kinetic_energy) / scale, 1e-10)
            check("kinetic energy vs 1/2|nu|^2", run, i, abs(k - 0.5 * o["nu"] @ o["nu"]) / scale, 1e-10)


def test_momentum(run):
    for i, case, outs in run.each():
        for o in outs:
            check("momentum", run, i, rel_err(o["momentum"], case.momentum), 1e-10)


def test_coriolis_is_workless(run):
    for i, case, outs in run.each():
        for o in outs:
            nu, c = o["nu"], o["coriolis"]
            # C is quadratic in nu; where it vanishes (a sphere tumbling freely)
            # round-off alone would fail a bound of |nu||C|.
            bound = np.linalg.norm(nu) * max(np.linalg.norm(c), nu @ nu)
            check("nu.C / (|nu| max(|C|, |nu|^2))", run, i, abs(nu @ c) / max(bound, 1e-300), 1e-9)


def test_coriolis_matches_mujoco(run):
    """C(theta, nu) = -nu_dot with gravity, springs, dampers and torques off."""
    for i, case, outs in run.each():
        for o in outs:
            check("coriolis", run, i, rel_err(o["coriolis"], case.coriolis), 1e-6)


def test_single_object_in_single_object_out(nudyn):
    path = EXAMPLES[0]
    ref = Reference.from_file(path)
    qpos, qvel, torque = ref.random_state(np.random.default_rng(3))
    req = {"theta": qpos.tolist(), "qvel": qvel.tolist(), "torque": torque.tolist()}
    single = run_eval(nudyn, path, json.dumps(req)).json()
    assert isinstance(single, dict), f"a single object in should give a single object out: {single!r}"
    batch = run_eval(nudyn, path, json.dumps([req])).json()
    assert isinstance(batch, list) and len(batch) == 1
    for k in KEYS:
        assert np.allclose(single[k], batch[0][k], rtol=0, atol=0), k
    assert rel_err(single["nu"], ref.nu(qpos, qvel)) <= 1e-10


@pytest.mark.parametrize("scale", [2.0**-530, 2.0**-1000, 2.0**520, 2.0**1000], ids=lambda s: f"{s:.0e}")
def test_quaternions_at_the_edges_of_floating_point(nudyn, scale):
    """A free base's quaternion scaled to near the underflow or overflow of
    its squares is the same rotation (powers of two scale exactly): θ comes
    back at unit length and the motion is the unit quaternion's, to rounding."""
    path = EXAMPLES[0]
    ref = Reference.from_file(path)
    qpos, qvel, _ = ref.random_state(np.random.default_rng(5))
    scaled = qpos.copy()
    scaled[3:7] *= scale
    unit, edge = (run_eval(nudyn, path, json.dumps({"theta": q.tolist(), "qvel": qvel.tolist()})).json()
                  for q in (qpos, scaled))
    assert abs(np.linalg.norm(edge["theta"][3:7]) - 1.0) <= 4e-16
    for key in ("theta", "nu", "nu_dot", "momentum"):
        assert rel_err(edge[key], unit[key]) <= 1e-14, key
