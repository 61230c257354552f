"""Cost of one evaluation of the dynamics: nudyn's ν̇ beside MuJoCo's
pipelines (timed natively in one process by `nudyn-bench eval-cost`), and
Pinocchio's ABA (timed from Python, call overhead included and measured)."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from nudyn_driver.cli import run_json

from .vehicles import Vehicle, mujoco_library


def eval_cost(bench: Path, vehicle: Vehicle, repetitions: int, batch_ms: float, shortcuts: bool, dense: bool) -> dict:
    """`nudyn-bench eval-cost`: ns per call of each case, per repetition
    (MuJoCo's only when the vehicle has a MuJoCo model)."""
    cmd = [
        str(bench), "eval-cost", str(vehicle.path), "--state", str(vehicle.state_path),
        "--repetitions", str(repetitions), "--batch-ms", str(batch_ms),
    ]
    if vehicle.mujoco_path is not None:
        cmd += ["--mujoco-lib", str(mujoco_library()), "--mujoco-model", str(vehicle.mujoco_path)]
    if shortcuts:
        cmd.append("--shortcuts")
    if dense:
        cmd.append("--dense")
    return run_json(cmd)


def _time_calls(call, repetitions: int, batch_s: float) -> list[float]:
    """ns per call, one entry per repetition of a batch of about batch_s."""
    calls = 1
    while True:
        start = time.perf_counter()
        for _ in range(calls):
            call()
        if time.perf_counter() - start >= batch_s:
            break
        calls *= 2
    times = []
    for _ in range(repetitions):
        start = time.perf_counter()
        for _ in range(calls):
            call()
        times.append((time.perf_counter() - start) / calls * 1e9)
    return times


def pinocchio_model(vehicle: Vehicle):
    """(Pinocchio's model of the MJCF file or None, why not, the relative
    difference of the mass matrices): it converts when nq and nv agree and
    the mass matrix of the joints past the base is within 1e-2 of MuJoCo's
    at the state's pose."""
    import mujoco
    import pinocchio as pin

    try:
        model = pin.buildModelFromMJCF(str(vehicle.path))
    except Exception as error:  # the parser's own exception types vary
        return None, f"Pinocchio cannot read it: {error}", None
    reference = vehicle.model
    if model.nv != reference.nv or model.nq != reference.nq:
        return None, f"Pinocchio has nq, nv = {model.nq}, {model.nv}; MuJoCo {reference.nq}, {reference.nv}", None
    q = pinocchio_configuration(model, reference, vehicle.qpos)
    pin_m = pin.crba(model, model.createData(), q)
    pin_m = np.triu(pin_m) + np.triu(pin_m, 1).T
    data = mujoco.MjData(reference)
    data.qpos[:] = vehicle.qpos
    mujoco.mj_fwdPosition(reference, data)
    mj_m = np.zeros((reference.nv, reference.nv))
    mujoco.mj_fullM(reference, data, mj_m)
    base = 6 if _free_base(reference) else 0
    difference = float(np.abs(pin_m[base:, base:] - mj_m[base:, base:]).max() / np.abs(mj_m).max())
    # Small differences come from inertias Pinocchio's parser computes
    # otherwise (capsule geoms); they do not change what ABA costs.
    if difference > 1e-2:
        return None, f"Pinocchio's mass matrix differs from MuJoCo's by {difference:.1e} (relative)", difference
    return model, None, difference


def _free_base(model) -> bool:
    import mujoco

    return model.njnt > 0 and model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE


def pinocchio_configuration(model, reference, qpos) -> np.ndarray:
    """MuJoCo's qpos in Pinocchio's order: a free joint's quaternion is
    (x, y, z, w) there, and hinges and slides count from `ref`."""
    import mujoco

    q = np.array(qpos, float)
    for j in range(reference.njnt):
        a = reference.jnt_qposadr[j]
        kind = reference.jnt_type[j]
        if kind == mujoco.mjtJoint.mjJNT_FREE:
            q[a + 3 : a + 7] = np.roll(qpos[a + 3 : a + 7], -1)
        elif kind == mujoco.mjtJoint.mjJNT_BALL:
            q[a : a + 4] = np.roll(qpos[a : a + 4], -1)
        else:
            q[a] = qpos[a] - reference.qpos0[a]
    return q


def pinocchio_aba(vehicle: Vehicle, repetitions: int, batch_s: float) -> dict:
    """ns per `pin.aba` call from Python at the vehicle's state, and the
    same for a one-hinge model: the floor of a Python call into Pinocchio."""
    import pinocchio as pin

    model, problem, difference = pinocchio_model(vehicle)
    if model is None:
        return {"converts": False, "problem": problem}
    data = model.createData()
    q = pinocchio_configuration(model, vehicle.model, vehicle.qpos)
    v = np.array(vehicle.qvel, float)
    tau = np.zeros(model.nv)
    times = _time_calls(lambda: pin.aba(model, data, q, v, tau), repetitions, batch_s)
    one = pin.Model()
    joint = one.addJoint(0, pin.JointModelRY(), pin.SE3.Identity(), "hinge")
    one.appendBodyToJoint(joint, pin.Inertia.FromSphere(1.0, 0.1), pin.SE3.Identity())
    one_data = one.createData()
    q1, v1, tau1 = np.zeros(1), np.ones(1), np.zeros(1)
    floor = _time_calls(lambda: pin.aba(one, one_data, q1, v1, tau1), repetitions, batch_s)
    return {"converts": True, "mass_matrix_difference": difference, "nanoseconds": times, "one_hinge_nanoseconds": floor}


def eval_cost_side_by_side(bench: Path, vehicles: list[Vehicle], repetitions: int, batch_ms: float) -> list[dict]:
    """`nudyn-bench eval-cost-side-by-side`: ns per ν̇ evaluation of each
    vehicle, per repetition, the vehicles timed in turn within each repetition."""
    cmd = [str(bench), "eval-cost-side-by-side", "--repetitions", str(repetitions), "--batch-ms", str(batch_ms)]
    for vehicle in vehicles:
        cmd += ["--model", str(vehicle.path), "--state", str(vehicle.state_path)]
    return run_json(cmd)
