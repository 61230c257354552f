"""Work-precision: wall time to simulate a vehicle for 10 s against the
largest error over the run, for nudyn's methods (`nudyn-bench simulate`,
timed in Rust) and MuJoCo's RK4, Euler and implicitfast
(`mujoco.rollout`, a native loop of mj_step; timed around the call, with
its output array allocated beforehand).

The error of a run is the largest, over the samples (every 0.5 s: each is
a point where nudyn's adaptive steps stop, as at an FMU communication
point, and where MuJoCo's states are picked from its rollout), of
max |qpos − qpos_ref| (quaternions up to sign) and max |qvel − qvel_ref|:
MuJoCo's coordinates, in which both sides are compared. The reference is
MuJoCo's RK4 at a tiny step, and it is checked against nudyn's DOP853 at a
tight tolerance: an independent computation of the same motion."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import mujoco.rollout
import numpy as np

from nudyn_driver.cli import run_json
from nudyn_validation.compare import quaternion_starts
from nudyn_validation.mujoco_reference import set_timestep

from .vehicles import Vehicle

INTEGRATORS = {
    "RK4": mujoco.mjtIntegrator.mjINT_RK4,
    "Euler": mujoco.mjtIntegrator.mjINT_EULER,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
}
STATE_SPEC = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)


@dataclass
class Plan:
    """What the work-precision runs cover."""

    duration: float
    sample: float
    reference_step: float
    reference_tolerance: float
    rk4_steps: list[float]
    first_order_steps: list[float]
    dopri5_tolerances: list[float]
    dop853_tolerances: list[float]
    # The pairs added for issue 36 and `method = auto` (bs3 stops where it needs 10⁵ steps and more).
    bs3_tolerances: list[float] = field(default_factory=list)
    tsit5_tolerances: list[float] = field(default_factory=list)
    auto_tolerances: list[float] = field(default_factory=list)


# The starts: the validation's tumble (seed 1), and the same with rates ten
# times larger (arm joints about 2 rad/s, the bus 1 rad/s). At the
# validation's rates every method is within 1e-6 at its largest steps, so
# that comparison mostly measures fixed costs; the fast one measures accuracy.
SCENARIOS = {"tumble": 1.0, "fast tumble": 10.0}

FULL = Plan(
    duration=10.0,
    sample=0.5,
    reference_step=2e-5,
    reference_tolerance=1e-12,
    rk4_steps=[0.1, 0.05, 0.02, 0.01, 5e-3, 2e-3, 1e-3, 5e-4],
    first_order_steps=[0.01, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4, 5e-5],
    dopri5_tolerances=[1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10],
    dop853_tolerances=[1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11],
    bs3_tolerances=[1e-3, 1e-4, 1e-5, 1e-6, 1e-7],
    tsit5_tolerances=[1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10],
    auto_tolerances=[1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11],
)
QUICK = Plan(
    duration=0.2,
    sample=0.1,
    reference_step=1e-3,
    reference_tolerance=1e-10,
    rk4_steps=[0.05, 0.01],
    first_order_steps=[0.01],
    dopri5_tolerances=[1e-4],
    dop853_tolerances=[1e-6],
    bs3_tolerances=[1e-4],
    tsit5_tolerances=[1e-4],
    auto_tolerances=[1e-6],
)


class MujocoRuns:
    """MuJoCo's model with each integrator, and rollouts from the vehicle's state."""

    def __init__(self, vehicle: Vehicle):
        self.vehicle = vehicle
        self.model = vehicle.model
        self.data = mujoco.MjData(self.model)
        self.data.qpos[:] = vehicle.qpos
        self.data.qvel[:] = vehicle.qvel
        mujoco.mj_forward(self.model, self.data)
        self.initial = np.empty(mujoco.mj_stateSize(self.model, STATE_SPEC))
        mujoco.mj_getState(self.model, self.data, self.initial, STATE_SPEC)
        # Layout of a FULLPHYSICS state: time, qpos, qvel, ...
        self.qpos = slice(1, 1 + self.model.nq)
        self.qvel = slice(1 + self.model.nq, 1 + self.model.nq + self.model.nv)

    def run(self, integrator: str, step: float, plan: Plan) -> tuple[float, np.ndarray, np.ndarray]:
        """(wall time, qpos and qvel at every sample) of one run."""
        self.model.opt.integrator = INTEGRATORS[integrator]
        set_timestep(self.model, step)
        per_sample = _whole(plan.sample, step)
        samples = _whole(plan.duration, plan.sample)
        states = np.empty((1, per_sample * samples, self.initial.size))
        # Untimed, one sample long: a millisecond run timed cold (first
        # after a change of integrator) took up to twice its warm time.
        mujoco.rollout.rollout(self.model, self.data, self.initial, nstep=per_sample, state=states[:, :per_sample])
        start = time.perf_counter()
        mujoco.rollout.rollout(self.model, self.data, self.initial, nstep=per_sample * samples, state=states)
        seconds = time.perf_counter() - start
        picked = np.vstack([self.initial, states[0, per_sample - 1 :: per_sample]])
        return seconds, picked[:, self.qpos], picked[:, self.qvel]

    def reference(self, plan: Plan) -> tuple[np.ndarray, np.ndarray]:
        """RK4 at the reference step, sample by sample (a whole run's
        states would not fit in memory)."""
        self.model.opt.integrator = INTEGRATORS["RK4"]
        set_timestep(self.model, plan.reference_step)
        # Chunks of at most 0.1 s: a sample's states at once could be too many.
        chunk = min(plan.sample, 0.1)
        per_chunk = _whole(chunk, plan.reference_step)
        chunks_per_sample = _whole(plan.sample, chunk)
        state = self.initial.copy()
        picked = [state]
        for _ in range(_whole(plan.duration, plan.sample)):
            for _ in range(chunks_per_sample):
                out = mujoco.rollout.rollout(self.model, self.data, state, nstep=per_chunk)
                state = out[0][0, -1].copy()
            picked.append(state)
        picked = np.array(picked)
        return picked[:, self.qpos], picked[:, self.qvel]


def _whole(total: float, step: float) -> int:
    count = int(round(total / step))
    if abs(count * step - total) > 1e-9 * total:
        raise ValueError(f"{total} is not a multiple of {step}")
    return count


def nudyn_runs(bench: Path, vehicle: Vehicle, runs: list[str], plan: Plan, samples: bool = True) -> list[dict]:
    """`nudyn-bench simulate` of each run once (with the sampled states, or only the times)."""
    cmd = [
        str(bench), "simulate", str(vehicle.path), "--state", str(vehicle.state_path),
        "--duration", str(plan.duration), "--sample", str(plan.sample),
    ]
    if not samples:
        cmd.append("--no-samples")
    for run in runs:
        cmd += ["--run", run]
    return run_json(cmd)


def max_error(model: mujoco.MjModel, qpos, qvel, reference_qpos, reference_qvel) -> float:
    """Largest |qpos error| (quaternions up to sign) or |qvel error| over the samples."""
    qpos = np.array(qpos, float)
    for a in quaternion_starts(model):
        flip = np.sum(qpos[:, a : a + 4] * reference_qpos[:, a : a + 4], axis=1) < 0
        qpos[flip, a : a + 4] *= -1
    largest = max(np.abs(qpos - reference_qpos).max(), np.abs(np.asarray(qvel) - reference_qvel).max())
    # A run that blew up (MuJoCo leaves NaN, or resets with a warning) has no finite error.
    return float(largest) if np.isfinite(largest) else float("inf")


def nudyn_run_names(plan: Plan) -> list[str]:
    return (
        [f"rk4:{h:g}" for h in plan.rk4_steps]
        + [f"dopri5:{t:g}" for t in plan.dopri5_tolerances]
        + [f"dop853:{t:g}" for t in plan.dop853_tolerances]
        + [f"bs3:{t:g}" for t in plan.bs3_tolerances]
        + [f"tsit5:{t:g}" for t in plan.tsit5_tolerances]
        + [f"auto:{t:g}" for t in plan.auto_tolerances]
    )


def mujoco_run_names(plan: Plan) -> list[tuple[str, float]]:
    return [("RK4", h) for h in plan.rk4_steps] + [
        (name, h) for name in ("Euler", "implicitfast") for h in plan.first_order_steps
    ]


def time_at_error(points: list[tuple[float, float]], target: float) -> float | None:
    """Wall time at max error `target` on one method's curve: log-linear
    interpolation between the two runs whose errors bracket it (the runs
    sorted by time); the cheapest run already within target otherwise;
    None if no run reaches it."""
    points = sorted(points, key=lambda p: p[1])  # (error, time) by time
    for (e0, t0), (e1, t1) in zip(points, points[1:]):
        if np.isfinite(e0) and e0 > target >= e1 > 0:
            w = (np.log(target) - np.log(e0)) / (np.log(e1) - np.log(e0))
            return float(np.exp(np.log(t0) + w * (np.log(t1) - np.log(t0))))
    within = [t for e, t in points if e <= target]
    return min(within) if within else None
