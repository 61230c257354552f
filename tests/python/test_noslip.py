"""MuJoCo's no-slip pass on friction-loss rows against mj_forward.

tests/fixtures/constraints/noslip_trees.xml has three kinematic trees with
friction loss on hinge, slide and ball dofs and on a tendon, limits and a
joint coupling that makes two of the trees one island. Copies of it set
noslip_iterations, noslip_tolerance and the island flag; MuJoCo's main
solver runs to round-off (load_model), so the pass starts from the same
forces on both sides.
"""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest

from conftest import ROOT, run_eval
from nudyn_validation.mujoco_reference import load_model

FIXTURE = ROOT / "tests" / "fixtures" / "constraints" / "noslip_trees.xml"
N_STATES = 100
ISLAND = int(mujoco.mjtDisableBit.mjDSBL_ISLAND)

# (noslip_iterations, noslip_tolerance, islands): 1e-2 stops some islands
# after a sweep or two, where MuJoCo's answer depends on the island split.
SETTINGS = [(1, 1e-6, True), (3, 1e-6, True), (50, 1e-10, True), (50, 1e-2, True), (50, 1e-2, False), (3, 1e-1, False)]


def variant(tmp_path, iterations: int, tolerance: float, islands: bool):
    text = FIXTURE.read_text()
    text = text.replace('noslip_iterations="3"', f'noslip_iterations="{iterations}" noslip_tolerance="{tolerance}"')
    text = text.replace('contact="disable"', f'contact="disable" island="{"enable" if islands else "disable"}"')
    path = tmp_path / f"noslip_{iterations}_{tolerance}_{islands}.xml"
    path.write_text(text)
    return path


def random_states(model: mujoco.MjModel, rng: np.random.Generator):
    """Limited joints over their range and 10 % beyond, the others in ±1,
    ball joints up to 0.8 rad against a 35° cone; zero velocity in one state
    out of five."""
    for k in range(N_STATES):
        qpos = model.qpos0.copy()
        for j in range(model.njnt):
            a, kind = model.jnt_qposadr[j], model.jnt_type[j]
            if kind == mujoco.mjtJoint.mjJNT_FREE:
                qpos[a : a + 3] += rng.normal(0, 0.3, 3)
                q = rng.normal(size=4)
                qpos[a + 3 : a + 7] = q / np.linalg.norm(q)
            elif kind == mujoco.mjtJoint.mjJNT_BALL:
                axis, angle = rng.normal(size=3), rng.uniform(0, 0.8)
                qpos[a : a + 4] = [np.cos(angle / 2), *(np.sin(angle / 2) * axis / np.linalg.norm(axis))]
            else:
                low, high = model.jnt_range[j] if model.jnt_limited[j] else (-1.0, 1.0)
                qpos[a] = rng.uniform(low - 0.1 * (high - low), high + 0.1 * (high - low))
        yield qpos, (rng.normal(0, 0.5, model.nv) if k % 5 else np.zeros(model.nv))


def mujoco_answers(model, states):
    data = mujoco.MjData(model)
    answers = []
    for qpos, qvel in states:
        data.qpos[:], data.qvel[:] = qpos, qvel
        mujoco.mj_forward(model, data)
        answers.append((data.qacc.copy(), data.qfrc_constraint.copy(), data.efc_force.copy(), data.efc_type.copy()))
    return answers


