"""The two closed-loop demos, as data: which vehicle, which controller, the
start, the controller's communication step h and how often within it the
plant's state is sampled to watch V between communication points."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from nudyn_driver.locations import examples_dir
from nudyn_validation.mujoco_reference import Reference



@dataclass
class Scenario:
    name: str
    title: str
    mjcf: Path
    end_effector: str | None
    duration: float
    # h: the controller FMU's communication step (ε is held over it).
    step: float
    # Plant steps per h: V is watched at h/substeps within each step.
    substeps: int
    # Plant start values by variable name (nu[...]).
    plant_start: dict[str, float] = field(default_factory=dict)
    # Controller parameter values by name (c1[...], c2[...], targets).
    controller: dict[str, float] = field(default_factory=dict)
    # What the scenario must reach.
    nu_tolerance: float | None = None
    position_tolerance: float | None = None
    rotation_tolerance: float | None = None


def _nu_start(mjcf: Path, qvel) -> dict[str, float]:
    """ν = m*(qpos0) qvel, from MuJoCo, as plant start values."""
    reference = Reference.from_file(mjcf)
    nu = reference.nu(reference.model.qpos0, np.asarray(qvel, float))
    return {f"nu[{k + 1}]": float(x) for k, x in enumerate(nu)}


def detumble() -> Scenario:
    """bus_arm7 spinning and drifting with its arm swinging; rate feedback
    with the controller FMU's default gains (c1 = 5/s on every dof, c2 = 0)."""
    mjcf = examples_dir() / "bus_arm7.xml"
    # Free joint: linear velocity (world), angular velocity (body); then the 7 arm joints.
    qvel = [0.05, -0.02, 0.03, 0.3, -0.2, 0.4, 0.2, -0.3, 0.25, 0.4, -0.2, 0.3, -0.5]
    return Scenario(
        name="detumble",
        title="detumble: bus_arm7 from a tumble, eps = -c1 nu (c1 = 5/s, the default)",
        mjcf=mjcf,
        end_effector=None,
        duration=5.0,
        step=0.01,
        substeps=10,
        plant_start=_nu_start(mjcf, qvel),
        nu_tolerance=1e-6,
    )


# The arm demo's target: the end effector's pose at qpos0, moved by
# TARGET_SHIFT (m, world) and turned by TARGET_TURN (rotation vector, rad,
# about the end effector's own axes).
TARGET_SHIFT = np.array([-0.6, 0.8, 0.5])
TARGET_TURN = np.array([0.5, -0.4, 0.7])
POSITION_GAIN = 600.0  # N/m
ROTATION_GAINS = (20.0, 20.0, 10.0)  # N*m/rad about the target frame's x, y, z


def arm() -> Scenario:
    """bus_arm7 at rest; the end effector is driven to a pose 1.1 m and
    0.95 rad away while the free-floating base has no target (it is only damped
    by the c1 term and ends where the motion leaves it)."""
    mjcf = examples_dir() / "bus_arm7.xml"
    model = mujoco.MjModel.from_xml_path(str(mjcf))
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "end_effector")
    position = data.xpos[body] + TARGET_SHIFT
    turn = np.zeros(4)
    mujoco.mju_axisAngle2Quat(turn, TARGET_TURN / np.linalg.norm(TARGET_TURN), np.linalg.norm(TARGET_TURN))
    quaternion = np.zeros(4)
    mujoco.mju_mulQuat(quaternion, data.xquat[body], turn)
    controller = {f"target_position[{k + 1}]": float(position[k]) for k in range(3)}
    controller |= {f"target_quaternion[{k + 1}]": float(quaternion[k]) for k in range(4)}
    controller |= {f"c2[{k + 1}]": POSITION_GAIN for k in range(3)}
    controller |= {f"c2[{k + 4}]": gain for k, gain in enumerate(ROTATION_GAINS)}
    return Scenario(
        name="arm",
        title="arm: end effector to a target pose, base floating (c1 = 5/s, c2 = 600 N/m, 20/20/10 N*m/rad)",
        mjcf=mjcf,
        end_effector="end_effector",
        duration=10.0,
        step=0.01,
        substeps=5,
        controller=controller,
        position_tolerance=1e-5,
        rotation_tolerance=1e-5,
    )


SCENARIOS = {"detumble": detumble, "arm": arm}
