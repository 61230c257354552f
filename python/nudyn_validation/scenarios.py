"""The validation scenarios: an initial state and a law for the held ε.

Sizes are chosen per dof from its joint type and from MuJoCo's factor at the
initial pose, so that any vehicle, light or heavy, moves visibly but
realistically in a couple of seconds:
  velocities: free joint 0.05 m/s and 0.1 rad/s, ball and hinge 0.2 rad/s,
              slide 0.02 m/s (each component ~ N(0, scale)): a space
              robot's rates (they add up along a chain: chain60 starts
              with 630 J);
  pose:       hinges qpos0 ± 0.5 rad, slides qpos0 ± 0.05 m, ball and free
              joints a random orientation (free: position qpos0 ± 0.5 m);
  sine ε:     ε_k = a_k sin(2π f_k t + φ_k), a_k = √d_k · (velocity scale
              of dof k) / 1 s, i.e. the diagonalized force that changes
              the dof's rate by its scale in about a second;
  ctrl:       0 (MuJoCo's d.ctrl at rest: position servos hold their
              joints at 0) except in 'actuated', where each communication
              step holds a fresh draw, uniform in ctrlrange where the
              actuator is limited, N(0, 1) in its own units where not;
  wrenches:   in 'wrenched', on the bodies exported with --wrench-inputs,
              each communication step holds a fresh world-frame force
              ~ N(0, 0.1 m) N and torque ~ N(0, 0.05 m) N m per component,
              m the mass of the body's subtree (MuJoCo's xfrc_applied).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import mujoco
import numpy as np

from .mujoco_reference import MujocoFactor, random_quat
from .mujoco_run import has_gravity

# Tolerances of the issue: max |θ error| and |ν error| over the run.
UNFORCED_TOLERANCE = 1e-8
FORCED_TOLERANCE = 1e-6

# Rate-damping gain of ε = −c ν (1/s): ν decays like e^{−t}.
DAMPING_GAIN = 1.0

SCENARIO_NAMES = ("tumble", "sine", "damping", "gravity", "actuated", "wrenched")

# ε as a function of (time, the FMU's ν at that communication point).
EpsLaw = Callable[[float, np.ndarray], np.ndarray]

# The actuators' controls (MuJoCo's d.ctrl) held from a communication point, by its index.
CtrlLaw = Callable[[int], np.ndarray]
# The wrenches on the wrench bodies (one row of 6 per body, MuJoCo's
# xfrc_applied) held from a communication point, by its index.
WrenchLaw = Callable[[int], np.ndarray]


@dataclass
class Scenario:
    name: str
    description: str
    qpos0: np.ndarray
    qvel0: np.ndarray
    eps_law: EpsLaw
    unforced: bool
    ctrl_law: CtrlLaw | None = None
    wrench_bodies: tuple[str, ...] = ()
    wrench_law: WrenchLaw | None = None
    tolerance: float = field(init=False)

    def __post_init__(self):
        self.tolerance = UNFORCED_TOLERANCE if self.unforced else FORCED_TOLERANCE


def velocity_scales(model: mujoco.MjModel) -> np.ndarray:
    """Per-dof velocity scale (m/s or rad/s) from the joint types."""
    scale = np.zeros(model.nv)
    for j in range(model.njnt):
        v, kind = model.jnt_dofadr[j], model.jnt_type[j]
        if kind == mujoco.mjtJoint.mjJNT_FREE:
            scale[v : v + 6] = [0.05] * 3 + [0.1] * 3
        elif kind == mujoco.mjtJoint.mjJNT_BALL:
            scale[v : v + 3] = 0.2
        elif kind == mujoco.mjtJoint.mjJNT_HINGE:
            scale[v] = 0.2
        else:
            scale[v] = 0.02
    return scale


def offset_pose(model: mujoco.MjModel, rng: np.random.Generator) -> np.ndarray:
    """A random pose near qpos0; qpos0 itself for a model with active
    equality constraints, which hold in the pose the file was written in
    (a random pose would start every weld and connect far from holding)."""
    qpos = model.qpos0.copy()
    if np.any(model.eq_active0):
        return qpos
    for j in range(model.njnt):
        a, kind = model.jnt_qposadr[j], model.jnt_type[j]
        if kind == mujoco.mjtJoint.mjJNT_FREE:
            qpos[a : a + 3] += rng.uniform(-0.5, 0.5, 3)
            qpos[a + 3 : a + 7] = random_quat(rng)
        elif kind == mujoco.mjtJoint.mjJNT_BALL:
            qpos[a : a + 4] = random_quat(rng)
        elif kind == mujoco.mjtJoint.mjJNT_HINGE:
            qpos[a] += rng.uniform(-0.5, 0.5)
        else:
            qpos[a] += rng.uniform(-0.05, 0.05)
    return qpos


def sqrt_d_at(model: mujoco.MjModel, qpos) -> np.ndarray:
    """√d of MuJoCo's factor at qpos."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_fwdPosition(model, data)
    return MujocoFactor(model).sqrt_d(data)


