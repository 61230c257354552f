"""`nudyn linearize` against MuJoCo.

The exact derivatives behind it (src/dynamics/derivatives.rs) are checked
here against MuJoCo's own dynamics, on the example vehicles that have
neither actuators nor constraint forces (the ones the derivatives cover
so far), at random states:

- ∂θ̈/∂(δq, θ̇, T), A's and B's lower halves, against central differences of
  mj_forward (δq moved by mj_integratePos, as MuJoCo's mjd_transitionFD
  does), with one Richardson step: within 1e-6 relative;
- ∂θ̈/∂T against MuJoCo's M⁻¹ (mj_solveM): to round-off;
- on the constrained fixtures (equality rows, friction loss, limits, tendon
  rows), ∂θ̈/∂(δq, θ̇, ctrl) at states whose differences stay in one
  constraint mode, against MuJoCo's differences with its solver run to
  round-off: within 1e-6 relative;
- with --step H at an equilibrium, the zero-order hold's A_d against the
  transition matrix of one step of MuJoCo's RK4 at step H, differenced
  centrally as mjd_transitionFD does (which refuses RK4 in MuJoCo 4.0):
  the difference is RK4's own truncation against the exact hold (measured
  figures in docs/linearization.md).
"""

from __future__ import annotations

import json
import os
import subprocess
import zlib

import mujoco
import numpy as np
import pytest

from conftest import EXAMPLES, ROOT, tangent_jacobian
from nudyn_validation.mujoco_reference import Reference, load_model

# The examples whose dynamics the derivatives cover (no actuators, tendons
# or constraint forces).
COVERED = [p for p in EXAMPLES if p.stem in ("bus_arm7", "chain60", "fixed_rig", "flexible_boom")]
STEP = 1e-3


def linearize(nudyn, path, *args):
    proc = subprocess.run([str(nudyn), "linearize", str(path), *args], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout), proc.stderr


def listed(values):
    return ",".join(repr(float(v)) for v in values)


def relative(a, b):
    return np.abs(a - b).max() / max(1.0, np.abs(b).max())


def mujoco_qacc_jacobians(ref: Reference, qpos, qvel, torque):
    """∂θ̈/∂(δq, θ̇, T) by central differences of mj_forward."""
    qacc = lambda d: d.qacc  # noqa: E731
    return tuple(tangent_jacobian(ref, qpos, qvel, torque, qacc, which, h)
                 for which, h in ((0, STEP), (1, STEP), (2, STEP * 100)))


@pytest.fixture(scope="module", params=COVERED, ids=[p.stem for p in COVERED])
def vehicle(request):
    return request.param


def test_the_continuous_pair_agrees_with_differences_of_mujoco(nudyn, vehicle):
    ref = Reference.from_file(vehicle)
    rng = np.random.default_rng(zlib.crc32(vehicle.stem.encode()))
    for _ in range(3):
        qpos, qvel, torque = ref.random_state(rng)
        out, _ = linearize(nudyn, vehicle, "--qpos", listed(qpos), "--qvel", listed(qvel),
                           "--torque", listed(torque), "--inputs", "torque")
        nv = ref.nv
        a, b = np.array(out["A"]), np.array(out["B"])
        by_q, by_v, by_t = mujoco_qacc_jacobians(ref, qpos, qvel, torque)
        for what, ours, theirs in [("dq", a[nv:, :nv], by_q), ("qvel", a[nv:, nv:], by_v), ("T", b[nv:], by_t)]:
            print(f"{vehicle.stem}: ∂qacc/∂{what} {relative(ours, theirs):.1e} from MuJoCo's differences")
            assert relative(ours, theirs) < 1e-6, f"∂qacc/∂{what}: {relative(ours, theirs):.2e}"
        ref.forward(qpos, qvel, torque)
        inverse = np.zeros((nv, nv))
        mujoco.mj_solveM(ref.model, ref.data, inverse, np.eye(nv))
        print(f"{vehicle.stem}: ∂qacc/∂T {relative(b[nv:], inverse):.1e} from M⁻¹")
        assert relative(b[nv:], inverse) < 1e-10, f"∂qacc/∂T vs M⁻¹: {relative(b[nv:], inverse):.2e}"
        assert np.array_equal(a[:nv, nv:], np.eye(nv)) and not b[:nv].any()


