"""Constraint forces (equality constraints, joint friction loss and limits)
against MuJoCo.

tests/fixtures/constraints/limited_arm.xml flies a bus with a 5-dof arm
whose joints carry friction loss, hinge, slide and ball limits (margins,
per-joint and per-class solref/solimp, a direct solref);
docked_servicer.xml adds a client vehicle welded to the bus, a tool held by
a connect, a site weld with a torque scale and a joint coupling. MuJoCo's
constraint solver is run to round-off (nudyn_validation.mujoco_reference.
load_model), so both sides solve the same convex problem to its optimum.
"""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest

from conftest import ROOT, assert_restores_bit_for_bit, run_eval
from nudyn_validation.compare import Settings, validate_model
from nudyn_validation.mujoco_reference import load_model
from nudyn_validation.scenarios import FORCED_TOLERANCE, UNFORCED_TOLERANCE

FIXTURES = {name: ROOT / "tests" / "fixtures" / "constraints" / f"{name}.xml" for name in ("limited_arm", "docked_servicer")}
FIXTURE = FIXTURES["limited_arm"]
N_STATES = 100


def random_states(model: mujoco.MjModel, rng: np.random.Generator):
    """qpos with every limited joint spread over its range and 10 % beyond
    it on each side (ball joints up to 1.2 rad against a 40° cone), and
    velocities that are zero in one state out of five (friction loss at rest)."""
    for k in range(N_STATES):
        qpos = model.qpos0.copy()
        for j in range(model.njnt):
            a = model.jnt_qposadr[j]
            kind = model.jnt_type[j]
            if kind == mujoco.mjtJoint.mjJNT_FREE:
                qpos[a : a + 3] += rng.normal(0, 0.3, 3)
                q = rng.normal(size=4)
                qpos[a + 3 : a + 7] = q / np.linalg.norm(q)
            elif kind == mujoco.mjtJoint.mjJNT_BALL:
                axis = rng.normal(size=3)
                angle = rng.uniform(0, 1.2)
                qpos[a : a + 4] = [np.cos(angle / 2), *(np.sin(angle / 2) * axis / np.linalg.norm(axis))]
            else:
                low, high = model.jnt_range[j]
                qpos[a] = rng.uniform(low - 0.1 * (high - low), high + 0.1 * (high - low))
        qvel = rng.normal(0, 0.5, model.nv) if k % 5 else np.zeros(model.nv)
        yield qpos, qvel


@pytest.fixture(params=list(FIXTURES))
def evaluated(request, nudyn, once):
    """(MuJoCo's data per state, nudyn eval's answer per state) for a fixture."""
    return once(evaluate, FIXTURES[request.param], nudyn)


def evaluate(path, nudyn):
    model = load_model(path)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(34)
    references, requests = [], []
    for qpos, qvel in random_states(model, rng):
        data.qpos[:], data.qvel[:] = qpos, qvel
        mujoco.mj_forward(model, data)
        references.append(
            {
                "qacc": data.qacc.copy(),
                "qfrc_constraint": data.qfrc_constraint.copy(),
                "efc_force": data.efc_force.copy(),
                "efc_type": data.efc_type.copy(),
                "efc_frictionloss": data.efc_frictionloss.copy(),
                "sensordata": data.sensordata.copy(),
                "qacc_unconstrained": None,
            }
        )
        requests.append({"theta": qpos.tolist(), "qvel": qvel.tolist()})
    # The same states with MuJoCo's constraints off: how far a model
    # without them would be (the check below must be able to fail).
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    for reference, request in zip(references, requests):
        data.qpos[:], data.qvel[:] = request["theta"], request["qvel"]
        mujoco.mj_forward(model, data)
        reference["qacc_unconstrained"] = data.qacc.copy()
    result = run_eval(nudyn, path, json.dumps(requests))
    out = result.json()
    assert isinstance(out, list) and len(out) == N_STATES, result.describe()
    return references, out


