"""The worked LQR example (python/nudyn_control/lqr.py, docs/linearization.md):
a discrete regulator designed on `nudyn linearize --step H`'s zero-order
hold at bus_arm7's qpos0, closed around the plant FMU in FMPy.

What makes this a test of the linearization: the FMU runs the nonlinear
dynamics, the prediction x_{k+1} = (A_d − B_d K) x_k the linear ones, and
their difference from the same x₀ must be of second order in x₀ (halving
x₀ quarters it). A wrong first-order term in A_d or B_d would leave a
difference of first order (halving x₀ would halve it): with B_d 1 % off,
the ratio measured 2.19 at these amplitudes, against 4.00 as it is."""

from __future__ import annotations

import numpy as np
import mujoco

from conftest import EXAMPLES
from nudyn_control.lqr import close_the_loop, design
from nudyn_driver.cli import Nudyn

STEP = 0.05


def test_the_regulator_designed_on_the_hold_closes_the_loop_around_the_fmu(nudyn, tmp_path):
    bus = next(p for p in EXAMPLES if p.stem == "bus_arm7")
    plan = design(nudyn, bus, STEP)
    assert max(abs(np.linalg.eigvals(plan.closed_loop()))) < 0.95
    fmu = Nudyn(nudyn).export(bus, tmp_path / "plant.fmu", outputs=["qvel"])
    nv = mujoco.MjModel.from_xml_path(str(bus)).nv
    direction = np.zeros(nv)
    direction[3:6] = (0.02, -0.01, 0.015)  # the bus turned about all three axes
    direction[6:] = 0.02  # every arm joint
    gaps = []
    for scale in (1 / 64, 1 / 128):
        run = close_the_loop(fmu, bus, plan, direction * scale, 5.0, tmp_path / f"run{len(gaps)}")
        x0, end = np.abs(run.state[0]).max(), np.abs(run.state[-1]).max()
        assert end < 1e-2 * x0, f"|x| from {x0:.3g} to only {end:.3g} in 5 s"
        gaps.append(np.abs(run.state - run.predicted).max())
    ratio = gaps[0] / gaps[1]
    print(f"FMU vs linear closed loop: {gaps[0]:.3g} at |x0| = {x0 * 2:.3g}, {gaps[1]:.3g} at half; ratio {ratio:.3f}")
    assert 3.8 < ratio < 4.2, f"halving x0 divides the FMU's difference from the linear loop by {ratio:.2f}, not 4"