def rk4_transition(ref: Reference, qpos, qvel, torque, h):
    """∂x⁺/∂x of one step of MuJoCo's RK4 (x = (δq, θ̇), δq by
    mj_integratePos and mj_differentiatePos), by central differences as
    mjd_transitionFD (flg_centered) takes them: MuJoCo 4.0's mjd_transitionFD
    refuses RK4 ("RK4 integrator is not supported")."""
    m, nv = ref.model, ref.nv
    m.opt.integrator = int(mujoco.mjtIntegrator.mjINT_RK4)
    d = ref.data

    def step(dx):
        mujoco.mj_resetData(m, d)
        d.qpos[:] = qpos
        mujoco.mj_integratePos(m, d.qpos, dx[:nv], 1.0)
        d.qvel[:] = qvel + dx[nv:]
        d.qfrc_applied[:] = torque
        mujoco.mj_step(m, d)
        return d.qpos.copy(), d.qvel.copy()

    transition = np.zeros((2 * nv, 2 * nv))
    eps = 1e-6
    for k in range(2 * nv):
        dx = np.zeros(2 * nv)
        dx[k] = eps
        (qp, vp), (qm, vm) = step(dx), step(-dx)
        position = np.zeros(nv)
        mujoco.mj_differentiatePos(m, position, 2 * eps, qm, qp)
        transition[:nv, k] = position
        transition[nv:, k] = (vp - vm) / (2 * eps)
    return transition


def test_the_zero_order_hold_is_mujocos_rk4_transition_at_an_equilibrium(nudyn, vehicle):
    """At rest with the joint forces that hold the vehicle there (gravity and
    springs balanced), the one-step transition of the nonlinear dynamics is
    e^{AH}, and MuJoCo's RK4 step differs from it by its truncation. (Away
    from an equilibrium the two differ by O(H²): the flow's Jacobian takes
    in how A changes along the motion over the step, the linearization's
    hold does not; docs/linearization.md.)"""
    ref = Reference.from_file(vehicle)
    rng = np.random.default_rng(1 + zlib.crc32(vehicle.stem.encode()))
    qpos, _, _ = ref.random_state(rng)
    qvel = np.zeros(ref.nv)
    d = ref.forward(qpos, qvel)
    holding = d.qfrc_bias - d.qfrc_passive
    assert np.abs(ref.forward(qpos, qvel, holding).qacc).max() < 1e-9
    h = ref.model.opt.timestep
    out, _ = linearize(nudyn, vehicle, "--qpos", listed(qpos), "--qvel", listed(qvel), "--torque", listed(holding),
                       "--inputs", "torque", "--step", repr(h))
    error = relative(np.array(out["Ad"]), rk4_transition(ref, qpos, qvel, holding, h))
    print(f"{vehicle.stem}: Ad vs MuJoCo's RK4 transition at h = {h}: {error:.2e}")
    assert error < 1e-7, f"Ad vs MuJoCo's RK4 transition (h = {h}): {error:.2e}"


def test_npz_holds_the_json_matrices_and_modes_are_printed(nudyn, tmp_path):
    bus = next(p for p in COVERED if p.stem == "bus_arm7")
    npz = tmp_path / "bus.npz"
    out, stderr = linearize(nudyn, bus, "--step", "0.01", "--outputs", "qpos,nu,qacc", "--npz", str(npz))
    arrays = np.load(npz)
    for name in ("A", "B", "C", "D", "Ad", "Bd"):
        assert np.array_equal(arrays[name], np.array(out[name])), name
    nv = len(out["qvel"])
    assert np.array(out["C"]).shape == (3 * nv, 2 * nv) and out["outputs"][nv] == "nu[1]"
    lambdas = arrays["eigenvalues"][:, 0] + 1j * arrays["eigenvalues"][:, 1]
    assert np.allclose(np.sort_complex(lambdas), np.sort_complex(np.linalg.eigvals(arrays["A"])), atol=1e-9)
    assert "frequency (Hz)" in stderr and "damping" in stderr


ACTUATED = [ROOT / "tests/fixtures/actuators/kinds.xml", next(p for p in EXAMPLES if p.stem == "servicer")]


