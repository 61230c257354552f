"""The flexible example vehicle, examples/flexible_spacecraft/ (docs/flexible.md,
"The example vehicle"; issue 49, item 6 and the rigid limit).

A bus with two solar arrays on drive hinges and a boom, each appendage
flexible with 4 modes that CalculiX and the converter made from meshes
python -m nudyn_validation.flexible_example writes. Checked here: the files
in examples/ are what the generator makes today; with the modes frozen (the
same nodes, no modes) nudyn's FMU follows MuJoCo's rigid vehicle (the same
MJCF) number for number; with the modes, the drives' torques excite them
and the vehicle's momentum stays what it was (internal torques only)."""

from __future__ import annotations

import json
import shutil

import fmpy
import mujoco
import numpy as np
import pytest
from conftest import ROOT
from nudyn_validation import flexible_example

EXAMPLE = ROOT / "examples" / "flexible_spacecraft"
MODEL = EXAMPLE / "flexible_spacecraft.xml"
COMMUNICATION = 0.05
RK4, DOP853 = 1, 3  # the FMU's `method` enumeration (docs/fmi.md)
QVEL0 = [0.1, 0.0, 0.0, 0.05, -0.03, 0.08, 0.1, -0.05]  # bus (linear, angular), drives
QPOS0 = [0, 0, 0, 1, 0, 0, 0, 0.3, -0.2]


def numbers(value):
    """Every number in a JSON value, flattened."""
    if isinstance(value, dict):
        return [x for v in value.values() for x in numbers(v)]
    if isinstance(value, list):
        return [x for v in value for x in numbers(v)]
    return [value] if isinstance(value, (int, float)) and not isinstance(value, bool) else []


def test_the_example_is_what_calculix_and_the_converter_make(nudyn, tmp_path):
    ccx = shutil.which("ccx")
    if ccx is None:
        pytest.fail("ccx not found: install the Debian package calculix-ccx (scripts/setup-test.sh does)")
    made = flexible_example.write_example(tmp_path, nudyn, ccx)
    assert made.read_text() == MODEL.read_text()
    for name in ("array.json", "boom.json"):
        ours, theirs = json.loads((EXAMPLE / name).read_text()), json.loads((tmp_path / name).read_text())
        nodes = np.array(numbers(ours["nodes"])), np.array(numbers(theirs["nodes"]))
        assert nodes[0].shape == nodes[1].shape and np.abs(nodes[0] - nodes[1]).max() <= 1e-9 * np.abs(nodes[1]).max()
        assert len(ours["modes"]) == len(theirs["modes"]) == flexible_example.MODES
        for k, (mode, again) in enumerate(zip(ours["modes"], theirs["modes"])):
            assert mode["frequency"] == pytest.approx(again["frequency"], rel=1e-9), (name, k)
            # A mode's sign is the eigensolver's choice.
            shape, shape_again = np.array(mode["shape"]), np.array(again["shape"])
            sign = np.sign(np.vdot(shape, shape_again))
            assert np.abs(shape - sign * shape_again).max() <= 1e-6 * np.abs(shape).max(), (name, k)


def ctrl_schedule(steps: int) -> np.ndarray:
    """Drive torques (N m), constant over each communication step."""
    return np.random.default_rng(49).uniform(-2.0, 2.0, size=(steps, 2))


def run_fmu(fmu, nu0, theta0, stop, method, max_step, tolerance, outputs):
    steps = round(stop / COMMUNICATION)
    ctrl = ctrl_schedule(steps)
    times = np.arange(steps) * COMMUNICATION
    signals = np.array([(t, *c) for t, c in zip(times, ctrl)] + [(stop, *ctrl[-1])],
                       dtype=[("time", np.float64), ("ctrl[1]", np.float64), ("ctrl[2]", np.float64)])
    start = {f"theta[{k + 1}]": v for k, v in enumerate(theta0)}
    start.update({f"nu[{k + 1}]": v for k, v in enumerate(nu0)})
    start.update({"method": method, "max_step": max_step, "tolerance": tolerance})
    return fmpy.simulate_fmu(fmu, stop_time=stop, output_interval=COMMUNICATION, start_values=start,
                             input=signals, output=outputs)