def relative(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


def test_qacc_and_qfrc_constraint_match_mujoco(evaluated):
    references, out = evaluated
    for k, (reference, answer) in enumerate(zip(references, out)):
        assert relative(answer["qacc"], reference["qacc"]) < 1e-9, f"state {k}"
        assert relative(answer["qfrc_constraint"], reference["qfrc_constraint"]) < 1e-8, f"state {k}"


def test_sensors_read_the_limit_rows_as_mujocos(evaluated):
    """jointlimitpos, jointlimitvel, jointlimitfrc (and an accelerometer,
    which feels the constraint forces, and docked_servicer's force and
    torque sensors, which feel the welds and the connect) equal MuJoCo's
    sensordata."""
    references, out = evaluated
    for k, (reference, answer) in enumerate(zip(references, out)):
        assert relative(answer["sensordata"], reference["sensordata"]) < 1e-8, f"state {k}"
    limit_forces = np.array([r["sensordata"][:5] for r in references])
    assert np.count_nonzero(limit_forces) > 10 and np.count_nonzero(limit_forces == 0) > 10


def test_rows_are_mujocos_rows_in_its_order(evaluated):
    references, out = evaluated
    kinds = {
        int(mujoco.mjtConstraint.mjCNSTR_EQUALITY): "equality",
        int(mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF): "friction",
        int(mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT): "limit",
    }
    for k, (reference, answer) in enumerate(zip(references, out)):
        rows = answer["constraint_rows"]
        assert [r["kind"] for r in rows] == [kinds[int(t)] for t in reference["efc_type"]], f"state {k}"
        forces = np.array([r["force"] for r in rows])
        # A weld's rotation rows measure the vector part of a quaternion
        # product: nudyn takes the frames' quaternions from rotation
        # matrices, MuJoCo composes them body by body, so the three rows
        # may come out negated, their forces with them (Jᵀf is the same,
        # checked above). Compare those three up to that sign.
        for first in weld_rotation_rows(rows):
            block = slice(first, first + 3)
            if np.dot(forces[block], reference["efc_force"][block]) < 0:
                forces[block] *= -1
        assert relative(forces, reference["efc_force"]) < 1e-8, f"state {k}"


def weld_rotation_rows(rows) -> list[int]:
    """The first of each weld's three rotation rows (rows 3–5 of its six)."""
    starts, k = [], 0
    while k < len(rows):
        label = rows[k].get("equality", "")
        count = sum(1 for r in rows[k : k + 6] if r.get("equality") == label) if label else 1
        if label.startswith("<weld>"):
            starts.append(k + 3)
            k += 6
        else:
            k += count if label else 1
    return starts


# Models where nudyn once differed from MuJoCo (issue 47): refsafe turned
# off, constraints whose Jacobian vanishes, and bodies MuJoCo weighs by
# 1/mass (each fixture's header says why; welded_strap below).
EDGE_FIXTURES = {
    name: ROOT / "tests" / "fixtures" / "constraints" / f"{name}.xml"
    for name in ("refsafe_off", "empty_rows", "slider_hand")
}


@pytest.mark.parametrize("name", list(EDGE_FIXTURES))
def test_edge_models_match_mujoco(name, nudyn, once):
    """qacc, qfrc_constraint, sensordata and the rows' forces equal MuJoCo's
    at random states in and beyond the limits."""
    references, out = once(evaluate, EDGE_FIXTURES[name], nudyn)
    for k, (reference, answer) in enumerate(zip(references, out)):
        assert relative(answer["qacc"], reference["qacc"]) < 1e-9, f"state {k}"
        assert relative(answer["qfrc_constraint"], reference["qfrc_constraint"]) < 1e-8, f"state {k}"
        if reference["sensordata"].size:
            assert relative(answer["sensordata"], reference["sensordata"]) < 1e-8, f"state {k}"
        forces = [row["force"] for row in answer["constraint_rows"]]
        assert relative(forces, reference["efc_force"]) < 1e-8 if forces else not reference["efc_force"].size


def test_a_tendon_limit_between_welded_bodies_has_no_row(nudyn):
    """welded_strap's tendon cannot change length: nudyn makes no row for
    its violated limit at any swing angle, and its qacc is that of MuJoCo
    with the limit off. Where MuJoCo's own moment arms cancel exactly (at
    least the pose drawn) it drops the row too, and the two agree; at
    other angles it keeps a row of round-off arms pushed by ~1e17."""
    path = ROOT / "tests" / "fixtures" / "constraints" / "welded_strap.xml"
    model = load_model(path)
    free = load_model(path)
    free.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_LIMIT)
    data, free_data = mujoco.MjData(model), mujoco.MjData(free)
    angles = [0.0, *np.random.default_rng(5).uniform(-3, 3, 20)]
    requests, mujoco_drops = [], []
    for angle in angles:
        for d, m in ((data, model), (free_data, free)):
            d.qpos[:], d.qvel[:] = angle, 0.7
            mujoco.mj_forward(m, d)
        requests.append({"theta": [angle], "qvel": [0.7]})
        mujoco_drops.append((data.nefc == 0, data.qacc.copy(), free_data.qacc.copy()))
    out = run_eval(nudyn, path, json.dumps(requests)).json()
    assert mujoco_drops[0][0], "MuJoCo drops the row in the pose drawn"
    for k, (answer, (dropped, qacc, qacc_free)) in enumerate(zip(out, mujoco_drops)):
        assert answer["constraint_rows"] == [] and answer["sensordata"] == [0.0], f"angle {angles[k]}"
        assert relative(answer["qacc"], qacc_free) < 1e-12, f"angle {angles[k]}"
        if dropped:
            assert relative(answer["qacc"], qacc) < 1e-12, f"angle {angles[k]}"


