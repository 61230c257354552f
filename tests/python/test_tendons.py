"""Tendons against MuJoCo.

tests/fixtures/tendons/tendon_finger.xml flies a bus with a 3-joint finger
coupled by a fixed tendon (spring with a deadband, damper, friction loss,
range) and pulled by a spatial tendon through sites on the bus and each
phalanx (with a pulley), a position servo on the fixed tendon with an
inherited ctrlrange and a motor on the spatial one; tendon_limits.xml a bus
with an arm whose spatial and fixed tendons carry limits and friction loss
beside joint friction and a joint limit, and two tendon equalities;
tendon_wrap.xml spatial tendons wrapping around a cylinder and two spheres;
tendon_sidesite.xml the same with side sites (MuJoCo 4.0's rule, the long
way round in some states); tendon_wrap_fitted.xml the same with the
cylinder and a sphere fitted to meshes (their radius and frame from the
mesh, as MuJoCo's compiler fits them); tendon_armature.xml two arms on a
bus whose tendons carry armature, along one chain, across both arms and
through a pulley, with limits, friction loss, equalities and tendon
actuators; tendon_force_range.xml an arm whose tendons' actuators are held
to the tendons' actuatorfrcrange. MuJoCo's
constraint solver is run to round-off (nudyn_validation.mujoco_reference.
load_model), so both sides solve the same problem to its optimum.
"""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest

from conftest import ROOT, run_eval
from nudyn_validation.compare import Settings, validate_model
from nudyn_validation.mujoco_reference import load_model
from nudyn_validation.scenarios import FORCED_TOLERANCE, UNFORCED_TOLERANCE

FIXTURES = {
    name: ROOT / "tests" / "fixtures" / "tendons" / f"{name}.xml"
    for name in ("tendon_finger", "tendon_limits", "tendon_wrap", "tendon_wrap_fitted", "tendon_armature",
                 "tendon_force_range", "tendon_sidesite")
}
N_STATES = 60
KINDS = {
    int(mujoco.mjtConstraint.mjCNSTR_EQUALITY): "equality",
    int(mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF): "friction",
    int(mujoco.mjtConstraint.mjCNSTR_FRICTION_TENDON): "tendon_friction",
    int(mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT): "limit",
    int(mujoco.mjtConstraint.mjCNSTR_LIMIT_TENDON): "tendon_limit",
}


def random_states(model: mujoco.MjModel, rng: np.random.Generator):
    """The bus anywhere, the arm's joints spread by 0.8 rad (or m) about
    qpos0 so that tendons cross their ranges, random velocities and controls
    beyond their ranges; one state in five near qpos0 at rest without
    controls, where friction loss holds the arm (its rows inside their box)."""
    for k in range(N_STATES):
        at_rest = k % 5 == 0
        qpos = model.qpos0.copy()
        qpos[:3] += rng.normal(0, 0.3, 3)
        q = rng.normal(size=4)
        qpos[3:7] = q / np.linalg.norm(q)
        qpos[7:] += rng.normal(0, 0.01 if at_rest else 0.8, model.nq - 7)
        qvel = np.zeros(model.nv) if at_rest else rng.normal(0, 0.5, model.nv)
        ctrl = np.zeros(model.nu) if at_rest else rng.uniform(-1.5, 1.5, model.nu)
        yield qpos, qvel, ctrl


@pytest.fixture(params=list(FIXTURES))
def evaluated(request, nudyn, once):
    """(MuJoCo's data per state, nudyn eval's answer per state) for a fixture."""
    return once(evaluate, FIXTURES[request.param], nudyn)


