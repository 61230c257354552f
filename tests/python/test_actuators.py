"""Actuators in `nudyn eval` and `nudyn describe` against MuJoCo 4.0.

The fixtures in tests/fixtures/actuators/ and the examples with actuators
cover every kind nudyn models (motor, position, velocity, damper, general
with fixed or affine gain and bias), transmission (joint and jointinparent
on hinge, slide, ball and free joints; site with and without refsite, on
bodies and on the world), gear, clamping rule (ctrlrange with ctrllimited
and autolimits, forcerange, joint actuatorfrcrange, clampctrl, disabled
groups and actuation) and default-class rule. For random states and ctrl
(inside and beyond the ranges, and beyond one turn on rotations) nudyn must
give MuJoCo's d.actuator_length, d.actuator_velocity, d.actuator_force and
d.qfrc_actuator; the O(N) eps of the actuators must equal l J^T f computed
densely from MuJoCo's mass matrix (mj_fullM, factored here) and moment arms
(d.actuator_moment); and nu_dot with ctrl must be MuJoCo's with the same
generalized force applied. The compiled parameters (gain, bias, gear,
ranges) must be MuJoCo's, for the fixtures and for random default classes.
"""

from __future__ import annotations

import json
import subprocess
import zlib

import mujoco
import numpy as np
import pytest

from conftest import EXAMPLES, ROOT, run_eval
from nudyn_validation.mujoco_reference import Reference, load_model, rel_err

FIXTURES = sorted((ROOT / "tests" / "fixtures" / "actuators").glob("*.xml"))
# With activation states (act at 0 here; test_activation.py moves it).
ACTIVATED = sorted((ROOT / "tests" / "fixtures" / "activation").glob("*.xml"))
ACTUATED = FIXTURES + ACTIVATED + [p for p in EXAMPLES if "<actuator" in p.read_text()]
N_STATES = 6
ACTUATOR_KEYS = ["actuator_length", "actuator_velocity", "actuator_force", "qfrc_actuator", "eps_actuator"]


def random_ctrl(model: mujoco.MjModel, rng: np.random.Generator) -> np.ndarray:
    """ctrl inside and beyond each limited range (half a span either side),
    and up to 3 turns for the unlimited ones (setpoints wrap on rotations)."""
    ctrl = rng.uniform(-3 * np.pi, 3 * np.pi, model.nu)
    for i in range(model.nu):
        if model.actuator_ctrllimited[i]:
            low, high = model.actuator_ctrlrange[i]
            ctrl[i] = rng.uniform(low - 0.5 * (high - low), high + 0.5 * (high - low))
    return ctrl


