"""Gravity compensation (body gravcomp, joint actuatorgravcomp) against
MuJoCo.

tests/fixtures/gravcomp/arm_on_bus.xml floats a bus on its own
compensation and carries an arm compensated by 1, 0.5, 0.25 and -0.5, with
a welded camera; the elbow's compensation is an actuator force clamped by
its actuatorfrcrange, and the wrist (a ball joint) routes its own through a
default class. Variants of the file, written per test, turn off what
MuJoCo turns the compensation off with: zero or disabled gravity, springs
and dampers both disabled, no body with gravcomp > 0, and (for the routed
share) actuation disabled or no actuators at all.
"""

from __future__ import annotations

import json
import re
import subprocess

import mujoco
import numpy as np
import pytest

from conftest import ROOT, run_eval
from nudyn_validation.compare import Settings, validate_model
from nudyn_validation.mujoco_reference import load_model
from nudyn_validation.scenarios import FORCED_TOLERANCE, UNFORCED_TOLERANCE

FIXTURE = ROOT / "tests" / "fixtures" / "gravcomp" / "arm_on_bus.xml"
N_STATES = 100
ELBOW_LIMIT = 3.0


def random_states(model: mujoco.MjModel, rng: np.random.Generator):
    """qpos with hinges over ±2 rad, random ball and bus orientations,
    slides within ±0.1 m; velocities ~ N(0, 0.5); ctrl uniform in ctrlrange
    where limited, N(0, 1) where not."""
    low, high = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    limited = model.actuator_ctrllimited.astype(bool)
    for _ in range(N_STATES):
        qpos = model.qpos0.copy()
        for j in range(model.njnt):
            a = model.jnt_qposadr[j]
            kind = model.jnt_type[j]
            if kind == mujoco.mjtJoint.mjJNT_FREE:
                qpos[a : a + 3] += rng.normal(0, 0.3, 3)
                q = rng.normal(size=4)
                qpos[a + 3 : a + 7] = q / np.linalg.norm(q)
            elif kind == mujoco.mjtJoint.mjJNT_BALL:
                q = rng.normal(size=4)
                qpos[a : a + 4] = q / np.linalg.norm(q)
            elif kind == mujoco.mjtJoint.mjJNT_HINGE:
                qpos[a] = rng.uniform(-2, 2)
            else:
                qpos[a] = rng.uniform(-0.1, 0.1)
        qvel = rng.normal(0, 0.5, model.nv)
        ctrl = np.where(limited, rng.uniform(low, high), rng.normal(0, 1, model.nu))
        yield qpos, qvel, ctrl


def evaluate(path, nudyn):
    """MuJoCo's mj_forward and nudyn eval at the same random states (with
    ctrl): a list of (MuJoCo's data, nudyn's answer), and MuJoCo's θ̈ with
    every gravcomp set to 0 (how far a model without compensation is)."""
    model = load_model(path)
    data = mujoco.MjData(model)
    uncompensated = load_model(path)
    uncompensated.body_gravcomp[:] = 0
    uncompensated_data = mujoco.MjData(uncompensated)
    references, requests = [], []
    for qpos, qvel, ctrl in random_states(model, np.random.default_rng(33)):
        for m, d in ((model, data), (uncompensated, uncompensated_data)):
            d.qpos[:], d.qvel[:], d.ctrl[:] = qpos, qvel, ctrl
            mujoco.mj_forward(m, d)
        references.append(
            {
                "qacc": data.qacc.copy(),
                "qfrc_gravcomp": data.qfrc_gravcomp.copy(),
                "qfrc_actuator": data.qfrc_actuator.copy(),
                "sensordata": data.sensordata.copy(),
                "qacc_uncompensated": uncompensated_data.qacc.copy(),
            }
        )
        requests.append({"theta": qpos.tolist(), "qvel": qvel.tolist(), "ctrl": ctrl.tolist()})
    result = run_eval(nudyn, path, json.dumps(requests))
    out = result.json()
    assert isinstance(out, list) and len(out) == N_STATES, result.describe()
    return references, out


