#!/usr/bin/env python3
"""The cost of θ̈'s Jacobian (issue 48's cost item) side by side with
Pinocchio's analytic ABA derivatives and MuJoCo's finite-difference
transition matrices, on the examples Pinocchio can model (the servicer's
rigid tree: nudyn's case carries its actuators at mid-range ctrl, which
Pinocchio, given joint forces only, does not have; `servicer_unactuated`
is the same file with its <actuator> element removed, the same vehicle
on both sides).

Per vehicle and round (rounds interleave the three tools, so that a slow
spell of the shared machine falls on all of them): `nudyn-bench eval-cost`
(its cases interleaved, medians of its batches: θ̈'s Jacobians in closed
form, the dual numbers' ν̇ Jacobian, one ν̇, θ̈), then Pinocchio's
`computeABADerivatives` (∂θ̈/∂(q, v, τ), called from Python) and MuJoCo's
`mjd_transitionFD` (centered; MuJoCo 4.0 refuses RK4 there, so Euler, its
cheapest step), each the best of a few timed loops at one random state.
Python's call costs are given by the same Pinocchio call on a one-hinge
model (`floor`), which the table subtracts from Pinocchio's time. The
median over the rounds is reported.

    .venv/bin/python scripts/bench_derivatives.py [--rounds 3] [--out FILE.json] [VEHICLE ...]
"""

import argparse
import json
import re
import statistics
import subprocess
import sys
import time
import zlib
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
sys.path.insert(0, str(ROOT / "tests" / "python"))

from nudyn_bench.vehicles import prepare  # noqa: E402
from nudyn_validation.mujoco_reference import Reference  # noqa: E402
from test_pinocchio import pinocchio_model, pinocchio_q  # noqa: E402

BENCH = ROOT / "target" / "release" / "nudyn-bench"
VEHICLES = ["bus_arm7", "servicer", "servicer_unactuated", "fixed_rig", "flexible_boom", "chain60"]
UNACTUATED = "_unactuated"
NUDYN_CASES = {
    "closed_form": "nudyn θ̈ Jacobians in θ and θ̇ (closed form)",
    "dual_jacobian": "nudyn Jacobians of ν̇ (dual numbers)",
    "nu_dot": "nudyn",
    "qacc": "nudyn qacc (integrator stage)",
}


def per_call(call, seconds: float = 0.2) -> float:
    """Seconds per call of `call`, timed over loops of doubling length."""
    n = 1
    while True:
        start = time.perf_counter()
        for _ in range(n):
            call()
        elapsed = time.perf_counter() - start
        if elapsed > seconds:
            return elapsed / n
        n *= 2


def nudyn_costs(path: Path, state: Path) -> dict:
    cmd = [str(BENCH), "eval-cost", str(path), "--state", str(state), "--repetitions", "15"]
    result = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
    return {key: float(np.median(result["nanoseconds"][name])) / 1e3 for key, name in NUDYN_CASES.items()}


def vehicle_path(name: str, work: Path) -> Path:
    """The example's MJCF file; for NAME_unactuated, a copy of NAME's without its <actuator> element."""
    if not name.endswith(UNACTUATED):
        return ROOT / "examples" / f"{name}.xml"
    text = (ROOT / "examples" / f"{name.removesuffix(UNACTUATED)}.xml").read_text()
    path = work / f"{name}.xml"
    path.write_text(re.sub(r"<actuator>.*?</actuator>", "", text, flags=re.S))
    return path


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("vehicles", nargs="*", default=VEHICLES)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()

    one = pin.Model()
    one.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "hinge")
    one.appendBodyToJoint(1, pin.Inertia.Random(), pin.SE3.Identity())
    one_data, one_q, one_v = one.createData(), np.zeros(1), np.ones(1)

    import tempfile
    results = {}
    with tempfile.TemporaryDirectory() as work:
        paths = {name: vehicle_path(name, Path(work)) for name in args.vehicles}
        prepared = {name: prepare(name, paths[name], Path(work)) for name in args.vehicles}
        rounds: dict[str, list[dict]] = {name: [] for name in args.vehicles}
        for _ in range(args.rounds):
            for name in args.vehicles:
                vehicle = prepared[name]
                row = {f"nudyn_{key}_us": value for key, value in nudyn_costs(vehicle.path, vehicle.state_path).items()}
                ref = Reference.from_file(paths[name])
                m = ref.model
                rng = np.random.default_rng(zlib.crc32(name.encode()) + 7)
                qpos, qvel, torque = ref.random_state(rng)
                d = ref.forward(qpos, qvel, torque)
                model, coordinates = pinocchio_model(m)
                data = model.createData()
                q, tau = pinocchio_q(m, model, coordinates, qpos), torque + d.qfrc_passive
                row["floor_us"] = 1e6 * min(per_call(lambda: pin.computeABADerivatives(one, one_data, one_q, one_v,
                                                                                         one_v)) for _ in range(3))
                row["pinocchio_us"] = 1e6 * min(per_call(lambda: pin.computeABADerivatives(model, data, q, qvel, tau))
                                                for _ in range(3))
                md = mujoco.MjData(m)
                md.qpos[:], md.qvel[:], md.qfrc_applied[:] = qpos, qvel, torque
                m.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
                nx = 2 * m.nv + m.na
                a, b = np.zeros((nx, nx)), np.zeros((nx, m.nu))
                row["mjd_transition_fd_us"] = 1e6 * min(
                    per_call(lambda: mujoco.mjd_transitionFD(m, md, 1e-6, 1, a, b, None, None)) for _ in range(2))
                rounds[name].append(row)
        for name, rows in rounds.items():
            summary = {key: statistics.median(r[key] for r in rows) for key in rows[0]}
            summary["pinocchio_less_floor_us"] = summary["pinocchio_us"] - summary["floor_us"]
            summary["closed_form_over_pinocchio"] = summary["nudyn_closed_form_us"] / summary["pinocchio_less_floor_us"]
            summary["closed_form_over_mjd"] = summary["nudyn_closed_form_us"] / summary["mjd_transition_fd_us"]
            results[name] = {"median": summary, "rounds": rows}
            print(f"{name}: closed form {summary['nudyn_closed_form_us']:.2f} µs, Pinocchio "
                  f"{summary['pinocchio_us']:.2f} µs (less the {summary['floor_us']:.2f} µs call floor: "
                  f"{summary['pinocchio_less_floor_us']:.2f}; ratio {summary['closed_form_over_pinocchio']:.2f}), "
                  f"mjd_transitionFD {summary['mjd_transition_fd_us']:.1f} µs (ratio "
                  f"{summary['closed_form_over_mjd']:.3f}); ν̇ {summary['nudyn_nu_dot_us']:.2f} µs, θ̈ "
                  f"{summary['nudyn_qacc_us']:.2f} µs, ν̇ Jacobian in dual numbers "
                  f"{summary['nudyn_dual_jacobian_us']:.0f} µs", flush=True)
    if args.out:
        args.out.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