def dense_moment(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """MuJoCo's moment arms J (nu x nv), dense."""
    moment = np.zeros((model.nu, model.nv))
    mujoco.mju_sparse2dense(moment, data.actuator_moment, data.moment_rownnz, data.moment_rowadr, data.moment_colind)
    return moment


def joint_clamped(model: mujoco.MjModel, torque: np.ndarray) -> np.ndarray:
    """The total actuator force clamped at the joints with actuatorfrcrange."""
    out = torque.copy()
    for j in range(model.njnt):
        if model.jnt_actfrclimited[j]:
            dof = model.jnt_dofadr[j]
            out[dof] = np.clip(out[dof], *model.jnt_actfrcrange[j])
    return out


class ActuatedRun:
    """Random states and ctrl for one file, MuJoCo's actuators there, and
    one `nudyn eval` call with all of them."""

    def __init__(self, path, nudyn):
        self.path = path
        self.ref = Reference.from_file(path)  # actuators off: nu_dot under a given T
        self.model = load_model(path)
        data = mujoco.MjData(self.model)
        rng = np.random.default_rng(zlib.crc32(path.stem.encode()))
        self.cases = []
        for _ in range(N_STATES):
            qpos, qvel, _ = self.ref.random_state(rng)
            ctrl = random_ctrl(self.model, rng)
            mujoco.mj_resetData(self.model, data)
            data.qpos[:], data.qvel[:], data.ctrl[:] = qpos, qvel, ctrl
            mujoco.mj_forward(self.model, data)
            case = {key: getattr(data, key).copy() for key in ACTUATOR_KEYS[:-1]}
            case.update(qpos=qpos, qvel=qvel, ctrl=ctrl, moment=dense_moment(self.model, data))
            self.cases.append(case)
        requests = [{"theta": c["qpos"].tolist(), "qvel": c["qvel"].tolist(), "ctrl": c["ctrl"].tolist()} for c in self.cases]
        self.result = run_eval(nudyn, path, json.dumps(requests))
        # Every numeric field; the constraint rows are records (test_constraints.py checks them).
        self.outputs = [{k: np.asarray(v, float) for k, v in o.items() if k != "constraint_rows"} for o in self.result.json()]


@pytest.fixture(scope="module", params=ACTUATED, ids=[p.stem for p in ACTUATED])
def run(request, nudyn):
    return ActuatedRun(request.param, nudyn)


def check(what, run, i, err, tol):
    assert err <= tol, f"{run.path.stem} state {i}: {what} off by {err:.3e} (tolerance {tol:g})"


def test_every_fixture_has_actuators_that_mujoco_loads(run):
    assert run.model.nu > 0 and len(run.outputs) == N_STATES
    for out in run.outputs:
        for key in ACTUATOR_KEYS:
            size = run.model.nu if key.startswith("actuator") else run.model.nv
            assert out[key].shape == (size,), f"{key}: shape {out[key].shape}"


@pytest.mark.parametrize("key", ACTUATOR_KEYS[:-1])
def test_transmission_force_and_generalized_force_are_mujocos(run, key):
    for i, (case, out) in enumerate(zip(run.cases, run.outputs)):
        check(key, run, i, rel_err(out[key], case[key]), 1e-10)


def test_eps_of_the_actuators_is_l_times_dense_jt_f(run):
    for i, (case, out) in enumerate(zip(run.cases, run.outputs)):
        torque = joint_clamped(run.model, case["moment"].T @ case["actuator_force"])
        check("J^T f (clamped at the joints) vs MuJoCo's qfrc_actuator", run, i, rel_err(torque, case["qfrc_actuator"]), 1e-10)
        eps = np.linalg.solve(run.ref.m_upper(case["qpos"]), torque)
        check("eps_actuator = m^-1 J^T f", run, i, rel_err(out["eps_actuator"], eps), 1e-9)


def test_nu_dot_includes_the_actuators(run):
    for i, (case, out) in enumerate(zip(run.cases, run.outputs)):
        expected = run.ref.nu_dot(case["qpos"], case["qvel"], case["qfrc_actuator"])
        check("nu_dot with ctrl", run, i, rel_err(out["nu_dot"], expected), 1e-6)


def test_without_ctrl_there_are_no_actuator_outputs(nudyn):
    path = FIXTURES[0]
    ref = Reference.from_file(path)
    qpos, qvel, _ = ref.random_state(np.random.default_rng(1))
    out = run_eval(nudyn, path, json.dumps({"theta": qpos.tolist(), "qvel": qvel.tolist()})).json()
    assert not [k for k in ACTUATOR_KEYS if k in out], sorted(out)
    assert rel_err(out["nu_dot"], ref.nu_dot(qpos, qvel)) <= 1e-6


@pytest.mark.parametrize("flag, actuators", [("", True), ('<flag actuation="disable"/>', True), ("", False)])
def test_a_force_range_without_zero_binds_only_while_actuators_act(nudyn, tmp_path, flag, actuators):
    """actuatorfrcrange="0.5 1" moves a zero actuator force to 0.5 while an
    actuator acts; with actuation disabled or no actuator at all MuJoCo
    returns before the clamp, and the joint takes no force."""
    motor = '<actuator><motor joint="j"/></actuator>' if actuators else ""
    path = tmp_path / "range_without_zero.xml"
    path.write_text(f"""<mujoco><option>{flag}</option><worldbody><body>
  <joint name="j" axis="0 1 0" actuatorfrcrange="0.5 1"/><geom size="0.1" pos="0 0 -1"/>
</body></worldbody>{motor}</mujoco>""")
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    request = {"theta": [0.0], "qvel": [0.0], **({"ctrl": [0.0]} if actuators else {})}
    out = run_eval(nudyn, path, json.dumps(request)).json()
    assert abs(out["qacc"][0] - data.qacc[0]) <= 1e-15, (out["qacc"], data.qacc)
    assert data.qacc[0] != 0.0 if actuators and not flag else data.qacc[0] == 0.0


def test_ctrl_of_the_wrong_length_is_refused(nudyn):
    path = FIXTURES[0]
    model = mujoco.MjModel.from_xml_path(str(path))
    request = {"theta": model.qpos0.tolist(), "qvel": [0.0] * model.nv, "ctrl": [0.0] * (model.nu - 1)}
    result = run_eval(nudyn, path, json.dumps(request))
    assert result.returncode == 1 and f"ctrl has {model.nu - 1} entries, expected {model.nu}" in result.stderr, (
        result.describe()
    )


# ---------------------------------------------------------------------- #
# compiled parameters
# ---------------------------------------------------------------------- #
TRANSMISSIONS = {
    int(mujoco.mjtTrn.mjTRN_JOINT): "joint",
    int(mujoco.mjtTrn.mjTRN_JOINTINPARENT): "jointinparent",
    int(mujoco.mjtTrn.mjTRN_SITE): "site",
}


def describe(nudyn, path_or_xml, tmp_path=None):
    """`nudyn describe --json` of a file, or of XML text written to tmp_path."""
    path = path_or_xml
    if tmp_path is not None:
        path = tmp_path / "model.xml"
        path.write_text(path_or_xml)
    proc = subprocess.run([str(nudyn), "describe", str(path), "--json"], capture_output=True, text=True)
    return proc, (json.loads(proc.stdout) if proc.returncode == 0 else None)


def assert_same_actuators(described, m: mujoco.MjModel, context: str):
    assert len(described["actuators"]) == m.nu, context
    for i, a in enumerate(described["actuators"]):
        where = f"{context}, actuator {i}"
        assert a["name"] == mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i), where
        assert a["transmission"] == TRANSMISSIONS[int(m.actuator_trntype[i])], where
        assert a["gaintype"] == ["fixed", "affine"][int(m.actuator_gaintype[i])], where
        assert a["biastype"] == ["none", "affine"][int(m.actuator_biastype[i])], where
        np.testing.assert_allclose(a["gear"], m.actuator_gear[i], rtol=0, atol=1e-15, err_msg=where)
        np.testing.assert_allclose(a["gainprm"], m.actuator_gainprm[i, :3], rtol=1e-12, atol=1e-15, err_msg=where)
        np.testing.assert_allclose(a["biasprm"], m.actuator_biasprm[i, :3], rtol=1e-12, atol=1e-15, err_msg=where)
        for key, limited, bounds in [
            ("ctrlrange", m.actuator_ctrllimited, m.actuator_ctrlrange),
            ("forcerange", m.actuator_forcelimited, m.actuator_forcerange),
        ]:
            if limited[i]:
                np.testing.assert_allclose(a[key], bounds[i], rtol=1e-15, atol=1e-15, err_msg=f"{where}: {key}")
            else:
                assert a[key] is None, f"{where}: {key} {a[key]} but MuJoCo does not limit it"
        assert_same_activation(a.get("activation"), m, i, where)