def test_refsafe_off_changes_the_forces(nudyn, once):
    """The refsafe fixture's check can fail: with MuJoCo's refsafe on, its
    constraint forces are far from those of the file as written."""
    model = load_model(EDGE_FIXTURES["refsafe_off"])
    model.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_REFSAFE)
    data = mujoco.MjData(model)
    references, _ = once(evaluate, EDGE_FIXTURES["refsafe_off"], nudyn)
    rng = np.random.default_rng(34)
    differing = 0
    for reference, (qpos, qvel) in zip(references, random_states(model, rng)):
        data.qpos[:], data.qvel[:] = qpos, qvel
        mujoco.mj_forward(model, data)
        differing += relative(data.qacc, reference["qacc"]) > 1e-2
    assert differing > N_STATES // 4


def test_slider_hand_invweights_are_not_the_mass_matrix():
    """The slider fixture's check can fail: MuJoCo weighs its three slide
    bodies' rows by 1/mass, far from the diagonal of M⁻¹ (armature in)
    that nudyn takes for other bodies."""
    model = load_model(EDGE_FIXTURES["slider_hand"])
    assert list(model.body_simple[2:]) == [2, 2, 2]
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    assert relative(np.diag(np.linalg.inv(full)), model.dof_invweight0) > 0.5


def test_the_states_cover_every_regime(nudyn, once):
    """On limited_arm: limits active and inactive, friction loss saturated
    and not; and in every state where a row pushes, a model without
    constraints would be off. (On docked_servicer the random states pull
    the welds far apart: their forces saturate every friction row.)"""
    references, out = once(evaluate, FIXTURE, nudyn)
    limit_counts = [sum(r["kind"] == "limit" for r in a["constraint_rows"]) for a in out]
    assert min(limit_counts) == 0 and max(limit_counts) >= 3
    saturated = sliding = 0
    for reference in references:
        friction = reference["efc_frictionloss"] > 0
        at_bound = np.isclose(np.abs(reference["efc_force"][friction]), reference["efc_frictionloss"][friction])
        saturated += int(np.sum(at_bound))
        sliding += int(np.sum(~at_bound))
    assert saturated > 10 and sliding > 10
    pushing = [r for r in references if np.max(np.abs(r["efc_force"])) > 1e-3]
    assert len(pushing) > N_STATES // 2
    for reference in pushing:
        assert relative(reference["qacc_unconstrained"], reference["qacc"]) > 1e-4