@pytest.mark.parametrize("path", ACTUATED, ids=[p.stem for p in ACTUATED])
def test_the_actuators_inputs_agree_with_differences_of_mujoco(nudyn, path):
    """B for ctrl (every actuator kind, transmission and gain; the servicer's
    thrusters, wheels and servos) and A with the actuators' bias forces, at
    random states clear of the joint limits, ctrl inside its range."""
    ref = Reference(load_model(path), None)
    ref.data = mujoco.MjData(ref.model)
    m = ref.model
    rng = np.random.default_rng(zlib.crc32(path.stem.encode()))
    limited = [j for j in range(m.njnt) if m.jnt_limited[j] and m.jnt_type[j] in (2, 3)]

    def clear(qpos):
        return all(m.jnt_range[j, 0] + 0.05 < qpos[m.jnt_qposadr[j]] < m.jnt_range[j, 1] - 0.05 for j in limited)

    for _ in range(2):
        qpos, qvel, _ = next(s for s in iter(lambda: ref.random_state(rng), None) if clear(s[0]))
        low, high = m.actuator_ctrlrange[:, 0], m.actuator_ctrlrange[:, 1]
        ranged = (m.actuator_ctrllimited == 1) & (low < high)
        ctrl = np.where(ranged, low + (high - low) * rng.uniform(0.2, 0.8, m.nu), rng.uniform(-1, 1, m.nu))
        out, _ = linearize(nudyn, path, "--qpos", listed(qpos), "--qvel", listed(qvel), "--ctrl", listed(ctrl),
                           "--inputs", "ctrl")
        nv = m.nv
        a, b = np.array(out["A"]), np.array(out["B"])
        d = ref.data

        def qacc(dq, dv, du):
            mujoco.mj_resetData(m, d)
            d.qpos[:] = qpos
            mujoco.mj_integratePos(m, d.qpos, dq, 1.0)
            d.qvel[:] = qvel + dv
            d.ctrl[:] = ctrl + du
            mujoco.mj_forward(m, d)
            assert d.nefc == 0, "a constraint row acts"
            return d.qacc.copy()

        def jacobian(which, count, h=1e-4):
            def column(k, h):
                step = [np.zeros(nv), np.zeros(nv), np.zeros(m.nu)]
                step[which] = np.zeros(count)
                step[which][k] = h
                minus = [-x for x in step]
                return (qacc(*step) - qacc(*minus)) / (2 * h)
            return np.column_stack([(4 * column(k, h / 2) - column(k, h)) / 3 for k in range(count)])

        for what, ours, theirs in [("dq", a[nv:, :nv], jacobian(0, nv)), ("qvel", a[nv:, nv:], jacobian(1, nv)),
                                   ("ctrl", b[nv:], jacobian(2, m.nu))]:
            print(f"{path.stem}: ∂qacc/∂{what} {relative(ours, theirs):.1e} from MuJoCo's differences")
            assert relative(ours, theirs) < 1e-6, f"∂qacc/∂{what}: {relative(ours, theirs):.2e}"


def test_a_vector_of_the_wrong_length_is_refused(nudyn):
    wrong = subprocess.run([str(nudyn), "linearize", str(COVERED[0]), "--qvel", "1,2"], capture_output=True, text=True)
    assert wrong.returncode != 0 and "--qvel has 2 values" in wrong.stderr, wrong.stderr


