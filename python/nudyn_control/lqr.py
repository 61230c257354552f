"""A worked LQR example (docs/linearization.md): `nudyn linearize --step H`
gives the zero-order hold's pair (A_d, B_d) at a state, a discrete
linear-quadratic regulator is designed on it, and the loop is closed around
the plant FMU in FMPy, the regulator sampling θ and θ̇ (the FMU's `qvel`
output) every H and holding ε over the step, as the hold assumes.

    python -m nudyn_control.lqr [--vehicle examples/bus_arm7.xml] [--plot docs/control/lqr_bus_arm7.png]

x = (δq, θ̇) as `nudyn linearize` and MuJoCo's mjd_transitionFD take it: δq
the displacement from the operating point in the tangent space
(mj_differentiatePos), u = ε. The Riccati equation is solved by iterating
it (numpy only); the gain is u = −K x.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from nudyn_driver.cli import Nudyn
from nudyn_driver.instance import Instance
from nudyn_driver.locations import examples_dir, nudyn_binary
from nudyn_driver.package import FmuPackage


@dataclass
class Design:
    """The linearization at qpos0 (at rest, ε = 0) and the regulator designed on it."""

    qpos0: np.ndarray
    ad: np.ndarray
    bd: np.ndarray
    gain: np.ndarray
    step: float

    def closed_loop(self) -> np.ndarray:
        return self.ad - self.bd @ self.gain


def discrete_lqr(ad: np.ndarray, bd: np.ndarray, q: np.ndarray, r: np.ndarray, tolerance=1e-13,
                 iterations=100_000) -> np.ndarray:
    """K of u = −Kx minimizing Σ xᵀQx + uᵀRu for x⁺ = A_d x + B_d u: the
    discrete Riccati equation iterated from P = Q to its fixed point."""
    p = q.copy()
    for _ in range(iterations):
        gain = np.linalg.solve(r + bd.T @ p @ bd, bd.T @ p @ ad)
        following = q + ad.T @ p @ (ad - bd @ gain)
        following = (following + following.T) / 2
        if np.abs(following - p).max() <= tolerance * np.abs(following).max():
            return np.linalg.solve(r + bd.T @ following @ bd, bd.T @ following @ ad)
        p = following
    raise RuntimeError(f"the Riccati iteration did not converge in {iterations} steps")


def design(nudyn: Path, vehicle: Path, step: float, position_weight=100.0, rate_weight=1.0,
           input_weight=0.01) -> Design:
    """Linearizes the vehicle at qpos0 at rest with ε as the input and designs the regulator."""
    proc = subprocess.run([str(nudyn), "linearize", str(vehicle), "--inputs", "eps", "--step", repr(step)],
                          capture_output=True, text=True, check=True)
    out = json.loads(proc.stdout)
    ad, bd = np.array(out["Ad"]), np.array(out["Bd"])
    nv = bd.shape[1]
    q = np.diag([position_weight] * nv + [rate_weight] * nv)
    gain = discrete_lqr(ad, bd, q, np.eye(nv) * input_weight)
    return Design(np.array(out["qpos"]), ad, bd, gain, step)


@dataclass
class Run:
    time: np.ndarray
    state: np.ndarray  # (steps + 1, 2 nv): x from the FMU
    predicted: np.ndarray  # (steps + 1, 2 nv): x from the linear closed loop


def close_the_loop(fmu: Path, mjcf: Path, plan: Design, offset: np.ndarray, duration: float,
                   workdir: Path) -> Run:
    """The regulator around the FMU in FMPy from qpos0 ⊕ offset at rest, and
    the linear closed loop's prediction from the same x₀."""
    model = mujoco.MjModel.from_xml_path(str(mjcf))
    nv = model.nv
    start = plan.qpos0.copy()
    mujoco.mj_integratePos(model, start, offset, 1.0)
    package = FmuPackage.unzip(fmu, workdir / "lqr_plant")
    plant = Instance(package, name="plant", theta=start, nu=np.zeros(nv), stop_time=duration)
    steps = round(duration / plan.step)
    state = np.zeros((steps + 1, 2 * nv))

    def measured() -> np.ndarray:
        dq = np.zeros(nv)
        mujoco.mj_differentiatePos(model, dq, 1.0, plan.qpos0, plant.array("theta"))
        return np.concatenate([dq, plant.array("qvel")])

    for k in range(steps):
        state[k] = measured()
        plant.set_array("eps", -plan.gain @ state[k])
        plant.step(plan.step, communication_point=k * plan.step)
    state[steps] = measured()
    plant.close()
    predicted = np.zeros_like(state)
    predicted[0] = state[0]
    closed = plan.closed_loop()
    for k in range(steps):
        predicted[k + 1] = closed @ predicted[k]
    return Run(np.arange(steps + 1) * plan.step, state, predicted)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--vehicle", type=Path, default=examples_dir() / "bus_arm7.xml")
    parser.add_argument("--step", type=float, default=0.05)
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--plot", type=Path)
    args = parser.parse_args()
    nudyn = nudyn_binary()
    plan = design(nudyn, args.vehicle, args.step)
    radius = max(abs(np.linalg.eigvals(plan.closed_loop())))
    print(f"closed-loop spectral radius at H = {args.step} s: {radius:.6f}")
    model = mujoco.MjModel.from_xml_path(str(args.vehicle))
    offset = np.zeros(model.nv)
    offset[3:6] = (0.02, -0.01, 0.015)  # the bus turned about all three axes
    offset[6:] = 0.02  # every arm joint
    with tempfile.TemporaryDirectory() as work:
        fmu = Nudyn(nudyn).export(args.vehicle, Path(work) / "plant.fmu", outputs=["qvel"])
        run = close_the_loop(fmu, args.vehicle, plan, offset, args.duration, Path(work))
    gap = np.abs(run.state - run.predicted).max()
    print(f"|x| from {np.abs(run.state[0]).max():.3g} to {np.abs(run.state[-1]).max():.3g} in "
          f"{args.duration} s; FMU vs linear closed loop: {gap:.3g}")
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
        top.plot(run.time, run.state[:, : model.nv])
        top.plot(run.time, run.predicted[:, : model.nv], "k:", linewidth=0.8)
        top.set_ylabel("δq (FMU; dotted: linear)")
        bottom.semilogy(run.time, np.abs(run.state - run.predicted).max(axis=1) + 1e-17)
        bottom.set_ylabel("|FMU − linear|")
        bottom.set_xlabel("time (s)")
        fig.tight_layout()
        fig.savefig(args.plot, dpi=100)


if __name__ == "__main__":
    main()
