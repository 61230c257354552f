"""Actuator activation dynamics (MuJoCo's dyntype integrator, filter and
filterexact, with actlimited and actearly) against MuJoCo.

tests/fixtures/activation/filtered_arm.xml flies a base with a four-joint
arm: an integrated velocity command limited to ±0.6 and read early, a
filtered torque, a position servo with a filtered setpoint (filterexact),
a filterexact read early and limited below its ctrl range, a filtered
thrust on a site, and a stateless motor. nudyn refused these files before
(dm_control's quadruped among them).
"""

from __future__ import annotations

import json
import re
import subprocess

import mujoco
import numpy as np
import pytest

from conftest import ROOT, assert_restores_bit_for_bit, run_eval

FIXTURE = ROOT / "tests" / "fixtures" / "activation" / "filtered_arm.xml"
N_STATES = 30


def random_state(model: mujoco.MjModel, rng: np.random.Generator):
    """qpos, qvel, ctrl (up to twice past its range, to exercise the
    clamp) and act (up to 1.5 times past the limited ranges: MuJoCo's force
    reads act as it is, its actearly look-ahead clamps)."""
    qpos = model.qpos0.copy()
    qpos[:3] += rng.normal(0, 0.3, 3)
    q = rng.normal(size=4)
    qpos[3:7] = q / np.linalg.norm(q)
    qpos[7:] += rng.normal(0, 0.5, model.nq - 7)
    qvel = rng.normal(0, 0.5, model.nv)
    ctrl = rng.uniform(-2, 2, model.nu) * np.max(np.abs(model.actuator_ctrlrange), axis=1)
    act = rng.uniform(-0.9, 0.9, model.na)
    return qpos, qvel, ctrl, act


def test_qacc_and_act_dot_match_mj_forward(nudyn):
    """At random states with random controls and activations, nudyn eval's
    qacc, act_dot and actuator forces are mj_forward's to 1e-12."""
    model = mujoco.MjModel.from_xml_path(str(FIXTURE))
    assert model.na == 5 and set(model.actuator_dyntype) == {0, 1, 2, 3}
    data = mujoco.MjData(model)
    rng = np.random.default_rng(11)
    requests, references = [], []
    for _ in range(N_STATES):
        qpos, qvel, ctrl, act = random_state(model, rng)
        data.qpos[:], data.qvel[:], data.ctrl[:], data.act[:] = qpos, qvel, ctrl, act
        mujoco.mj_forward(model, data)
        requests.append({"theta": qpos.tolist(), "qvel": qvel.tolist(), "ctrl": ctrl.tolist(), "act": act.tolist()})
        references.append((data.qacc.copy(), data.act_dot.copy(), data.actuator_force.copy()))
    answers = run_eval(nudyn, FIXTURE, json.dumps(requests)).json()
    early_clamped = 0
    for k, (answer, (qacc, act_dot, force)) in enumerate(zip(answers, references)):
        scale = max(1.0, np.max(np.abs(qacc)))
        assert np.max(np.abs(np.array(answer["qacc"]) - qacc)) <= 1e-12 * scale, k
        assert np.max(np.abs(np.array(answer["act_dot"]) - act_dot)) <= 1e-12 * max(1.0, np.max(np.abs(act_dot))), k
        assert np.max(np.abs(np.array(answer["actuator_force"]) - force)) <= 1e-12 * max(1.0, np.max(np.abs(force))), k
        # The early look-ahead clamped to ±0.6 rad (the shoulder servo's force reads 30·0.6 at most).
        early_clamped += abs(force[0] + 30 * requests[k]["theta"][7] + 3 * requests[k]["qvel"][6]) >= 30 * 0.6 - 1e-9
    assert early_clamped > 0, "some state must drive the early activation past its range"
    # The activations matter: with act at 0 the forces are others.
    without = run_eval(nudyn, FIXTURE, json.dumps({**requests[0], "act": [0.0] * model.na})).json()
    assert np.max(np.abs(np.array(without["qacc"]) - references[0][0])) > 1e-3


SHORTCUTS = ROOT / "tests" / "fixtures" / "activation" / "shortcut_servos.xml"