def nu_of(cli, model, theta, qvel):
    return json.loads(cli.run("eval", model, stdin=json.dumps({"theta": theta, "qvel": qvel})))["nu"]


def test_with_the_modes_frozen_the_fmu_follows_mujocos_rigid_vehicle(cli, tmp_path):
    """The done-when's rigid limit: the modal files with their nodes and no
    modes (nudyn's rigid model: the nodes make up the <inertial>), RK4 at
    1e-4 s on both sides, 5 s, the bus tumbling, random drive torques."""
    for name in ("array.json", "boom.json"):
        modal = json.loads((EXAMPLE / name).read_text())
        modal["modes"] = []
        (tmp_path / name).write_text(json.dumps(modal))
    shutil.copy(MODEL, tmp_path / MODEL.name)
    model = tmp_path / MODEL.name
    stop = 5.0
    fmu = cli.export(model, tmp_path / "rigid.fmu")
    nu0 = nu_of(cli, model, QPOS0, QVEL0)
    theta_names = [f"theta[{k}]" for k in range(1, 10)]
    result = run_fmu(fmu, nu0, QPOS0, stop, RK4, 1e-4, 1e-6, theta_names)

    rigid = mujoco.MjModel.from_xml_path(str(MODEL))
    rigid.opt.integrator, rigid.opt.timestep = mujoco.mjtIntegrator.mjINT_RK4, 1e-4
    data = mujoco.MjData(rigid)
    data.qpos[:], data.qvel[:] = QPOS0, QVEL0
    trajectory = [data.qpos.copy()]
    for ctrl in ctrl_schedule(round(stop / COMMUNICATION)):
        data.ctrl[:] = ctrl
        mujoco.mj_step(rigid, data, nstep=round(COMMUNICATION / rigid.opt.timestep))
        trajectory.append(data.qpos.copy())
    ours = np.column_stack([result[n] for n in theta_names])
    difference = np.abs(ours - np.array(trajectory)).max()
    print(f"rigid limit: largest qpos difference from MuJoCo over {stop} s: {difference:.2e}")
    assert np.abs(ours[-1, 7:] - ours[0, 7:]).max() > 0.1, "the drives must turn"
    assert difference < 1e-9, difference


def test_the_drives_excite_the_modes_and_the_momentum_stays(cli, tmp_path):
    """With the modes: 2 s of random drive torques (internal), dop853 at
    1e-10: the modes move (strain energy), the momentum about the world
    origin stays within 1e-8 of its start, and the bus turns otherwise than
    the rigid vehicle's."""
    stop = 2.0
    fmu = cli.export(MODEL, tmp_path / "flexible.fmu", outputs=["momentum", "modal_strain_energy"])
    theta0 = QPOS0 + [0.0] * 12
    nu0 = nu_of(cli, MODEL, theta0, QVEL0 + [0.0] * 12)
    outputs = [f"momentum[{k}]" for k in range(1, 7)] + ["modal_strain_energy"] + [f"theta[{k}]" for k in range(1, 22)]
    result = run_fmu(fmu, nu0, theta0, stop, DOP853, 0.0, 1e-10, outputs)
    momentum = np.column_stack([result[f"momentum[{k}]"] for k in range(1, 7)])
    drift = np.abs(momentum - momentum[0]).max() / np.abs(momentum[0]).max()
    eta = np.column_stack([result[f"theta[{k}]"] for k in range(10, 22)])
    print(f"momentum drift {drift:.2e}, largest strain energy {result['modal_strain_energy'].max():.3e} J, "
          f"largest |eta| {np.abs(eta).max():.3e}")
    assert drift < 1e-8, drift
    assert result["modal_strain_energy"].max() > 1e-6
    assert np.abs(eta).max() > 1e-4