def relative(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


@pytest.mark.parametrize("iterations,tolerance,islands", SETTINGS)
def test_no_slip_forces_match_mujoco(iterations, tolerance, islands, nudyn, tmp_path):
    path = variant(tmp_path, iterations, tolerance, islands)
    model = load_model(path)
    assert bool(model.opt.disableflags & ISLAND) != islands
    states = list(random_states(model, np.random.default_rng(5)))
    references = mujoco_answers(model, states)
    requests = [{"theta": qpos.tolist(), "qvel": qvel.tolist()} for qpos, qvel in states]
    result = run_eval(nudyn, path, json.dumps(requests))
    out = result.json()
    assert isinstance(out, list) and len(out) == N_STATES, result.describe()
    for k, ((qacc, qfrc, force, _), answer) in enumerate(zip(references, out)):
        assert relative(answer["qacc"], qacc) < 1e-9, f"state {k}"
        assert relative(answer["qfrc_constraint"], qfrc) < 1e-9, f"state {k}"
        assert relative([r["force"] for r in answer["constraint_rows"]], force) < 1e-9, f"state {k}"

    # The pass matters: without it MuJoCo's answer is elsewhere.
    model.opt.noslip_iterations = 0
    without = mujoco_answers(model, states)
    moved = sum(relative(a[0], b[0]) > 1e-6 for a, b in zip(without, references))
    assert moved > N_STATES // 4


def test_the_settings_and_states_decide(tmp_path):
    """The settings above give different answers (so each is checked for
    itself): one sweep against several, an early stop against none, and at
    tolerance 1e-2 islands against one group; the states have limit rows
    the coupling's row and the tendon's friction row."""
    model = load_model(variant(tmp_path, 3, 1e-6, True))
    states = list(random_states(model, np.random.default_rng(5)))

    def qacc(iterations, tolerance, islands):
        model.opt.noslip_iterations, model.opt.noslip_tolerance = iterations, tolerance
        model.opt.disableflags = (model.opt.disableflags | ISLAND) if not islands else (model.opt.disableflags & ~ISLAND)
        return [a[0] for a in mujoco_answers(model, states)]

    def differing(one, two):
        return sum(relative(a, b) > 1e-9 for a, b in zip(qacc(*one), qacc(*two)))

    assert differing((1, 1e-6, True), (3, 1e-6, True)) > 5
    assert differing((50, 1e-2, True), (50, 0.0, True)) > 5
    assert differing((50, 1e-2, True), (50, 1e-2, False)) > 5
    kinds = [set(a[3]) for a in mujoco_answers(model, states)]
    assert sum(int(mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT) in k for k in kinds) > N_STATES // 4
    assert all(int(mujoco.mjtConstraint.mjCNSTR_EQUALITY) in k for k in kinds)
    assert all(int(mujoco.mjtConstraint.mjCNSTR_FRICTION_TENDON) in k for k in kinds)


def test_the_fmu_runs_the_pass(nudyn, tmp_path):
    """The FMU's qfrc_constraint at a state is MuJoCo's with the pass (and
    not without it)."""
    from fmpy import simulate_fmu

    from nudyn_driver.cli import Nudyn

    path = variant(tmp_path, 3, 1e-6, True)
    model = load_model(path)
    states = list(random_states(model, np.random.default_rng(5)))
    with_pass = mujoco_answers(model, states)
    model.opt.noslip_iterations = 0
    without_pass = mujoco_answers(model, states)
    # The first state where the pass moves qfrc_constraint.
    k = next(k for k in range(N_STATES) if relative(without_pass[k][1], with_pass[k][1]) > 1e-6)
    (qpos, qvel), qfrc = states[k], with_pass[k][1]
    answer = run_eval(nudyn, path, json.dumps({"theta": qpos.tolist(), "qvel": qvel.tolist()})).json()
    fmu = tmp_path / "noslip.fmu"
    Nudyn(nudyn).export(path, fmu, outputs=("qfrc_constraint",))
    start = {f"theta[{i + 1}]": v for i, v in enumerate(qpos)}
    start.update({f"nu[{i + 1}]": v for i, v in enumerate(answer["nu"])})
    names = [f"qfrc_constraint[{i + 1}]" for i in range(model.nv)]
    result = simulate_fmu(fmu, stop_time=1e-3, output_interval=1e-3, start_values=start, output=names)
    at_start = np.array([result[name][0] for name in names])
    assert relative(at_start, qfrc) < 1e-9