def test_intvelocity_and_cylinder_act_as_in_mj_forward(nudyn):
    """MuJoCo's <intvelocity> and <cylinder> shortcuts (on elements, from
    classes, lent by a <general> default, an activation range inherited
    from the joint; test_actuators.py compares their compiled parameters):
    at random states, controls (some past their ranges) and activations
    (the integrators' within their ranges, where a run keeps them: nudyn's
    force reads act clamped, MuJoCo's as it is, docs/DYNAMICS.md §5), nudyn eval's
    qacc, act_dot and actuator forces are mj_forward's to 1e-12."""
    model = mujoco.MjModel.from_xml_path(str(SHORTCUTS))
    assert list(model.actuator_dyntype) == [1, 1, 2, 2]
    data = mujoco.MjData(model)
    rng = np.random.default_rng(12)
    requests, references = [], []
    for _ in range(N_STATES):
        qpos, qvel, ctrl, act = random_state(model, rng)
        act[:2] = [rng.uniform(*model.actuator_actrange[i]) for i in range(2)]
        act[2:] *= 30  # the cylinders' pressures
        data.qpos[:], data.qvel[:], data.ctrl[:], data.act[:] = qpos, qvel, ctrl, act
        mujoco.mj_forward(model, data)
        requests.append({"theta": qpos.tolist(), "qvel": qvel.tolist(), "ctrl": ctrl.tolist(), "act": act.tolist()})
        references.append((data.qacc.copy(), data.act_dot.copy(), data.actuator_force.copy()))
    answers = run_eval(nudyn, SHORTCUTS, json.dumps(requests)).json()
    for k, (answer, (qacc, act_dot, force)) in enumerate(zip(answers, references)):
        for name, ours, theirs in [("qacc", answer["qacc"], qacc), ("act_dot", answer["act_dot"], act_dot),
                                   ("actuator_force", answer["actuator_force"], force)]:
            error = np.max(np.abs(np.array(ours) - theirs))
            assert error <= 1e-12 * max(1.0, np.max(np.abs(theirs))), (k, name, error)


def fixture_for_rk4(tmp_path, timestep: float):
    """The fixture with `timestep`, and its filterexact actuators written as
    filter. MuJoCo's RK4 takes τ(1 − e^(−h/τ)) for h in a filterexact's
    last update, which makes it first order there (2.7e-5 off at 1e-5 s
    on this file): filter is the same ODE, which its RK4 integrates to
    fourth order. actearly's look-ahead, where the two differ, reads one
    timestep ahead, so both sides read the same short one here;
    test_qacc_and_act_dot_match_mj_forward checks it at the file's."""
    text = re.sub(r'timestep="[^"]*"', f'timestep="{timestep}"', FIXTURE.read_text())
    text = text.replace('dyntype="filterexact"', 'dyntype="filter"')
    servo = '<position name="roll_servo" joint="roll" kp="6" kv="0.4" timeconst="0.08" ctrlrange="-2 2"/>'
    assert servo in text
    text = text.replace(servo, '<general name="roll_servo" joint="roll" gainprm="6" biastype="affine" '
                        'biasprm="0 -6 -0.4" dyntype="filter" dynprm="0.08" ctrlrange="-2 2"/>')
    path = tmp_path / "filtered_arm.xml"
    path.write_text(text)
    return path