DYNAMICS_TYPES = {
    int(mujoco.mjtDyn.mjDYN_NONE): None,
    int(mujoco.mjtDyn.mjDYN_INTEGRATOR): "integrator",
    int(mujoco.mjtDyn.mjDYN_FILTER): "filter",
    int(mujoco.mjtDyn.mjDYN_FILTEREXACT): "filterexact",
}


def assert_same_activation(activation, m: mujoco.MjModel, i: int, where: str):
    """`describe --json`'s activation of actuator i against MuJoCo's dyntype,
    dynprm[0], actlimited and actrange, and actearly."""
    kind = DYNAMICS_TYPES[int(m.actuator_dyntype[i])]
    if kind is None:
        assert activation is None, f"{where}: an activation {activation} where MuJoCo has none"
        return
    assert activation is not None and activation["kind"] == kind, f"{where}: {activation} but MuJoCo's is {kind}"
    np.testing.assert_allclose(activation["time_constant"], m.actuator_dynprm[i, 0], rtol=1e-15, err_msg=where)
    if m.actuator_actlimited[i]:
        np.testing.assert_allclose(activation["range"], m.actuator_actrange[i], rtol=1e-15, atol=1e-15, err_msg=where)
    else:
        assert activation["range"] is None, f"{where}: actrange {activation['range']} but MuJoCo does not limit act"
    assert activation["early"] == bool(m.actuator_actearly[i]), where


@pytest.mark.parametrize("path", ACTUATED, ids=[p.stem for p in ACTUATED])
def test_compiled_actuators_are_mujocos(nudyn, path):
    proc, described = describe(nudyn, path)
    assert proc.returncode == 0, proc.stderr
    assert_same_actuators(described, mujoco.MjModel.from_xml_path(str(path)), path.stem)


def test_describe_lists_the_actuators_in_ctrl_order(nudyn):
    proc = subprocess.run([str(nudyn), "describe", str(FIXTURES[0])], capture_output=True, text=True)
    m = mujoco.MjModel.from_xml_path(str(FIXTURES[0]))
    lines = proc.stdout.splitlines()
    header = lines.index(f"{m.nu} actuators (ctrl order)")
    for i, line in enumerate(lines[header + 2 : header + 2 + m.nu]):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i) or "-"
        assert line.split()[:2] == [str(i + 1), name], line


# Random default classes: kinds written in defaults and on elements, with
# and without their own parameters, nested classes, and the mechanical
# attributes of any default; MuJoCo's compiled values are the reference.
SHORTCUT_PARAMETERS = {
    "motor": [],
    "position": ["kp", "kv", "dampratio"],
    "velocity": ["kv"],
    "damper": ["kv"],
    "intvelocity": ["kp", "kv", "dampratio"],
    "cylinder": ["timeconst", "area", "diameter"],
    "general": [],
}


