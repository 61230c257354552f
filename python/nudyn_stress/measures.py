"""What the suite measures on a run: drift of the invariants, error against
a reference run or an exact solution, and the cost of the integration.

Errors are scaled as the FMU's tolerance scales them: |x − x_ref| / (1 +
|x_ref|) per component, max over components and time; a quaternion is
first given the sign nearer the reference's (q and −q are one rotation)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nudyn_driver.cli import Nudyn
from nudyn_driver.package import FmuPackage

from .runs import Run, Setup, simulate

# Dynamics evaluations per internal step (first-same-as-last saves one of
# Dormand–Prince 5(4)'s seven stages).


def kinetic_energy_drift(run: Run) -> np.ndarray:
    """|K(t) − K₀| / K₀."""
    k = np.array(run.kinetic_energy)
    return np.abs(k - k[0]) / k[0]


def momentum_drift(run: Run) -> np.ndarray:
    """max(|ΔL| / |L₀|, |Δp| / |p₀|): angular (about the world origin) and
    linear momentum, each relative to its own size."""
    h = np.array(run.momentum)
    change = h - h[0]
    angular = np.linalg.norm(change[:, :3], axis=1) / np.linalg.norm(h[0, :3])
    linear = np.linalg.norm(change[:, 3:], axis=1) / np.linalg.norm(h[0, 3:])
    return np.maximum(angular, linear)


def energy_residual(run: Run) -> np.ndarray:
    """|K − K₀ − work| / K₀: the integration's energy error, also where
    dampers, springs or ε do work."""
    return np.abs(np.array(run.energy_residual)) / run.kinetic_energy[0]


def align_quaternions(theta: np.ndarray, reference: np.ndarray, quaternion_starts: list[int]) -> np.ndarray:
    theta = theta.copy()
    for a in quaternion_starts:
        block = slice(a, a + 4)
        flip = np.sum(theta[:, block] * reference[:, block], axis=1) < 0.0
        theta[flip, block] *= -1.0
    return theta


def scaled_error(run: Run, reference: Run, quaternion_starts: list[int]) -> np.ndarray:
    """Per sample time (those both runs reached), the max over θ and ν
    components of |x − x_ref| / (1 + |x_ref|)."""
    n = min(len(run.time), len(reference.time))
    # A discarded run's last sample is where it stopped, inside a step.
    while n > 0 and abs(run.time[n - 1] - reference.time[n - 1]) > 1e-9:
        n -= 1
    ref_theta, ref_nu = np.array(reference.theta[:n]), np.array(reference.nu[:n])
    theta = align_quaternions(np.array(run.theta[:n]), ref_theta, quaternion_starts)
    nu = np.array(run.nu[:n])
    theta_error = np.abs(theta - ref_theta) / (1 + np.abs(ref_theta))
    nu_error = np.abs(nu - ref_nu) / (1 + np.abs(ref_nu))
    return np.maximum(theta_error.max(axis=1), nu_error.max(axis=1))


def evaluation_cost(package: FmuPackage, theta0, nu0, steps: int = 200, step: float = 1e-3) -> float:
    """Seconds per dynamics evaluation, from RK4 (4 per step, no error
    control)."""
    run = simulate(package, Setup("rk4", max_step=step), theta0, nu0, steps * step, steps * step)
    return run.wall_time / (4 * steps)


def steps_per_second(run: Run) -> float:
    """Internal steps (taken and rejected, as the FMU reports them) per
    simulated second."""
    simulated = run.time[-1] - run.time[0]
    if simulated <= 0:
        return float("nan")
    return (run.steps_taken + run.steps_rejected) / simulated


def nu_of(nudyn: Path, model: Path, theta, qvel) -> np.ndarray:
    """ν = m*(θ) qvel, from `nudyn eval`."""
    return np.array(Nudyn(nudyn).eval(model, [{"theta": list(map(float, theta)), "qvel": list(map(float, qvel))}])[0]["nu"])


def sqrt_d(nudyn: Path, model: Path, theta, nv: int) -> np.ndarray:
    """√d_k of M = Lᵀ diag(d) L at θ: ν_k of qvel = e_k, because L is unit
    lower triangular."""
    theta = list(map(float, theta))
    requests = [{"theta": theta, "qvel": list(map(float, unit))} for unit in np.eye(nv)]
    return np.array([out["nu"][k] for k, out in enumerate(Nudyn(nudyn).eval(model, requests))])