def test_a_keyframe_is_the_point_its_vectors_give(nudyn, tmp_path):
    """--keyframe NAME (or index) linearizes at the key's qpos and qvel, as
    the same values given by --qpos and --qvel do; a flag given beside it
    replaces the key's vector; a missing key is named with those there are."""
    bus = next(p for p in COVERED if p.stem == "bus_arm7")
    ref = Reference.from_file(bus)
    qpos, qvel, _ = ref.random_state(np.random.default_rng(5))
    text = bus.read_text()
    key = f'<keyframe><key name="slewing" qpos="{listed(qpos).replace(",", " ")}" qvel="{listed(qvel).replace(",", " ")}"/></keyframe>'
    keyed = tmp_path / "bus_arm7.xml"
    keyed.write_text(text.replace("</mujoco>", key + "\n</mujoco>"))
    explicit, _ = linearize(nudyn, bus, "--qpos", listed(qpos), "--qvel", listed(qvel))
    by_name, _ = linearize(nudyn, keyed, "--keyframe", "slewing")
    by_index, _ = linearize(nudyn, keyed, "--keyframe", "0")
    assert by_name == explicit and by_index == explicit
    at_rest, _ = linearize(nudyn, keyed, "--keyframe", "slewing", "--qvel", listed(np.zeros(ref.nv)))
    assert at_rest == linearize(nudyn, bus, "--qpos", listed(qpos))[0]
    proc = subprocess.run([str(nudyn), "linearize", str(keyed), "--keyframe", "home"], capture_output=True, text=True)
    assert proc.returncode != 0
    assert 'the model has no keyframe "home" (its keyframes: "slewing")' in proc.stderr, proc.stderr
    mocap = ROOT / "tests/fixtures/mjcf/mocap.xml"
    proc = subprocess.run([str(nudyn), "linearize", str(mocap), "--keyframe", "start"], capture_output=True, text=True)
    assert proc.returncode != 0
    assert "keyframe start (line 22) places mocap bodies (mpos, mquat)" in proc.stderr, proc.stderr


# Constrained vehicles: equality rows, friction loss and limits (with sides
# active), and tendons' friction, limits and couplings; how far each state's
# dofs are spread about qpos0 (the docked servicer's welds hold at qpos0).
CONSTRAINED = {
    "tests/fixtures/constraints/docked_servicer.xml": 0.05,
    "tests/fixtures/constraints/limited_arm.xml": 0.8,
    "tests/fixtures/constraints/slider_hand.xml": 0.3,
    "tests/fixtures/tendons/tendon_limits.xml": 0.5,
    "tests/fixtures/tendons/tendon_finger.xml": 0.5,
    # MuJoCo's no-slip pass over the friction rows, its decisions (each
    # sweep's clamps, each island's sweeps) those of the point.
    "tests/fixtures/constraints/noslip_trees.xml": 0.3,
    # The tendons' armature (MuJoCo's M with its terms) with a connect, a
    # tendon coupling, friction loss and limits.
    "tests/fixtures/tendons/tendon_armature.xml": 0.3,
    # Tendons without rows: spatial paths wrapped round spheres and
    # cylinders, side sites.
    "tests/fixtures/tendons/tendon_wrap.xml": 0.5,
    "tests/fixtures/tendons/tendon_sidesite.xml": 0.5,
}
CONSTRAINED_STATES = int(os.environ.get("NUDYN_CONSTRAINED_STATES", "4"))


def constrained_jacobians(path, spread, states, seed, nudyn):
    """At `states` random states of `path` whose constraint mode (MuJoCo's
    rows and each row's state: a friction force at a bound or inside, a
    limit's force zero or pushing) is the same at every point the
    differences visit, and whose differences at h and h/2 agree (no
    impedance piece crossed): nudyn linearize's ∂θ̈/∂(δq, θ̇, ctrl) and central
    differences of mj_forward with MuJoCo's solver run to round-off. Yields
    (∂ name, relative difference); states whose differences would cross a
    switch are drawn again."""
    m = load_model(ROOT / path)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(seed)
    nv = m.nv
    done = 0
    while done < states:
        qpos = m.qpos0.copy()
        mujoco.mj_integratePos(m, qpos, rng.normal(0, spread, nv), 1.0)
        qvel = rng.normal(0, 0.3, nv)
        low, high = m.actuator_ctrlrange[:, 0], m.actuator_ctrlrange[:, 1]
        ranged = (m.actuator_ctrllimited == 1) & (low < high)
        ctrl = np.where(ranged, low + (high - low) * rng.uniform(0.2, 0.8, m.nu), rng.uniform(-1, 1, m.nu))

        def forward(dq, dv, du):
            mujoco.mj_resetData(m, d)
            d.qpos[:] = qpos
            mujoco.mj_integratePos(m, d.qpos, dq, 1.0)
            d.qvel[:] = qvel + dv
            d.ctrl[:] = ctrl + du
            mujoco.mj_forward(m, d)
            return d.qacc.copy(), (tuple(d.efc_type[: d.nefc]), tuple(d.efc_state[: d.nefc]))

        _, mode = forward(np.zeros(nv), np.zeros(nv), np.zeros(m.nu))
        smooth = True

        def jacobian(which, count, h=1e-5):
            nonlocal smooth

            def column(k, h):
                nonlocal smooth
                step = [np.zeros(nv), np.zeros(nv), np.zeros(m.nu)]
                step[which][k] = h
                (plus, plus_mode), (minus, minus_mode) = forward(*step), forward(*[-x for x in step])
                smooth &= plus_mode == mode == minus_mode
                return (plus - minus) / (2 * h)

            columns = []
            for k in range(count):
                coarse, fine = column(k, h), column(k, h / 2)
                # A switch MuJoCo's rows do not show (an impedance's piece)
                # shows as differences that disagree at h and h/2.
                smooth &= relative(coarse, fine) < 1e-7
                columns.append((4 * fine - coarse) / 3)
            return np.column_stack(columns) if columns else np.zeros((nv, 0))

        theirs = [jacobian(0, nv), jacobian(1, nv), jacobian(2, m.nu)]
        if not smooth:
            continue
        given_ctrl = ["--ctrl", listed(ctrl)] if m.nu else []
        out, _ = linearize(nudyn, ROOT / path, "--qpos", listed(qpos), "--qvel", listed(qvel), *given_ctrl,
                           "--inputs", "ctrl")
        a, b = np.array(out["A"]), np.array(out["B"])
        ours = [a[nv:, :nv], a[nv:, nv:], b[nv:]]
        done += 1
        yield len(mode[0]), [(what, relative(x, y)) for what, x, y in zip(("dq", "qvel", "ctrl"), ours, theirs)
                             if y.size]