def test_trajectory_matches_mujoco_rk4_converged(nudyn, tmp_path):
    """One second from a moving start with controls that drive two
    activations into their limits: nudyn simulate (dop853 at 1e-11) and
    MuJoCo's own RK4 at 1e-5 s agree in θ and act to 1e-9 (measured: 1.8e-11
    and 3.7e-13), and in qvel at the end (fixture_for_rk4 says what the
    file's copy changes)."""
    timestep = 1e-5
    path = fixture_for_rk4(tmp_path, timestep)
    model = mujoco.MjModel.from_xml_path(str(path))
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    data = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    qvel0 = rng.normal(0, 0.3, model.nv)
    act0 = np.array([0.1, -0.2, 0.3, 0.2, 0.0])
    ctrl = np.array([1.0, -0.8, 1.5, 1.0, 0.7, 0.3])
    data.qvel[:], data.act[:], data.ctrl[:] = qvel0, act0, ctrl
    mujoco.mj_forward(model, data)
    nu0 = run_eval(nudyn, path, json.dumps({"theta": data.qpos.tolist(), "qvel": qvel0.tolist()})).json()["nu"]

    step, stop = 0.05, 1.0
    request = {"nu": nu0, "act": act0.tolist(), "ctrl": ctrl.tolist()}
    cmd = [str(nudyn), "simulate", str(path), "--step", str(step), "--stop", str(stop), "--method", "dop853",
           "--tolerance", "1e-11"]
    proc = subprocess.run(cmd, input=json.dumps(request), capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    run = json.loads(proc.stdout)
    assert len(run["act"]) == len(run["time"]) == 21

    per_output = round(step / timestep)
    theta_error = act_error = 0.0
    limited = {0: 0.6, 3: 0.5}
    reached = set()
    for k in range(1, len(run["time"])):
        mujoco.mj_step(model, data, nstep=per_output)
        theta_error = max(theta_error, np.max(np.abs(np.array(run["theta"][k]) - data.qpos)))
        act_error = max(act_error, np.max(np.abs(np.array(run["act"][k]) - data.act)))
        reached |= {i for i, bound in limited.items() if abs(data.act[i]) >= bound - 1e-12}
    assert theta_error <= 1e-9 and act_error <= 1e-9, (theta_error, act_error)
    assert reached == set(limited), "both limited activations must reach their bounds"
    end = {"theta": run["theta"][-1], "nu": run["nu"][-1]}
    qvel = np.array(run_eval(nudyn, path, json.dumps(end)).json()["qvel"])
    assert np.max(np.abs(qvel - data.qvel)) <= 1e-7 * max(1.0, np.max(np.abs(data.qvel)))


def mujoco_rk4_run(path, qvel0, act0, ctrl, times):
    """MuJoCo's own RK4 at the file's (short) timestep: qpos and act at `times`."""
    model = mujoco.MjModel.from_xml_path(str(path))
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    data = mujoco.MjData(model)
    data.qvel[:], data.act[:], data.ctrl[:] = qvel0, act0, ctrl
    qpos, act = [data.qpos.copy()], [data.act.copy()]
    for t0, t1 in zip(times[:-1], times[1:]):
        mujoco.mj_step(model, data, nstep=round((t1 - t0) / model.opt.timestep))
        qpos.append(data.qpos.copy())
        act.append(data.act.copy())
    return np.array(qpos), np.array(act)


def test_fmu_runs_activations_in_co_simulation_and_model_exchange(nudyn, tmp_path):
    """The FMU has act[1..5] as outputs and, in model exchange, as the
    states after θ and ν (der(act[k]) last); set before initialization,
    they start the run. FMPy's co-simulation (dop853 at 1e-10) and its
    model exchange (CVode at rtol 1e-10) end where MuJoCo's RK4 at 1e-5 s
    does: θ and act within 1e-9 (measured 1.6e-11 and 2e-15) and 1e-7
    (3.7e-9 and 7.8e-9)."""
    from fmpy import read_model_description, simulate_fmu

    path = fixture_for_rk4(tmp_path, 1e-5)
    fmu = tmp_path / "filtered_arm.fmu"
    subprocess.run([str(nudyn), "export", str(path), "-o", str(fmu)], check=True, capture_output=True)
    description = read_model_description(str(fmu))
    names = [v.name for v in description.modelVariables]
    assert [names.index(f"act[{k}]") for k in range(1, 6)] == [names.index("act[1]") + k for k in range(5)]
    states = [d.variable.derivative.name for d in description.derivatives]
    assert states[-5:] == [f"act[{k}]" for k in range(1, 6)] and states[0] == "theta[1]"

    qvel0 = np.random.default_rng(3).normal(0, 0.3, 10)
    act0 = np.array([0.1, -0.2, 0.3, 0.2, 0.0])
    ctrl = np.array([1.0, -0.8, 1.5, 1.0, 0.7, 0.3])
    theta0 = mujoco.MjModel.from_xml_path(str(path)).qpos0
    nu0 = run_eval(nudyn, path, json.dumps({"theta": theta0.tolist(), "qvel": qvel0.tolist()})).json()["nu"]
    start = {f"nu[{k + 1}]": x for k, x in enumerate(nu0)}
    start |= {f"act[{k + 1}]": x for k, x in enumerate(act0)}
    start |= {f"ctrl[{k + 1}]": x for k, x in enumerate(ctrl)}
    outputs = [f"theta[{k}]" for k in range(1, 12)] + [f"act[{k}]" for k in range(1, 6)]
    times = np.linspace(0.0, 1.0, 21)
    qpos, act = mujoco_rk4_run(path, qvel0, act0, ctrl, times)
    for kind, tolerances, options in [
        ("CoSimulation", (1e-9, 1e-9), {"start_values": {**start, "tolerance": 1e-10}}),
        ("ModelExchange", (1e-7, 1e-7), {"start_values": start, "relative_tolerance": 1e-10}),
    ]:
        result = simulate_fmu(str(fmu), fmi_type=kind, stop_time=1.0, output_interval=0.05, output=outputs, **options)
        end = result[-1]
        assert abs(end["time"] - 1.0) < 1e-9
        theta_error = max(abs(end[f"theta[{k}]"] - qpos[-1][k - 1]) for k in range(1, 12))
        act_error = max(abs(end[f"act[{k}]"] - act[-1][k - 1]) for k in range(1, 6))
        assert theta_error <= tolerances[0] and act_error <= tolerances[1], (kind, theta_error, act_error)


@pytest.mark.parametrize("method", ["rk4", "dop853", "ros34pw2"])
def test_fmu_state_with_activations_round_trips_bit_exactly(method, nudyn, tmp_path):
    """A restored FMU state continues bit for bit with the activations
    (ros34pw2 saves its W with act's rows and columns): into the instance
    that ran on, and, serialized, into a fresh one; act moves meanwhile and
    reaches its bounds."""
    from nudyn_driver.cli import Nudyn
    from nudyn_driver.instance import Instance
    from nudyn_driver.package import FmuPackage

    fmu = tmp_path / "filtered_arm.fmu"
    Nudyn(nudyn).export(FIXTURE, fmu)
    package = FmuPackage.unzip(fmu, tmp_path / "filtered_arm")
    ctrl = dict(zip(package.names("ctrl"), [1.0, -0.8, 1.5, 1.0, 0.7, 0.3]))
    step = 0.005

    def advance(instance, steps):
        start = round(instance.time / step)
        for k in range(start, start + steps):
            instance.step(step, k * step)

    def started():
        instance = Instance(package, start={"method": method, "act[2]": 0.3})
        instance.set(ctrl)
        return instance

    with started() as running, started() as fresh:
        advance(running, 2)
        act_before = running.array("act").copy()
        assert_restores_bit_for_bit(running, fresh, advance, 60)
        act_after = running.array("act")
        assert np.all(act_after != act_before), "every act moves"
        assert act_before[3] < 0.5 and act_after[3] == 0.5, "reach_early's act reaches its bound and stays"


def test_adaptive_methods_meet_the_tolerance_across_the_clamps_without_relaxing(nudyn):
    """Where act or actearly's look-ahead reaches its actrange, the force
    kinks; the adaptive methods end a step there instead of creeping across
    it (which the round-off test took for round-off: dop853 at 1e-8 relaxed
    to 2.7e-4 per second). Every method delivers within the band the
    adaptive methods are held to (20 times the tolerance) of a dop853 run
    at 1e-13, and says nothing. (Measured: at most 0.04 times the
    tolerance while every step ended at a communication point; 1.4 times,
    dop853 at 1e-8, since steps reach past them: docs/integration.md.)"""
    request = json.dumps({"act": [0.1, -0.2, 0.3, 0.2, 0.0], "ctrl": [1.0, -0.8, 1.5, 1.0, 0.7, 0.3]})

    def run(method, tolerance):
        cmd = [str(nudyn), "simulate", str(FIXTURE), "--step", "0.1", "--stop", "1", "--method", method,
               "--tolerance", str(tolerance)]
        proc = subprocess.run(cmd, input=request, capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr
        out = json.loads(proc.stdout)
        return [np.array(out[key]) for key in ("theta", "nu", "act")], proc.stderr

    reference, _ = run("dop853", 1e-13)
    assert reference[2][-1][3] == 0.5 and reference[2][-1][0] == 0.6, "both limited activations reach their bounds"
    for method in ("dop853", "dopri5", "tsit5", "ros34pw2"):
        for tolerance in (1e-6, 1e-8):
            found, stderr = run(method, tolerance)
            assert "warning" not in stderr, (method, tolerance, stderr)
            error = max(np.max(np.abs(f - r) / (1 + np.abs(r))) for f, r in zip(found, reference))
            assert error <= 20 * tolerance, (method, tolerance, error)


def test_describe_lists_the_activation_states(nudyn):
    """`nudyn describe` names each activation state's actuator, dyntype,
    time constant, actrange and actearly (JSON: `activation`, absent for a
    stateless actuator)."""
    run = lambda *args: subprocess.run([str(nudyn), "describe", str(FIXTURE), *args], capture_output=True,
                                       text=True, check=True).stdout
    actuators = json.loads(run("--json"))["actuators"]
    assert [a.get("activation") is not None for a in actuators] == [True] * 5 + [False]
    assert actuators[3]["activation"] == {"kind": "filterexact", "time_constant": 0.03, "range": [-0.5, 0.5],
                                          "early": True}
    assert "5 activation states (act order)" in run()