def make_scenario(name: str, model: mujoco.MjModel, seed: int, wrench_bodies: tuple[str, ...] = ()) -> Scenario:
    """The scenario called name (one of SCENARIO_NAMES) for this model; the
    same seed gives the same pose, velocities and sine for every scenario."""
    rng = np.random.default_rng(seed)
    qpos0 = offset_pose(model, rng)
    scales = velocity_scales(model)
    qvel0 = rng.normal(0.0, scales)
    frequency = rng.uniform(0.3, 1.5, model.nv)  # Hz
    phase = rng.uniform(0.0, 2 * np.pi, model.nv)
    amplitude = sqrt_d_at(model, qpos0) * scales  # per 1 s

    zero = np.zeros(model.nv)
    if name == "tumble":
        return Scenario(
            name, "free motion, ε = 0, from a moving (tumbling) start", qpos0, qvel0, lambda t, nu: zero, True
        )
    if name == "sine":
        return Scenario(
            name,
            "open-loop sinusoidal ε, sampled and held at each communication point",
            qpos0,
            qvel0,
            lambda t, nu: amplitude * np.sin(2 * np.pi * frequency * t + phase),
            False,
        )
    if name == "damping":
        # ε comes from the FMU's ν, and MuJoCo is given the very same ε:
        # both sides then integrate the same input sequence, so their
        # difference measures the dynamics alone.  Feeding MuJoCo −c ν of
        # its own would compare two closed loops whose inputs already differ
        # by c·(ν error); the damping loop would shrink that difference and
        # hide part of the disagreement the comparison is there to show.
        return Scenario(
            name,
            f"closed-loop rate damping ε = −{DAMPING_GAIN:g} ν (the FMU's ν, held)",
            qpos0,
            qvel0,
            lambda t, nu: -DAMPING_GAIN * nu,
            False,
        )
    if name == "actuated":
        if model.nu == 0:
            raise ValueError("scenario 'actuated' needs a model with actuators (it has none)")
        return Scenario(
            name,
            "random ctrl held over each communication step (inside ctrlrange where limited), ε = 0",
            qpos0,
            qvel0,
            lambda t, nu: zero,
            False,
            ctrl_law=random_ctrl(model, seed),
        )
    if name == "wrenched":
        if not wrench_bodies:
            raise ValueError("scenario 'wrenched' needs bodies exported with --wrench-inputs")
        return Scenario(
            name,
            f"random wrenches on {', '.join(wrench_bodies)} held over each communication step (xfrc_applied), ε = 0",
            qpos0,
            qvel0,
            lambda t, nu: zero,
            False,
            wrench_bodies=tuple(wrench_bodies),
            wrench_law=random_wrenches(model, wrench_bodies, seed),
        )
    if name == "gravity":
        if not has_gravity(model):
            raise ValueError("scenario 'gravity' needs a model with gravity (it has none, or it is disabled)")
        return Scenario(
            name, "released from rest under gravity (and springs), ε = 0", qpos0, zero.copy(), lambda t, nu: zero, True
        )
    raise ValueError(f"unknown scenario '{name}' (known: {', '.join(SCENARIO_NAMES)})")


def random_ctrl(model: mujoco.MjModel, seed: int) -> CtrlLaw:
    """Controls drawn afresh for each communication step k, from (seed, k)
    alone: uniform in ctrlrange for a limited actuator, N(0, 1) otherwise."""
    limited = model.actuator_ctrllimited.astype(bool)
    low, high = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]

    def ctrl(k: int) -> np.ndarray:
        rng = np.random.default_rng([seed, k])
        unit, normal = rng.uniform(0.0, 1.0, model.nu), rng.normal(0.0, 1.0, model.nu)
        return np.where(limited, low + unit * (high - low), normal)

    return ctrl


def random_wrenches(model: mujoco.MjModel, bodies, seed: int) -> WrenchLaw:
    """Wrenches drawn afresh for each communication step k, from (seed, k)
    alone, scaled by the mass each body carries."""
    masses = np.array([model.body_subtreemass[model.body(name).id] for name in bodies])
    scale = np.column_stack([np.repeat(0.1 * masses[:, None], 3, 1), np.repeat(0.05 * masses[:, None], 3, 1)])

    def wrenches(k: int) -> np.ndarray:
        return np.random.default_rng([seed, k, 6]).normal(0.0, 1.0, scale.shape) * scale

    return wrenches


def applies(name: str, model: mujoco.MjModel, wrench_bodies: tuple[str, ...] = ()) -> bool:
    """'gravity' needs gravity, 'actuated' actuators, 'wrenched' wrench
    bodies; the others apply to every model."""
    if name == "gravity":
        return has_gravity(model)
    if name == "actuated":
        return model.nu > 0
    if name == "wrenched":
        return bool(wrench_bodies)
    return True


def default_scenarios(model: mujoco.MjModel, wrench_bodies: tuple[str, ...] = ()) -> list[str]:
    """Every scenario that applies to the model."""
    return [name for name in SCENARIO_NAMES if applies(name, model, wrench_bodies)]