@pytest.mark.parametrize("path", CONSTRAINED, ids=[p.split("/")[-1][:-4] for p in CONSTRAINED])
def test_constrained_vehicles_agree_with_differences_of_mujoco(nudyn, path):
    """The constraint forces' derivatives at the point's constraint mode,
    against MuJoCo's forward dynamics differenced within that mode."""
    for rows, errors in constrained_jacobians(path, CONSTRAINED[path], CONSTRAINED_STATES, zlib.crc32(path.encode()),
                                              nudyn):
        print(f"{path}: {rows} rows, " + ", ".join(f"∂qacc/∂{w} {e:.1e}" for w, e in errors))
        for what, error in errors:
            assert error < 1e-6, f"{path}: ∂qacc/∂{what} {error:.2e} from MuJoCo's differences ({rows} rows)"


# Sensors (`--outputs sensordata`): every kind but the limits' (every_sensor,
# cutoffs and the clock among them), force and torque on welded bodies
# (force_torque), and on the docked servicer force, torque and joint limit
# sensors through welds and a connect, near qpos0 where the welds hold.
SENSED = {
    "tests/fixtures/sensors/every_sensor.xml": 0.3,
    "tests/fixtures/sensors/force_torque.xml": 0.3,
    "tests/fixtures/constraints/docked_servicer.xml": 0.01,
}