def evaluate(path, nudyn):
    model = load_model(path)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(33)
    references, requests = [], []
    for qpos, qvel, ctrl in random_states(model, rng):
        data.qpos[:], data.qvel[:], data.ctrl[:] = qpos, qvel, ctrl
        mujoco.mj_forward(model, data)
        references.append(
            {
                "qacc": data.qacc.copy(),
                "qfrc_constraint": data.qfrc_constraint.copy(),
                "qfrc_passive": data.qfrc_passive.copy(),
                "efc_type": data.efc_type.copy(),
                "efc_force": data.efc_force.copy(),
                "ten_length": data.ten_length.copy(),
                "ten_velocity": data.ten_velocity.copy(),
                "ten_wrapnum": data.ten_wrapnum.copy(),
                "sensordata": data.sensordata.copy(),
            }
        )
        requests.append({"theta": qpos.tolist(), "qvel": qvel.tolist(), "ctrl": ctrl.tolist()})
    # The same states without the tendons' springs and dampers: how far a
    # model that left them out would be (the check below must be able to fail).
    model.tendon_stiffness[:] = 0
    model.tendon_damping[:] = 0
    for reference, request in zip(references, requests):
        data.qpos[:], data.qvel[:], data.ctrl[:] = request["theta"], request["qvel"], request["ctrl"]
        mujoco.mj_forward(model, data)
        reference["qacc_without_tendon_springs"] = data.qacc.copy()
    if model.tendon_armature.any():
        add_armature_references(model, references, requests)
    if model.tendon_actfrclimited.any():
        model.tendon_actfrclimited[:] = 0
        for reference, request in zip(references, requests):
            data.qpos[:], data.qvel[:], data.ctrl[:] = request["theta"], request["qvel"], request["ctrl"]
            mujoco.mj_forward(model, data)
            reference["qacc_without_tendon_force_ranges"] = data.qacc.copy()
    result = run_eval(nudyn, path, json.dumps(requests))
    out = result.json()
    assert isinstance(out, list) and len(out) == N_STATES, result.describe()
    return references, out


def add_armature_references(model, references, requests) -> None:
    """What the tendons' armature does in MuJoCo at each state, without
    springs: its unconstrained acceleration (qacc_smooth); that of a mass
    matrix taking the whole a·JᵀJ (MuJoCo keeps a·J_iJ_j only where dof i
    and dof j lie on one chain); that without the armature's bias a·J(J̇θ̇);
    and that without the armature at all (the compiled constants kept)."""
    data = mujoco.MjData(model)
    moments = np.zeros((model.ntendon, model.nv))
    armature = model.tendon_armature.copy()
    for reference, request in zip(references, requests):
        data.qpos[:], data.qvel[:], data.ctrl[:] = request["theta"], request["qvel"], request["ctrl"]
        mujoco.mj_forward(model, data)
        mass = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, mass)
        mujoco.mju_sparse2dense(moments, data.ten_J, model.ten_J_rownnz, model.ten_J_rowadr, model.ten_J_colind)
        smooth, force, bias = data.qacc_smooth.copy(), data.qfrc_smooth.copy(), data.qfrc_bias.copy()
        model.tendon_armature[:] = 0
        mujoco.mj_forward(model, data)
        tree_mass = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, tree_mass)
        armature_bias = bias - data.qfrc_bias
        reference["qacc_smooth"] = smooth
        reference["qacc_smooth_dense"] = np.linalg.solve(tree_mass + moments.T @ np.diag(armature) @ moments, force)
        reference["qacc_smooth_without_bias"] = np.linalg.solve(mass, force + armature_bias)
        reference["qacc_smooth_without_armature"] = data.qacc_smooth.copy()
        model.tendon_armature[:] = armature


def test_tendon_armature_counts_as_mujoco_applies_it(nudyn, once):
    """On tendon_armature, nudyn's agreement above (1e-12) could not come
    from leaving out the armature, from the whole a·JᵀJ in place of
    MuJoCo's tree-sparse share of it, or from leaving out its bias a·J(J̇θ̇):
    each moves MuJoCo's own unconstrained acceleration by far more."""
    references, _ = once(evaluate, FIXTURES["tendon_armature"], nudyn)
    for variant in ("qacc_smooth_without_armature", "qacc_smooth_dense", "qacc_smooth_without_bias"):
        moved = [relative(r[variant], r["qacc_smooth"]) for r in references if r["qacc_smooth"].any()]
        assert np.median(moved) > 1e-4, (variant, np.median(moved))


def test_tendon_armature_enters_nu_dot_as_its_own_eps(nudyn, once):
    """ν̇ = ε + ε_actuator + ε_tendon_inertia + ε_c − C + ε_passive, the
    armature's share reported apart (nudyn's ν stays the tree's)."""
    _, out = once(evaluate, FIXTURES["tendon_armature"], nudyn)
    for k, answer in enumerate(out):
        parts = ("eps", "eps_actuator", "eps_tendon_inertia", "eps_constraint", "eps_passive")
        total = sum(np.array(answer[p]) for p in parts) - np.array(answer["coriolis"])
        assert relative(total, answer["nu_dot"]) < 1e-13, f"state {k}"
        assert np.any(np.array(answer["eps_tendon_inertia"]) != 0) or not np.any(answer["qvel"]), f"state {k}"


