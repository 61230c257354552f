"""MuJoCo's simulation of a vehicle driven by diagonalized forces ε.

MuJoCo integrates with its own RK4 (mjINT_RK4, 4th order on quaternions) at
a step much smaller than the communication step.  MuJoCo knows physical
joint torques, not ε, so a control callback applies T = m(θ) ε with
m = Lᵀ diag(√d) from MuJoCo's own factor (`MujocoFactor`, qLD) at the state
of every RK4 stage: mjcb_control runs once per stage, after the position
stage has factored M at that stage's θ.  ε is held constant from one
communication point to the next, exactly as the FMU holds its input.
"""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path

import mujoco
import numpy as np

from .mujoco_reference import MujocoFactor, load_model, set_timestep, subtree_momentum


ENERGY = int(mujoco.mjtEnableBit.mjENBL_ENERGY)


@contextmanager
def control_callback(callback):
    """Install a global mjcb_control for the duration of the block, and put
    back whatever was there before (the callback is process-wide)."""
    previous = mujoco.get_mjcb_control()
    mujoco.set_mjcb_control(callback)
    try:
        yield
    finally:
        mujoco.set_mjcb_control(previous)


class MujocoVehicle:
    """One MuJoCo simulation of the vehicle, stepped in communication steps
    with a held ε; after each, the quantities compared with the FMU."""

    def __init__(self, model_path: str | Path, step: float):
        self.model = load_model(model_path)
        self.model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
        set_timestep(self.model, step)
        # data.energy = (potential: gravity and springs, kinetic ½ qvelᵀ M qvel).
        self.model.opt.enableflags |= ENERGY
        # The actuators act, as in the FMU (whose ctrl inputs are MuJoCo's
        # d.ctrl): a position servo pulls on its joint even at ctrl = 0.
        self.data = mujoco.MjData(self.model)
        self.factor = MujocoFactor(self.model)
        self.held_eps = np.zeros(self.model.nv)
        self._scratch = mujoco.MjData(self.model)

    def set_state(self, qpos, qvel) -> None:
        self.data.qpos[:] = qpos
        self.data.qvel[:] = qvel
        self.data.time = 0.0
        mujoco.mj_forward(self.model, self.data)

    def _apply_held_eps(self, model, data) -> None:
        data.qfrc_applied[:] = self.factor.torque(data, self.held_eps)

    def advance(self, eps, substeps: int, ctrl=None, wrenches=None) -> None:
        """Integrate over one communication step of `substeps` MuJoCo steps
        with ε held at eps, the actuators' controls at ctrl (default 0) and
        the external wrenches at `wrenches` ({body: 6 values}, MuJoCo's
        xfrc_applied; default none)."""
        self.held_eps[:] = eps
        self.data.ctrl[:] = 0.0 if ctrl is None else ctrl
        for body, wrench in (wrenches or {}).items():
            self.data.xfrc_applied[self.model.body(body).id] = wrench
        # With ε = 0 (free motion, gravity, the actuators alone) T = m(θ) 0 = 0
        # at every stage: no callback then, the same numbers (up to the sign
        # of an exact zero), and on a long chain much less work than the
        # factor at every stage.
        applying = bool(np.any(self.held_eps))
        if not applying:
            self.data.qfrc_applied[:] = 0.0
        with control_callback(self._apply_held_eps if applying else None):
            # The energies are read at the communication points only: computed
            # at every stage of every step, they cost a sixth of chain60's
            # step, and they change nothing in the motion.
            self.model.opt.enableflags &= ~ENERGY
            for _ in range(substeps):
                mujoco.mj_step(self.model, self.data)
            self.model.opt.enableflags |= ENERGY
            # RK4's last stage is not at the new state: evaluate there, so that
            # the factor, the energies and the momentum below belong to it.
            mujoco.mj_forward(self.model, self.data)

    def instability(self) -> str | None:
        """The first of MuJoCo's bad-state warnings raised so far, if any:
        on a non-finite or huge qpos, qvel or qacc MuJoCo resets the state
        and goes on, which must not pass for a comparison."""
        for warning in (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQACC):
            if self.data.warning[int(warning)].number > 0:
                return warning.name
        return None

    # Quantities at the current state (valid after set_state or advance).
    def theta(self) -> np.ndarray:
        return self.data.qpos.copy()

    def nu(self) -> np.ndarray:
        return self.factor.nu(self.data, self.data.qvel)

    def kinetic_energy(self) -> float:
        return self.factor.kinetic_energy(self.data)

    def potential_energy(self) -> float:
        return float(self.data.energy[0])

    def momentum(self) -> np.ndarray:
        return subtree_momentum(self.model, self.data)

    def potential_energy_at(self, qpos) -> float:
        """MuJoCo's potential energy (gravity, springs) at another θ, on
        scratch data: the FMU has no potential-energy output, so its energy
        drift uses this function of its own θ."""
        self._scratch.qpos[:] = qpos
        mujoco.mj_fwdPosition(self.model, self._scratch)
        mujoco.mj_energyPos(self.model, self._scratch)
        return float(self._scratch.energy[0])

    @property
    def conserves_energy_unforced(self) -> bool:
        """Whether K + U is conserved with ε = 0 and ctrl = 0: no joint
        damping, no actuator that pulls at ctrl = 0 (a position or
        velocity servo is a spring and a damper), and no gravity
        compensation (MuJoCo's U leaves its work out)."""
        return (
            not has_dampers(self.model)
            and not actuators_pull_at_rest(self.model)
            and not has_gravity_compensation(self.model)
        )


def _enabled(model: mujoco.MjModel, disable_bit) -> bool:
    return not model.opt.disableflags & int(disable_bit)


def has_gravity(model: mujoco.MjModel) -> bool:
    return bool(np.any(model.opt.gravity != 0.0)) and _enabled(model, mujoco.mjtDisableBit.mjDSBL_GRAVITY)


def has_gravity_compensation(model: mujoco.MjModel) -> bool:
    """Whether MuJoCo applies gravity compensation: some body with gravcomp
    > 0 under gravity, and its passive stage not skipped (springs and
    dampers not both disabled)."""
    bits = mujoco.mjtDisableBit
    passive = _enabled(model, bits.mjDSBL_SPRING) or _enabled(model, bits.mjDSBL_DAMPER)
    return bool(np.any(model.body_gravcomp > 0.0)) and has_gravity(model) and passive


def has_dampers(model: mujoco.MjModel) -> bool:
    return bool(np.any(model.dof_damping > 0.0)) and _enabled(model, mujoco.mjtDisableBit.mjDSBL_DAMPER)


def actuators_pull_at_rest(model: mujoco.MjModel) -> bool:
    """Whether some enabled actuator applies a force at ctrl = 0 (an affine bias)."""
    affine = model.actuator_biastype == int(mujoco.mjtBias.mjBIAS_AFFINE)
    biased = np.any(model.actuator_biasprm[:, :3] != 0.0, axis=1)
    return bool(np.any(affine & biased)) and _enabled(model, mujoco.mjtDisableBit.mjDSBL_ACTUATION)