@pytest.mark.parametrize("path", SENSED, ids=[p.split("/")[-1][:-4] for p in SENSED])
def test_the_sensors_rows_are_mujocos_transition_c_and_d(nudyn, path):
    """C and D of sensordata (x = (δq, θ̇), u = ctrl) against MuJoCo's
    mjd_transitionFD (centered at step 1e-5, its solver run to round-off), at random
    states near qpos0: within 1e-6 relative to the largest entry, as the
    other comparisons here. A reading held at its cutoff has derivative 0
    in both. (Relative to each row's largest entry the docked servicer's
    pod_mount force and dock torque rows differ by up to 8e-4: MuJoCo's
    differences there grow as 1/h, 4.5e-6 at h = 1e-4, 7.9e-4 at 1e-6,
    the solver's residual on weld forces of 1e5 N, while nudyn's own
    differences agree to 1e-7: tests/all/derivatives.rs.)"""
    m = load_model(ROOT / path)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(zlib.crc32(path.encode()))
    nv, ns = m.nv, m.nsensordata
    for _ in range(2):
        qpos = m.qpos0.copy()
        mujoco.mj_integratePos(m, qpos, rng.normal(0, SENSED[path], nv), 1.0)
        qvel = rng.normal(0, 0.3, nv)
        low, high = m.actuator_ctrlrange[:, 0], m.actuator_ctrlrange[:, 1]
        ranged = (m.actuator_ctrllimited == 1) & (low < high)
        ctrl = np.where(ranged, low + (high - low) * rng.uniform(0.2, 0.8, m.nu), rng.uniform(-1, 1, m.nu))
        mujoco.mj_resetData(m, d)
        d.qpos[:], d.qvel[:], d.ctrl[:] = qpos, qvel, ctrl
        mujoco.mj_forward(m, d)
        a, b = np.zeros((2 * nv, 2 * nv)), np.zeros((2 * nv, m.nu))
        c, dd = np.zeros((ns, 2 * nv)), np.zeros((ns, m.nu))
        # Its step 1e-5: at 1e-6 its differences of the docked servicer's
        # readings from weld forces carry 3e-6 of the solver's residual.
        mujoco.mjd_transitionFD(m, d, 1e-5, 1, a, b, c, dd)
        given_ctrl = ["--ctrl", listed(ctrl)] if m.nu else []
        out, _ = linearize(nudyn, ROOT / path, "--qpos", listed(qpos), "--qvel", listed(qvel), *given_ctrl,
                           "--inputs", "ctrl", "--outputs", "sensordata")
        ours_c, ours_d = np.array(out["C"]), np.array(out["D"]).reshape(ns, m.nu)
        errors = {"C": relative(ours_c, c), "D": relative(ours_d, dd) if m.nu else 0.0}
        print(f"{path}: {d.nefc} rows, sensordata " + ", ".join(f"{k} {e:.1e}" for k, e in errors.items())
              + " from mjd_transitionFD")
        for what, error in errors.items():
            assert error < 1e-6, f"{path}: the sensors' {what} {error:.2e} from MuJoCo's ({d.nefc} rows)"


# Each example's end effector, and bus_arm7 with a tool tip welded to its
# end effector at an offset (a body frame that is not its link's).
TOOL_TIP = '<body name="tool_tip" pos="0.03 -0.02 0.21" euler="10 -25 40"><geom size="0.01" mass="0.1"/></body>'
END_EFFECTORS = [("examples/bus_arm7.xml", "end_effector"), ("examples/servicer.xml", "hand"),
                 ("examples/fixed_rig.xml", "wrist"), ("examples/flexible_boom.xml", "solar_array"),
                 ("tool_tip", "tool_tip")]


@pytest.mark.parametrize("path,body", END_EFFECTORS, ids=[b for _, b in END_EFFECTORS])
def test_the_end_effector_rows_are_mujocos_body_jacobian(nudyn, path, body, tmp_path):
    """`--end-effector BODY`'s six rows of C (its origin in world axes,
    then its turn in its own axes) over δq against MuJoCo's mj_jacBody
    (jacp, and jacr in the body's axes) to 1e-10 relative, and against
    central differences of its pose from mj_forward (conftest's
    tangent_jacobian; the turn by mju_subQuat) to 1e-6; zero over
    θ̇ and in D. The tool tip checks a body welded at an offset to its link."""
    if path == "tool_tip":
        text = (ROOT / "examples/bus_arm7.xml").read_text()
        flange = '<geom type="box" size="0.04 0.06 0.05" pos="0.02 0.01 0.12"/>'
        assert flange in text
        file = tmp_path / "bus_arm7_tool.xml"
        file.write_text(text.replace(flange, flange + TOOL_TIP))
    else:
        file = ROOT / path
    ref = Reference.from_file(file)
    m, d = ref.model, ref.data
    index = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, body)
    rng = np.random.default_rng(zlib.crc32(body.encode()))
    nv = m.nv
    for _ in range(3):
        qpos, qvel, _ = ref.random_state(rng)
        out, _ = linearize(nudyn, file, "--qpos", listed(qpos), "--qvel", listed(qvel), "--outputs", "qvel",
                           "--end-effector", body)
        assert out["outputs"][nv:] == [f"end_effector[{k}]" for k in range(1, 7)]
        c, dd = np.array(out["C"])[nv:], np.array(out["D"])[nv:]
        assert not c[:, nv:].any() and not dd.any()
        ref.forward(qpos, qvel)
        jacp, jacr = np.zeros((3, nv)), np.zeros((3, nv))
        mujoco.mj_jacBody(m, d, jacp, jacr, index)
        analytic = np.vstack([jacp, d.xmat[index].reshape(3, 3).T @ jacr])
        at = d.xquat[index].copy()

        def pose(data):
            turn = np.zeros(3)
            mujoco.mju_subQuat(turn, data.xquat[index], at)
            return np.concatenate([data.xpos[index], turn])

        differences = tangent_jacobian(ref, qpos, qvel, np.zeros(nv), pose, 0, STEP)
        errors = relative(c[:, :nv], analytic), relative(c[:, :nv], differences)
        print(f"{body}: end effector rows {errors[0]:.1e} from mj_jacBody, {errors[1]:.1e} from differences")
        assert errors[0] < 1e-10 and errors[1] < 1e-6, errors