@pytest.mark.parametrize("name", list(FIXTURES))
def test_fmu_runs_into_its_limits_like_mujoco(name, nudyn, tmp_path):
    """Every scenario of scripts/validate.py on the fixture (RK4 at 1e-4 s on
    both sides, 2 s; the docked servicer from qpos0, where its equalities
    hold): θ, ν and sensordata within the validation's tolerances, with
    limits reached along the way."""
    FIXTURE = FIXTURES[name]
    # No MuJoCo twin: only the FMU's errors against MuJoCo are asserted
    # here; the twins feed the verdict, which test_corpus.py tests.
    validation = validate_model(FIXTURE, tmp_path / f"{name}.fmu", nudyn, None, Settings(twins=0))
    model = load_model(FIXTURE)
    limited = [j for j in range(model.njnt) if model.jnt_limited[j] and model.jnt_type[j] != mujoco.mjtJoint.mjJNT_BALL]
    reached = 0
    for result in validation.results:
        x = result.summary()
        tolerance = UNFORCED_TOLERANCE if result.scenario.name in ("tumble", "gravity") else FORCED_TOLERANCE
        report = json.dumps(x, indent=1)
        assert x["max_theta_error"] <= tolerance, report
        assert x["max_nu_error"] <= tolerance, report
        assert x["max_sensordata_error"] <= tolerance, report
        theta = result.mujoco.theta
        for j in limited:
            low, high = model.jnt_range[j]
            margin = model.jnt_margin[j]
            q = theta[:, model.jnt_qposadr[j]]
            reached += int(np.any((q - low < margin) | (high - q < margin)))
    assert reached >= 2, "the scenarios must drive some joint into its limit"
    actuated = next(r for r in validation.results if r.scenario.name == "actuated")
    frc = [k for k in range(load_model(FIXTURE).nsensor) if load_model(FIXTURE).sensor_type[k] == mujoco.mjtSensor.mjSENS_JOINTLIMITFRC]
    limit_forces = actuated.mujoco.sensordata[:, [load_model(FIXTURE).sensor_adr[k] for k in frc]]
    assert np.count_nonzero(limit_forces) > 0, "jointlimitfrc must read a limit's force on the way"


def test_the_fmu_outputs_qfrc_constraint(nudyn, tmp_path):
    """`--outputs qfrc_constraint` gives MuJoCo's qfrc_constraint at the
    FMU's state: equal to nudyn eval's there, and to MuJoCo's to 1e-8;
    zero for a vehicle without constraints."""
    from fmpy import simulate_fmu

    from nudyn_driver.cli import Nudyn

    model = load_model(FIXTURES["docked_servicer"])
    data = mujoco.MjData(model)
    rng = np.random.default_rng(7)
    data.qvel[:] = rng.normal(0, 0.3, model.nv)
    data.ctrl[:] = rng.uniform(-1, 1, model.nu)
    mujoco.mj_forward(model, data)
    answer = run_eval(nudyn, FIXTURES["docked_servicer"], json.dumps({"theta": data.qpos.tolist(), "qvel": data.qvel.tolist(), "ctrl": data.ctrl.tolist()})).json()
    fmu = tmp_path / "docked.fmu"
    Nudyn(nudyn).export(FIXTURES["docked_servicer"], fmu, outputs=("qfrc_constraint",))
    start = {f"theta[{i + 1}]": v for i, v in enumerate(data.qpos)}
    start.update({f"nu[{i + 1}]": v for i, v in enumerate(answer["nu"])})
    start.update({f"ctrl[{i + 1}]": v for i, v in enumerate(data.ctrl)})
    names = [f"qfrc_constraint[{i + 1}]" for i in range(model.nv)]
    result = simulate_fmu(fmu, stop_time=1e-3, output_interval=1e-3, start_values=start, output=names)
    at_start = np.array([result[name][0] for name in names])
    assert relative(at_start, answer["qfrc_constraint"]) < 1e-12
    assert relative(at_start, data.qfrc_constraint) < 1e-8
    assert np.max(np.abs(at_start)) > 1.0

    plain = tmp_path / "plain.fmu"
    Nudyn(nudyn).export(ROOT / "examples" / "bus_arm7.xml", plain, outputs=("qfrc_constraint",))
    result = simulate_fmu(plain, stop_time=1e-2, output_interval=1e-2, output=["qfrc_constraint[7]"])
    assert np.all(result["qfrc_constraint[7]"] == 0.0)