def random_actuator_attributes(rng, kind, in_default):
    attributes = {}
    if rng.random() < 0.3:
        attributes["gear"] = " ".join(f"{x:.3g}" for x in rng.uniform(-2, 2, rng.integers(1, 4)))
    if rng.random() < 0.3:
        attributes["forcerange"] = "-5 4"
    if kind != "damper" and rng.random() < 0.2:
        attributes["ctrllimited"] = str(rng.random() < 0.5).lower()
    # A damper limits ctrl to a non-negative range, which its class's other
    # elements inherit: mostly give one.
    if rng.random() < (0.9 if kind == "damper" else 0.3):
        attributes["ctrlrange"] = "0.1 2" if kind == "damper" or rng.random() < 0.5 else "-1 1"
    parameters = SHORTCUT_PARAMETERS[kind]
    for name in parameters:
        if rng.random() < 0.4:
            attributes[name] = f"{rng.uniform(0.1, 30):.3g}"
    if "kv" in attributes and "dampratio" in attributes:
        del attributes["dampratio"]
    if kind == "intvelocity":
        # The range of its integrated command, given or its joint's.
        if rng.random() < 0.3:
            attributes["actrange"] = "-0.5 0.7"
        elif not in_default and rng.random() < 0.3:
            attributes["inheritrange"] = f"{rng.uniform(0.5, 1.5):.3g}"
    if kind == "cylinder" and rng.random() < 0.4:
        attributes["bias"] = " ".join(f"{x:.3g}" for x in rng.uniform(-5, 5, 3))
    if kind == "general":
        if rng.random() < 0.5:
            attributes["gaintype"] = rng.choice(["fixed", "affine"])
        if rng.random() < 0.5:
            attributes["biastype"] = rng.choice(["none", "affine"])
        if rng.random() < 0.5:
            attributes["gainprm"] = " ".join(f"{x:.3g}" for x in rng.uniform(-5, 5, rng.integers(1, 4)))
        if rng.random() < 0.5:
            attributes["biasprm"] = " ".join(f"{x:.3g}" for x in rng.uniform(-5, 5, rng.integers(1, 4)))
    return " ".join(f'{k}="{v}"' for k, v in attributes.items())


def random_defaults_model(rng) -> str:
    kinds = list(SHORTCUT_PARAMETERS)

    def default_body(depth):
        children = "".join(
            f"<{kind} {random_actuator_attributes(rng, kind, True)}/>"
            for kind in rng.choice(kinds, rng.integers(0, 3), replace=False)
        )
        return children

    classes = ["c0", "c1", "c2", "c3"]
    defaults = (
        f'<default>{default_body(0)}'
        f'<default class="c0">{default_body(1)}<default class="c1">{default_body(2)}</default></default>'
        f'<default class="c2">{default_body(1)}<default class="c3">{default_body(2)}</default></default>'
        "</default>"
    )
    actuators = "".join(
        f'<{kind} joint="{rng.choice(["h", "s"])}" class="{rng.choice(classes + ["main"])}" '
        f"{random_actuator_attributes(rng, kind, False)}/>"
        for kind in rng.choice(kinds, 8)
    )
    return f"""<mujoco>
  {defaults}
  <worldbody>
    <body><joint name="h" axis="0 1 0" range="-1 1.5"/><geom size="0.1"/>
      <body pos="0.3 0 0"><joint name="s" type="slide" range="-0.2 0.3"/><geom size="0.1"/></body>
    </body>
  </worldbody>
  <actuator>{actuators}</actuator>
</mujoco>"""


def test_random_default_classes_compile_as_in_mujoco(nudyn, tmp_path):
    rng = np.random.default_rng(4)
    compared = refused = 0
    for trial in range(200):
        xml = random_defaults_model(rng)
        proc, described = describe(nudyn, xml, tmp_path)
        try:
            m = mujoco.MjModel.from_xml_string(xml)
        except ValueError as error:
            assert proc.returncode != 0, f"trial {trial}: MuJoCo refuses ({error}) but nudyn imports\n{xml}"
            refused += 1
            continue
        if np.isnan(m.actuator_biasprm).any():
            # A damping ratio with a negative kp: MuJoCo's damping is NaN, nudyn says why.
            assert "dampratio needs kp >= 0" in proc.stderr, f"trial {trial}: {proc.stderr}\n{xml}"
            refused += 1
            continue
        assert proc.returncode == 0, f"trial {trial}: MuJoCo compiles but nudyn refuses: {proc.stderr}\n{xml}"
        assert_same_actuators(described, m, f"trial {trial}\n{xml}")
        compared += 1
    assert compared >= 100 and refused >= 10, (compared, refused)