def test_the_end_effector_output_needs_a_body(nudyn):
    for args, message in [(["--outputs", "qpos,end_effector"], "needs --end-effector BODY"),
                          (["--end-effector", "nope"], "no body named 'nope'")]:
        proc = subprocess.run([str(nudyn), "linearize", str(ROOT / "examples/bus_arm7.xml"), *args],
                              capture_output=True, text=True, timeout=60)
        assert proc.returncode != 0 and message in proc.stderr, proc.stderr


def test_activation_states_are_states_of_the_linearization(nudyn):
    """With activation states (tests/fixtures/activation/shortcut_servos.xml:
    MuJoCo's intvelocity integrators and cylinder filters) x is (δq, θ̇,
    act): the rows of θ̈ and act's rate in A, and in B for ctrl, against
    central differences of mj_forward's qacc and act_dot in qpos (moved by
    mj_integratePos), qvel, act and ctrl, with one Richardson step, at a
    random state with act and ctrl inside their ranges: within 1e-6
    relative."""
    path = ROOT / "tests" / "fixtures" / "activation" / "shortcut_servos.xml"
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    nv, na, nu = m.nv, m.na, m.nu
    rng = np.random.default_rng(5)
    qpos = m.qpos0.copy()
    qpos[3:7] = rng.normal(size=4)
    qpos[3:7] /= np.linalg.norm(qpos[3:7])
    qpos[7:] += rng.normal(0, 0.3, m.nq - 7)
    qvel = rng.normal(0, 0.5, nv)
    inside = lambda ranges: np.array([lo + (hi - lo) * rng.uniform(0.3, 0.7) for lo, hi in ranges])
    act = inside([m.actuator_actrange[i] if m.actuator_actlimited[i] else (-0.5, 0.5)
                  for i in range(nu) if m.actuator_dyntype[i] != 0])
    ctrl = inside(m.actuator_ctrlrange)
    linear, _ = linearize(nudyn, path, "--inputs", "ctrl", "--qpos", listed(qpos), "--qvel", listed(qvel),
                          "--act", listed(act), "--ctrl", listed(ctrl))
    assert linear["state"][2 * nv:] == [f"act[{k}]" for k in range(1, na + 1)] and linear["act"] == list(act)
    a, b = np.array(linear["A"]), np.array(linear["B"])
    assert a.shape == (2 * nv + na, 2 * nv + na) and b.shape == (2 * nv + na, nu)

    def rates(x):
        d.qpos[:] = qpos
        mujoco.mj_integratePos(m, d.qpos, x[:nv], 1.0)
        d.qvel[:] = qvel + x[nv:2 * nv]
        d.act[:] = act + x[2 * nv:2 * nv + na]
        d.ctrl[:] = ctrl + x[2 * nv + na:]
        mujoco.mj_forward(m, d)
        return np.concatenate([d.qacc, d.act_dot])

    n = 2 * nv + na + nu
    columns = []
    for k in range(n):
        unit = np.eye(n)[k]
        central = lambda h: (rates(h * unit) - rates(-h * unit)) / (2 * h)
        columns.append((4 * central(STEP / 2) - central(STEP)) / 3)
    theirs = np.column_stack(columns)
    ours = np.hstack([a[nv:], b[nv:]])
    assert relative(ours, theirs) < 1e-6, relative(ours, theirs)
    # act matters: its columns are not zero.
    assert np.abs(a[nv:, 2 * nv:]).max() > 1e-3