def test_export_disable_leaves_constraint_kinds_out(nudyn, tmp_path):
    """`nudyn export --disable KIND,...` drops those rows as MuJoCo's flags
    do: the FMU's modelDescription names what is left, and with every kind
    disabled its qfrc_constraint stays 0 where the full FMU's does not."""
    import subprocess
    import zipfile

    from fmpy import simulate_fmu

    def export(name, *disable):
        fmu = tmp_path / f"{name}.fmu"
        options = ["--disable", ",".join(disable)] if disable else []
        command = [str(nudyn), "export", str(FIXTURES["docked_servicer"]), "-o", str(fmu), "--outputs", "qfrc_constraint", *options]
        subprocess.run(command, check=True, capture_output=True)
        with zipfile.ZipFile(fmu) as archive:
            description = archive.read("modelDescription.xml").decode()
        return fmu, description

    _, limits_only = export("limits", "equality", "frictionloss")
    assert "limits on 5 joints" in limits_only and "equality" not in limits_only.split("eps_c;")[1].split('"')[0]
    assert "friction loss" not in limits_only
    full, _ = export("full")
    none, description = export("none", "equality", "frictionloss", "limit")
    assert "eps_c" not in description
    names = [f"qfrc_constraint[{i + 1}]" for i in range(6, 12)]
    start = {"nu[7]": 0.5, "nu[9]": -0.3}
    for fmu, moves in ((full, True), (none, False)):
        result = simulate_fmu(fmu, stop_time=0.05, output_interval=0.01, start_values=start, output=names)
        forces = np.array([result[name] for name in names])
        assert (np.max(np.abs(forces)) > 0.1) == moves, fmu.name

    refused = subprocess.run([str(nudyn), "export", str(FIXTURES["docked_servicer"]), "-o", str(tmp_path / "x.fmu"), "--disable", "contact"], capture_output=True, text=True)
    assert refused.returncode == 2 and "unknown constraint kind 'contact'" in refused.stderr


@pytest.mark.parametrize("method", ["dop853", "dopri5", "tsit5", "auto"])
def test_fmu_state_round_trips_bit_exactly_with_constraints(method, nudyn, tmp_path):
    """On docked_servicer (welds, a connect, a coupling, limits, friction
    loss) a restored FMU state continues bit for bit: into the instance
    that ran on meanwhile (its constraint solver's last working set is a
    later one) and into a fresh instance (no working set yet)."""
    from nudyn_driver.cli import Nudyn
    from nudyn_driver.instance import Instance
    from nudyn_driver.package import FmuPackage

    fmu = tmp_path / "docked.fmu"
    Nudyn(nudyn).export(FIXTURES["docked_servicer"], fmu, outputs=("qfrc_constraint",))
    package = FmuPackage.unzip(fmu, tmp_path / "docked")
    eps = {name: 0.3 * np.sin(k) for k, name in enumerate(package.names("eps"))}
    step = 0.05

    def advance(instance, steps):
        start = round(instance.time / step)
        for k in range(start, start + steps):
            instance.step(step, k * step)

    def started():
        instance = Instance(package, start={"method": method})
        instance.set(eps)
        return instance

    with started() as running, started() as fresh:
        advance(running, 20)
        assert_restores_bit_for_bit(running, fresh, advance, 20)
        assert np.abs(running.array("qfrc_constraint")).max() > 1.0, "the constraints must act"