def test_the_reference_takes_m_and_k_of_the_tree_as_nudyn_does(nudyn):
    """nudyn_validation's Reference, against which `nudyn eval` is checked,
    leaves the tendons' armature out of M, m and K as nudyn does (MuJoCo's
    M holds it): ν, K and ν̇ agree on tendon_armature, and MuJoCo's own
    ½θ̇ᵀMθ̇ differs from K by far more than they do."""
    from nudyn_validation.mujoco_reference import Reference

    reference = Reference.from_file(FIXTURES["tendon_armature"])
    rng = np.random.default_rng(5)
    states = [(reference.model.qpos0 + np.concatenate([np.zeros(7), rng.normal(0, 0.3, reference.nq - 7)]),
               rng.normal(0, 0.5, reference.nv)) for _ in range(5)]
    requests = [{"theta": q.tolist(), "qvel": v.tolist()} for q, v in states]
    answers = run_eval(nudyn, FIXTURES["tendon_armature"], json.dumps(requests)).json()
    for (qpos, qvel), answer in zip(states, answers):
        assert relative(answer["nu"], reference.nu(qpos, qvel)) < 1e-12
        k = reference.kinetic_energy(qpos, qvel)
        assert abs(answer["kinetic_energy"] - k) < 1e-12 * max(1.0, k)
        assert relative(answer["nu_dot"], reference.nu_dot(qpos, qvel)) < 1e-8
        data = reference.forward(qpos, qvel)
        with_armature = np.zeros((reference.nv, reference.nv))
        mujoco.mj_fullM(reference.model, data, with_armature)
        assert abs(0.5 * qvel @ with_armature @ qvel - k) > 1e-5 * k


def test_tendon_force_ranges_bind_in_some_states(nudyn, once):
    """On tendon_force_range, MuJoCo's scaling of the tendons' actuator
    forces changes qacc in some states (by far more than the agreement
    above) and leaves it alone in others, so both are compared."""
    references, _ = once(evaluate, FIXTURES["tendon_force_range"], nudyn)
    # Both without the tendons' springs (evaluate takes them out first).
    moved = [relative(r["qacc_without_tendon_force_ranges"], r["qacc_without_tendon_springs"]) for r in references]
    assert sum(m > 1e-3 for m in moved) >= 10 and sum(m == 0 for m in moved) >= 5, sorted(moved)


