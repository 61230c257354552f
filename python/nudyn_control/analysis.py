"""What a closed-loop run shows, computed from MuJoCo (reference.py), not
from nudyn.

Lyapunov function: V = K + U, K = 1/2 |nu|^2, U = 1/2 (Yhat - Y)^T c2 (Yhat - Y).
With the ideal law eps*(x) = -c1 nu + g(theta), g = l J^T c2 (Yhat - Y),
dV/dt = nu . (eps + passive) - nu . g, so along the sampled loop, with
eps_held over a step,

    dV/dt = -nu^T c1 nu + nu . (eps_held - eps*(x(t)))   (bus_arm7: no passive forces)

and V(t) - V(t_k) <= integral over [t_k, t] of |nu| |eps_held - eps*(x)|: the
**sample-and-hold bound** B_k(t), measured on the run (trapezoid rule on the
plant's samples). With the held ε the law at the state at t_k - d h (d = 0:
FMPy's Gauss-Seidel loop, d = 1: libcosim's parallel steps),
|eps_held - eps*(x(s))| <= (s - t_k + d h) max|d eps*/dt|, so

    B_k <= (1/2 + d) h^2 max|nu| (c1_max max|nu_dot| + max|g_dot|)      (the c h bound)

and for pure rate feedback (g = 0), with |nu_dot| <= c1 |nu| + |C|,
B_k / K <= (1 + 2 d) c1 h (c1 h + h |C| / |nu|): the relative increase of
V within a step is second order in c1 h. Both bounds are evaluated per step
of the controller from the samples (maxima over the step and the d steps
before it; derivatives by differences of the samples)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .reference import ReferenceLaw
from .simulators import Trajectory


@dataclass
class Analysis:
    simulator: str
    time: np.ndarray
    lyapunov: np.ndarray  # V at every sample
    speed: np.ndarray  # |nu| at every sample
    position_error: np.ndarray | None
    rotation_error: np.ndarray | None
    delay: int  # steps of h between the state the law used and the step it acts in
    law_mismatch: float  # max |eps_held - eps*(delayed state)| / max |eps*|
    increase: np.ndarray  # per controller step: max over t in the step of V(t) - V(t_k)
    bound: np.ndarray  # per controller step: B_k at that t (the integral bound)
    ch_bound: np.ndarray  # per controller step: the c h bound
    bound_violation: float  # max over samples of (V(t) - V(t_k)) - B_k(t), scaled by V(0)
    wall_time: float

    def summary(self) -> dict:
        k = int(np.argmax(self.increase))
        period_start = self.lyapunov[:: self.substeps][:-1]
        return {
            "simulator": self.simulator,
            "delay_steps": self.delay,
            "law_mismatch": self.law_mismatch,
            "worst_increase": float(self.increase[k]),
            "worst_increase_time": float(self.time[k * self.substeps]),
            "bound_there": float(self.bound[k]),
            "ch_bound_there": float(self.ch_bound[k]),
            "worst_relative_increase": float(np.max(self.increase / period_start)),
            "worst_ratio_to_bound": float(np.max(self.increase / np.maximum(self.bound, 1e-300))),
            "steps_with_increase": int(np.sum(self.increase > 0)),
            "bound_violation": self.bound_violation,
            "final_speed": float(self.speed[-1]),
            "final_position_error": None if self.position_error is None else float(self.position_error[-1]),
            "final_rotation_error": None if self.rotation_error is None else float(self.rotation_error[-1]),
            "wall_time": self.wall_time,
        }

    substeps: int = 1


def analyse(run: Trajectory, law: ReferenceLaw) -> Analysis:
    m, h = run.substeps, run.step
    hf = h / m
    samples = len(run.time)
    lyapunov = np.array([law.lyapunov(q, n) for q, n in zip(run.theta, run.nu)])
    configuration = np.array([law.configuration_eps(q) for q in run.theta])
    ideal = configuration - law.parameters.c1 * run.nu
    speed = np.linalg.norm(run.nu, axis=1)

    # Which state the held ε is the law of: the start of this step, or of the one before.
    periods = (samples - 1) // m
    held = run.eps[::m]
    scale = max(float(np.max(np.abs(ideal))), 1e-300)
    mismatch = {}
    for d in (0, 1):
        used = ideal[np.maximum(np.arange(periods) - d, 0) * m]
        mismatch[d] = float(np.max(np.abs(held - used))) / scale
    delay = min(mismatch, key=mismatch.get)

    # The integral bound, sample by sample: trapezoid of |nu| |eps_held - eps*|.
    gap = np.linalg.norm(run.eps - ideal[:-1], axis=1) * speed[:-1]
    gap_end = np.linalg.norm(run.eps - ideal[1:], axis=1) * speed[1:]
    pieces = 0.5 * hf * (gap + gap_end)

    nu_rate = np.linalg.norm(np.diff(run.nu, axis=0), axis=1) / hf
    g_rate = np.linalg.norm(np.diff(configuration, axis=0), axis=1) / hf
    c1_max = float(np.max(law.parameters.c1))
    increase, bound, ch_bound = np.zeros(periods), np.zeros(periods), np.zeros(periods)
    violation = 0.0
    for k in range(periods):
        j0 = k * m
        rise = lyapunov[j0 + 1 : j0 + m + 1] - lyapunov[j0]
        allowed = np.cumsum(pieces[j0 : j0 + m])
        violation = max(violation, float(np.max(rise - allowed)))
        worst = int(np.argmax(rise))
        increase[k] = max(float(rise[worst]), 0.0)
        bound[k] = allowed[worst]
        window = slice(max(j0 - delay * m, 0), j0 + m)
        ch_bound[k] = (0.5 + delay) * h * h * float(np.max(speed[window.start : window.stop + 1])) * (
            c1_max * float(np.max(nu_rate[window])) + float(np.max(g_rate[window])))

    position_error = rotation_error = None
    if law.body is not None:
        errors = np.array([law.error(q) for q in run.theta])
        position_error = np.linalg.norm(errors[:, :3], axis=1)
        rotation_error = np.linalg.norm(errors[:, 3:], axis=1)
    return Analysis(run.simulator, run.time, lyapunov, speed, position_error, rotation_error, delay,
                    mismatch[delay], increase, bound, ch_bound, violation / max(lyapunov[0], 1e-300),
                    run.wall_time, m)