@pytest.mark.parametrize("method", ["dop853", "dopri5", "tsit5", "auto"])
def test_the_fmu_steps_a_constrained_vehicle_with_status_ok(method, nudyn, tmp_path):
    """docked_servicer through the FMU at 1e-6 and 1e-8: every fmi2DoStep
    returns fmi2OK with nothing in the log at warning level (the switches
    of its constraint forces are located: fmusim, OMSimulator and PyFMI
    stop at a warning), and the end is within 20 × the tolerance of a run
    at 1e-11."""
    from nudyn_driver.cli import Nudyn
    from nudyn_driver.instance import Instance
    from nudyn_driver.package import FmuPackage

    fmu = tmp_path / "docked.fmu"
    Nudyn(nudyn).export(FIXTURES["docked_servicer"], fmu)
    package = FmuPackage.unzip(fmu, tmp_path / "docked")
    eps = {name: 0.3 * np.sin(k) for k, name in enumerate(package.names("eps"))}
    outputs = package.names("theta") + package.names("nu")

    def run(method, tolerance):
        with Instance(package, start={"method": method, "tolerance": tolerance}) as slave:
            slave.set(eps)
            statuses = [slave.step(0.05, k * 0.05) for k in range(20)]
            problems = [m for status, _, m in slave.log.messages if status != 0]
            return np.array(slave.get(outputs)), statuses, problems

    reference, _, _ = run("dop853", 1e-11)
    for tolerance in (1e-6, 1e-8):
        end, statuses, problems = run(method, tolerance)
        assert set(statuses) == {0} and problems == [], (tolerance, problems)
        error = np.max(np.abs(end - reference) / (1 + np.abs(reference)))
        assert error <= 20 * tolerance, (tolerance, error)


def test_the_fmu_left_at_rest_holds_1e_10_with_status_ok(nudyn, tmp_path):
    """docked_servicer left at rest (fmusim's inputs) at 1e-10 in 0.01 s
    steps: near rest its error estimate comes within a few times of what
    θ̈'s round-off can make of it, and DOP853 holds 1.0e-9 per second from
    t = 1.05 s. Within 20 times the tolerance asked that meets it
    (docs/fmi.md): every step returns fmi2OK (fmusim stopped at the
    fmi2Warning it returned before), the log has nothing at warning level
    and says what was held, and the end is within 20 × the tolerance of a
    run at 1e-12."""
    from nudyn_driver.cli import Nudyn
    from nudyn_driver.instance import Instance
    from nudyn_driver.package import FmuPackage

    fmu = tmp_path / "docked.fmu"
    Nudyn(nudyn).export(FIXTURES["docked_servicer"], fmu)
    package = FmuPackage.unzip(fmu, tmp_path / "docked")
    outputs = package.names("theta") + package.names("nu")

    def run(tolerance):
        with Instance(package, start={"method": "dop853", "tolerance": tolerance}) as slave:
            statuses = [slave.step(0.01, k * 0.01) for k in range(200)]
            problems = [m for status, _, m in slave.log.messages if status != 0]
            return np.array(slave.get(outputs)), statuses, problems, slave.log.held_tolerance()

    reference = run(1e-12)[0]
    end, statuses, problems, held = run(1e-10)
    assert set(statuses) == {0} and problems == [], problems
    assert held is None or 1e-10 < held <= 20 * 1e-10, held
    error = np.max(np.abs(end - reference) / (1 + np.abs(reference)))
    assert error <= 20 * 1e-10, error