def relative(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


@pytest.fixture(scope="module")
def evaluated(nudyn):
    return evaluate(FIXTURE, nudyn)


def test_eval_matches_mujoco(evaluated):
    """θ̈, qfrc_gravcomp, qfrc_actuator (with the routed share, clamped) and
    the sensors (jointactuatorfrc reads qfrc_actuator, actuatorfrc the
    actuator's own force) equal MuJoCo's to round-off."""
    references, out = evaluated
    for k, (reference, answer) in enumerate(zip(references, out)):
        for key in ("qacc", "qfrc_gravcomp", "qfrc_actuator", "sensordata"):
            assert relative(answer[key], reference[key]) < 1e-12, f"state {k}: {key}"


def test_the_states_cover_every_rule(evaluated):
    """The elbow's actuator force is clamped in some states and not in
    others; the routed dofs carry compensation; and in every state a model
    without compensation would be off."""
    references, _ = evaluated
    model = load_model(FIXTURE)
    elbow = model.jnt_dofadr[model.joint("elbow").id]
    wrist = model.jnt_dofadr[model.joint("wrist").id]
    at_limit = [np.isclose(abs(r["qfrc_actuator"][elbow]), ELBOW_LIMIT) for r in references]
    assert 10 < sum(at_limit) < N_STATES - 10
    assert all(abs(r["qfrc_gravcomp"][elbow]) > 1e-3 for r in references)
    assert all(np.linalg.norm(r["qfrc_gravcomp"][wrist : wrist + 3]) > 1e-3 for r in references)
    for reference in references:
        assert relative(reference["qacc_uncompensated"], reference["qacc"]) > 1e-3


def variant(tmp_path, name: str, edit) -> object:
    path = tmp_path / f"{name}.xml"
    path.write_text(edit(FIXTURE.read_text()))
    return path


def with_flag(flags: str):
    return lambda text: text.replace('timestep="1e-4"/>', f'timestep="1e-4"><flag {flags}/></option>')


def without_actuators(text: str) -> str:
    text = re.sub(r"<actuator>.*</actuator>", "", text, flags=re.S)
    return re.sub(r"<sensor>.*</sensor>", "", text, flags=re.S)


def negated(text: str) -> str:
    return re.sub(r'gravcomp="(\d)', r'gravcomp="-\1', text)


# Variants where MuJoCo applies no compensation at all.
UNCOMPENSATED = {
    "zero_gravity": lambda text: text.replace('gravity="0.4 -0.3 -9.81"', 'gravity="0 0 0"'),
    "gravity_disabled": with_flag('gravity="disable"'),
    "springs_and_dampers_disabled": with_flag('spring="disable" damper="disable"'),
    "no_positive_gravcomp": negated,
}
# Variants where MuJoCo drops the share routed to the actuators.
UNROUTED = {"actuation_disabled": with_flag('actuation="disable"'), "no_actuators": without_actuators}
def fused(text: str) -> str:
    return text.replace("<option ", '<compiler fusestatic="true"/>\n  <option ', 1)


# Variants where it still applies all of it.
COMPENSATED = {"springs_disabled": with_flag('spring="disable"'), "fusestatic": fused}


@pytest.mark.parametrize("name", [*UNCOMPENSATED, *UNROUTED, *COMPENSATED])
def test_what_turns_compensation_off_as_in_mujoco(name, nudyn, tmp_path):
    edit = {**UNCOMPENSATED, **UNROUTED, **COMPENSATED}[name]
    path = variant(tmp_path, name, edit)
    references, out = evaluate(path, nudyn)
    for k, (reference, answer) in enumerate(zip(references, out)):
        assert relative(answer["qacc"], reference["qacc"]) < 1e-12, f"state {k}"
        if name in UNCOMPENSATED:
            assert not np.any(reference["qfrc_gravcomp"]), f"state {k}"
            assert "qfrc_gravcomp" not in answer, f"state {k}"
        else:
            assert relative(answer["qfrc_gravcomp"], reference["qfrc_gravcomp"]) < 1e-12, f"state {k}"
    if name in UNROUTED:
        # The rule matters: were the share a passive force, θ̈ would differ.
        routed, unrouted = 'actuatorgravcomp="true"', 'actuatorgravcomp="false"'
        passive = variant(tmp_path, f"{name}_passive", lambda text: edit(text).replace(routed, unrouted))
        passive_references, _ = evaluate(passive, nudyn)
        for reference, other in zip(references, passive_references):
            assert relative(reference["qacc"], other["qacc"]) > 1e-6

def test_fusestatic_fuses_what_mujoco_fuses(nudyn, tmp_path):
    """MuJoCo 4.0 fuses a welded body only where its parent's gravcomp
    compensates its mass alike: the lamp (1 under 1) goes, the camera (1
    under 0.5) stays; with springs and dampers disabled (no compensation at
    all) the same bodies stay."""
    passive_off = with_flag('spring="disable" damper="disable"')
    for name, edit in (("fused", fused), ("fused_off", lambda text: passive_off(fused(text)))):
        path = variant(tmp_path, name, edit)
        model = load_model(path)
        described = subprocess.run([nudyn, "describe", "--json", path], capture_output=True, text=True, check=True)
        described = json.loads(described.stdout)
        names = [model.body(i).name for i in range(1, model.nbody)]
        assert [b["name"] for b in described["bodies"]] == names
        assert "camera" in names and "lamp" not in names
        np.testing.assert_allclose([b["mass"] for b in described["bodies"]], model.body_mass[1:], rtol=1e-15)


def test_zero_gravity_gives_exactly_no_compensation(nudyn, tmp_path):
    """Without gravity, a file with gravcomp gives nudyn eval's every number
    of the same file without it, to the bit."""
    weightless = UNCOMPENSATED["zero_gravity"]
    with_gravcomp = variant(tmp_path, "with", weightless)
    without = variant(tmp_path, "without", lambda text: re.sub(r' gravcomp="[^"]*"', "", weightless(text)))
    assert " gravcomp=" in with_gravcomp.read_text() and " gravcomp=" not in without.read_text()
    model = load_model(FIXTURE)
    requests = [
        {"theta": q.tolist(), "qvel": v.tolist(), "ctrl": c.tolist()}
        for q, v, c in random_states(model, np.random.default_rng(5))
    ]
    answers = [run_eval(nudyn, path, json.dumps(requests)).json() for path in (with_gravcomp, without)]
    assert answers[0] == answers[1]


def test_fmu_follows_mujoco(nudyn, tmp_path):
    """Every scenario of scripts/validate.py on the fixture (RK4 at 1e-4 s
    on both sides, 2 s, random ctrl in 'actuated'): θ, ν and sensordata
    within the validation's tolerances."""
    # No MuJoCo twin: only the FMU's errors against MuJoCo are asserted
    # here; the twins feed the verdict, which test_corpus.py tests.
    validation = validate_model(FIXTURE, tmp_path / "arm_on_bus.fmu", nudyn, None, Settings(twins=0))
    names = [result.scenario.name for result in validation.results]
    assert {"gravity", "actuated"} <= set(names), names
    for result in validation.results:
        x = result.summary()
        tolerance = UNFORCED_TOLERANCE if result.scenario.name in ("tumble", "gravity") else FORCED_TOLERANCE
        report = json.dumps(x, indent=1)
        assert x["max_theta_error"] <= tolerance, report
        assert x["max_nu_error"] <= tolerance, report
        assert x["max_sensordata_error"] <= tolerance, report