def relative(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


def test_qacc_and_qfrc_constraint_match_mujoco(evaluated):
    references, out = evaluated
    for k, (reference, answer) in enumerate(zip(references, out)):
        assert relative(answer["qacc"], reference["qacc"]) < 1e-12, f"state {k}"
        # A vehicle without constraint rows reports none (MuJoCo's is then 0).
        qfrc_constraint = answer.get("qfrc_constraint", np.zeros_like(reference["qfrc_constraint"]))
        assert relative(qfrc_constraint, reference["qfrc_constraint"]) < 1e-12, f"state {k}"


def test_tendon_springs_and_dampers_count(evaluated):
    """Where MuJoCo's tendon springs and dampers push, a model without them
    is off by far more than the agreement above."""
    references, _ = evaluated
    if not any(r["qfrc_passive"].any() for r in references):
        pytest.skip("no tendon spring")
    moved = [relative(r["qacc_without_tendon_springs"], r["qacc"]) for r in references]
    assert min(moved) > 1e-6, min(moved)


def test_tendon_sensors_equal_mujocos_sensordata(evaluated):
    """tendonpos, tendonvel, tendonactuatorfrc and the tendon limit sensors
    (with actuator sensors on tendon transmissions) equal MuJoCo's."""
    references, out = evaluated
    for k, (reference, answer) in enumerate(zip(references, out)):
        assert relative(answer["sensordata"], reference["sensordata"]) < 1e-12, f"state {k}"


def test_rows_are_mujocos_rows_in_its_order(evaluated):
    references, out = evaluated
    for k, (reference, answer) in enumerate(zip(references, out)):
        rows = answer.get("constraint_rows", [])
        assert [r["kind"] for r in rows] == [KINDS[int(t)] for t in reference["efc_type"]], f"state {k}"
        forces = np.array([r["force"] for r in rows])
        assert not rows or relative(forces, reference["efc_force"]) < 1e-10, f"state {k}"


def test_the_states_cover_every_tendon_row(nudyn, once):
    """Tendon limits active and not, on both sides of the rows' order;
    tendon friction loss saturated and sliding; both equalities present."""
    _, limits = once(evaluate, FIXTURES["tendon_limits"], nudyn)
    kinds = [[r["kind"] for r in a["constraint_rows"]] for a in limits]
    assert min(k.count("tendon_limit") for k in kinds) == 0 and max(k.count("tendon_limit") for k in kinds) >= 1
    assert all(k.count("equality") == 2 for k in kinds)
    strap = [r for a in limits for r in a["constraint_rows"] if r.get("tendon") == "<spatial> tendon 'strap'"]
    assert {r["kind"] for r in strap} == {"tendon_friction", "tendon_limit"}
    friction = [r["force"] for a in limits + once(evaluate, FIXTURES["tendon_finger"], nudyn)[1] for r in a["constraint_rows"] if r["kind"] == "tendon_friction"]
    saturated = sum(np.isclose(abs(f), 8) or np.isclose(abs(f), 0.3) for f in friction)
    assert saturated > 10 and len(friction) - saturated > 5


@pytest.mark.parametrize("name", ["tendon_wrap", "tendon_wrap_fitted", "tendon_sidesite"])
def test_the_states_wrap_each_tendon_and_not(nudyn, name, once):
    """On the wrap fixtures, each tendon runs around its geom in some states
    and straight past it in others (MuJoCo's ten_wrapnum: two more points
    when wrapped), so both branches of the wrap are compared above."""
    references, _ = once(evaluate, FIXTURES[name], nudyn)
    counts = np.array([r["ten_wrapnum"] for r in references])
    for tendon in range(counts.shape[1]):
        assert len(set(counts[:, tendon])) == 2, (tendon, sorted(set(counts[:, tendon])))


def test_side_sites_change_the_wraps_in_some_states(nudyn, once):
    """tendon_sidesite.xml is tendon_wrap.xml with side sites and the same
    states: each side site sends its tendon another way round (or straight
    where it wrapped) in some of them, so the side rule is what the
    comparisons above test."""
    plain, _ = once(evaluate, FIXTURES["tendon_wrap"], nudyn)
    sided, _ = once(evaluate, FIXTURES["tendon_sidesite"], nudyn)
    lengths = [np.array([r["ten_length"] for r in references]) for references in (plain, sided)]
    differs = np.abs(lengths[0] - lengths[1]) > 1e-6
    assert np.all(differs.any(axis=0)), differs.sum(axis=0)


@pytest.mark.parametrize("name", list(FIXTURES))
def test_fmu_runs_with_its_tendons_like_mujoco(name, nudyn, tmp_path):
    """Every scenario of scripts/validate.py (RK4 at 1e-4 s on both sides,
    2 s): θ, ν and sensordata within the validation's tolerances; on
    tendon_limits with a tendon limit reached on the way."""
    fixture = FIXTURES[name]
    # No MuJoCo twin: only the FMU's errors against MuJoCo are asserted
    # here; the twins feed the verdict, which test_corpus.py tests.
    validation = validate_model(fixture, tmp_path / f"{name}.fmu", nudyn, None, Settings(twins=0))
    model = load_model(fixture)
    data = mujoco.MjData(model)
    reached = 0
    for result in validation.results:
        x = result.summary()
        tolerance = UNFORCED_TOLERANCE if result.scenario.name in ("tumble", "gravity") else FORCED_TOLERANCE
        report = json.dumps(x, indent=1)
        assert x["max_theta_error"] <= tolerance, report
        assert x["max_nu_error"] <= tolerance, report
        assert x["max_sensordata_error"] <= tolerance, report
        # K is the tree's on both sides (MuJoCo's energy counts the tendons' armature too).
        k_scale = max(1.0, float(np.max(result.mujoco.kinetic_energy)))
        assert x["max_kinetic_energy_error"] <= tolerance * k_scale, report
        for qpos in result.mujoco.theta:
            data.qpos[:] = qpos
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            mujoco.mj_tendon(model, data)
            low, high = model.tendon_range[:, 0] + model.tendon_margin, model.tendon_range[:, 1] - model.tendon_margin
            limited = model.tendon_limited.astype(bool)
            reached += int(np.any(limited & ((data.ten_length < low) | (data.ten_length > high))))
    if name == "tendon_limits":
        assert reached > 0, "the scenarios must drive some tendon into its limit"
