"""The FMU and MuJoCo run side by side from the same state with the same held
ε, and the differences between them.

At each communication point t_k the scenario's ε_k is computed (from the
FMU's ν for closed loops), given to both, and held until t_k + Δt.  Both
sides are sampled at every communication point: θ, ν, the kinetic energy,
the momentum and, for the energy drift, K + U (U: MuJoCo's potential energy
of gravity and springs).  MuJoCo's twins, the same run from qvel moved by
±TWIN_NUDGE, run beside them with the same inputs: how far they drift from
MuJoCo is what the model's sensitivity at this step allows (judgement.py).
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from fmpy.fmi1 import FMICallException

from nudyn_driver.cli import Nudyn
from nudyn_driver.instance import Instance
from nudyn_driver.package import FmuPackage

from .judgement import TWINS, judge, passes, twin_nudges
from .modal_part import MODAL_OUTPUTS, FreezeError, ModalPart, export_frozen, modal_files, run_modal_part
from .mujoco_reference import load_model
from .mujoco_run import MujocoVehicle
from .runners import Fmi3CoSimulation, ModelExchange
from .scenarios import Scenario, default_scenarios, make_scenario

# The optional outputs the comparison reads besides theta and nu.
EXTRA_OUTPUTS = ("kinetic_energy", "momentum")


class ValidationError(Exception):
    """A problem with the user's input or set-up, reported as a message."""


@dataclass
class Settings:
    """How both sides are run.  The defaults meet the tolerances on every
    example with margin (the measurements are in docs/validation.md)."""

    duration: float = 2.0
    communication_step: float = 0.01
    # Both RK4s at 1e-4 s.  On chain60, the most demanding example, the two
    # sides' max ν difference in free motion is 1.8e-6 at 1e-3 s, 1.1e-7 at
    # 5e-4 s, 7e-9 at 2.5e-4 s (4th order; both sides add about half) and
    # 4e-10 at 1e-4 s: well inside the 1e-8 tolerance.
    mujoco_step: float = 1e-4
    method: str = "rk4"
    # FMU Real parameters by name, over the defaults of parameters().
    fmu_parameters: dict | None = None
    seed: int = 1
    # The FMU exported and the interface it is run through: "cs" (its own
    # integrator) or "me" (FMPy's CVODE at relative_tolerance).
    fmi_version: int = 2
    interface: str = "cs"
    # 1e-11: at 1e-10 CVODE's own global error on fixed_rig free motion is 5e-8, over the 1e-8
    # tolerance (it falls 10x per decade of rtol; the FMU's derivatives are exact to round-off).
    relative_tolerance: float = 1e-11
    # Bodies exported with --wrench-inputs (their wrenches are inputs; the
    # 'wrenched' scenario drives them).
    wrench_bodies: tuple[str, ...] = ()
    # MuJoCo's twins (judgement.TWINS); each costs one more MuJoCo run. With
    # none the twin divergence is 0, so the verdict is "agrees" or "disagrees":
    # for a caller that asserts the errors against the tolerance itself.
    twins: int = TWINS

    def parameters(self) -> dict[str, float]:
        """RK4's internal step is the one above; an adaptive method keeps
        the FMU's own defaults (its step follows its `tolerance`) unless
        told otherwise."""
        defaults = {"max_step": 1e-4} if self.method == "rk4" else {}
        return {**defaults, **(self.fmu_parameters or {})}

    def check(self) -> None:
        """Refuse steps that do not divide (before any work is done)."""
        self.communication_steps()
        self.mujoco_substeps()

    def communication_steps(self) -> int:
        return _whole_number(self.duration, self.communication_step, "duration", "communication step")

    def mujoco_substeps(self) -> int:
        """MuJoCo steps per communication step: the input changes only at
        communication points, so they must fall on MuJoCo's step boundaries."""
        return _whole_number(self.communication_step, self.mujoco_step, "communication step", "MuJoCo step")


def _whole_number(total: float, step: float, total_name: str, step_name: str) -> int:
    count = round(total / step) if step > 0 else 0
    if count < 1 or abs(count * step - total) > 1e-9 * total:
        raise ValidationError(f"the {step_name} ({step:g} s) must divide the {total_name} ({total:g} s)")
    return count


@dataclass
class Trajectory:
    """One side's samples at the communication points."""

    theta: np.ndarray  # (n + 1, nq)
    nu: np.ndarray  # (n + 1, nv)
    kinetic_energy: np.ndarray  # (n + 1,)
    momentum: np.ndarray  # (n + 1, 6)
    energy: np.ndarray  # (n + 1,) K + U
    sensordata: np.ndarray  # (n + 1, nsensordata): at the state reached, with the inputs held
    act: np.ndarray  # (n + 1, na): the actuators' activation states (MuJoCo's act)
    wall_time: float  # seconds spent integrating


@dataclass
class ScenarioResult:
    scenario: Scenario
    time: np.ndarray  # (n + 1,)
    eps: np.ndarray  # (n, nv): ε held over [t_k, t_k+1]
    ctrl: np.ndarray | None  # (n, nu): the controls held likewise, where the scenario sets them
    fmu: Trajectory
    mujoco: Trajectory
    twins: list[Trajectory]  # MuJoCo again, from qvel + each of twin_nudges, with the same inputs
    quaternion_starts: list[int]  # qpos index of each quaternion (w, x, y, z)
    energy_is_conserved: bool

    def theta_error(self, side: Trajectory | None = None) -> np.ndarray:
        """max_k |θ_side − θ_mujoco| at each time (side: the FMU unless
        given), each quaternion of the side first given the sign nearer
        MuJoCo's (q and −q are the same rotation)."""
        theta = (side or self.fmu).theta.copy()
        for a in self.quaternion_starts:
            block = slice(a, a + 4)
            flip = np.sum(theta[:, block] * self.mujoco.theta[:, block], axis=1) < 0.0
            theta[flip, block] *= -1.0
        return np.max(np.abs(theta - self.mujoco.theta), axis=1, initial=0.0)

    def nu_error(self, side: Trajectory | None = None) -> np.ndarray:
        return np.max(np.abs((side or self.fmu).nu - self.mujoco.nu), axis=1, initial=0.0)

    def sensordata_error(self, side: Trajectory | None = None) -> np.ndarray:
        """max_k |s_side − s_mujoco| / max(1, |s_mujoco|) at each time."""
        reference = self.mujoco.sensordata
        scaled = np.abs((side or self.fmu).sensordata - reference) / np.maximum(1.0, np.abs(reference))
        return np.max(scaled, axis=1, initial=0.0)

    def act_error(self, side: Trajectory | None = None) -> np.ndarray:
        """max_k |act_side − act_mujoco| at each time (0 without activation states)."""
        return np.max(np.abs((side or self.fmu).act - self.mujoco.act), axis=1, initial=0.0)

    def twin_divergence(self) -> np.ndarray:
        """The twins' largest distance from MuJoCo at each time, in the norm
        of the FMU's error: the largest of θ, ν, sensordata and act differences
        (0 without twins)."""
        if not self.twins:
            return np.zeros(len(self.time))
        return np.maximum.reduce(
            [e for twin in self.twins for e in (self.theta_error(twin), self.nu_error(twin),
                                                self.sensordata_error(twin), self.act_error(twin))]
        )

    def kinetic_energy_error(self) -> np.ndarray:
        return np.abs(self.fmu.kinetic_energy - self.mujoco.kinetic_energy)

    def momentum_error(self) -> np.ndarray:
        return np.max(np.abs(self.fmu.momentum - self.mujoco.momentum), axis=1)

    def energy_drift(self, side: Trajectory) -> float | None:
        """max |E(t) − E(0)| with E = K + U, where E is conserved (ε = 0, no
        dampers); None elsewhere."""
        if not self.energy_is_conserved:
            return None
        return float(np.max(np.abs(side.energy - side.energy[0])))

    def summary(self) -> dict:
        theta_error, nu_error = float(np.max(self.theta_error())), float(np.max(self.nu_error()))
        sensordata_error = float(np.max(self.sensordata_error()))
        act_error = float(np.max(self.act_error()))
        error = max(theta_error, nu_error, sensordata_error, act_error)
        twin = float(np.max(self.twin_divergence()))
        verdict = judge(error, twin, self.scenario.tolerance)
        return {
            "scenario": self.scenario.name,
            "description": self.scenario.description,
            "max_theta_error": theta_error,
            "max_nu_error": nu_error,
            "max_sensordata_error": sensordata_error,
            "max_act_error": act_error,
            "max_kinetic_energy_error": float(np.max(self.kinetic_energy_error())),
            "max_momentum_error": float(np.max(self.momentum_error())),
            "kinetic_energy_start": float(self.mujoco.kinetic_energy[0]),
            "energy_drift_fmu": self.energy_drift(self.fmu),
            "energy_drift_mujoco": self.energy_drift(self.mujoco),
            "fmu_seconds": self.fmu.wall_time,
            "mujoco_seconds": self.mujoco.wall_time,
            "tolerance": self.scenario.tolerance,
            "max_twin_divergence": twin,
            "verdict": verdict,
            "passed": passes(verdict),
        }


def quaternion_starts(model: mujoco.MjModel) -> list[int]:
    starts = []
    for j in range(model.njnt):
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            starts.append(int(model.jnt_qposadr[j]) + 3)
        elif model.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL:
            starts.append(int(model.jnt_qposadr[j]))
    return starts


class _Samples:
    """Collects one side's samples, then freezes them into a Trajectory."""

    def __init__(self):
        keys = ("theta", "nu", "kinetic_energy", "momentum", "energy", "sensordata", "act")
        self.rows: dict[str, list] = {k: [] for k in keys}
        self.wall_time = 0.0

    def add(self, theta, nu, kinetic_energy, momentum, potential_energy, sensordata, act):
        for key, value in (
            ("sensordata", sensordata),
            ("act", act),
            ("theta", theta),
            ("nu", nu),
            ("kinetic_energy", kinetic_energy),
            ("momentum", momentum),
            ("energy", kinetic_energy + potential_energy),
        ):
            self.rows[key].append(value)

    def trajectory(self) -> Trajectory:
        return Trajectory(**{k: np.array(v) for k, v in self.rows.items()}, wall_time=self.wall_time)


def open_fmu(package: FmuPackage | None, fmu_path: Path, settings: Settings, theta, nu, unzip_dir: Path):
    """The FMU initialized at (θ, ν), through the version and interface the settings ask for."""
    start = {"method": settings.method, **settings.parameters()}
    if settings.interface == "me":
        return ModelExchange(fmu_path, unzip_dir, start=start, theta=theta, nu=nu,
                             relative_tolerance=settings.relative_tolerance)
    if settings.fmi_version == 3:
        return Fmi3CoSimulation(fmu_path, unzip_dir, start=start, theta=theta, nu=nu)
    return Instance(package, name="validation", start=start, theta=theta, nu=nu)


def run_scenario(package: FmuPackage | None, model_path: Path, scenario: Scenario, settings: Settings,
                 fmu_path: Path | None = None, unzip_dir: Path | None = None) -> ScenarioResult:
    """Run the FMU and MuJoCo in lockstep over settings.duration."""
    h = settings.communication_step
    steps, substeps = settings.communication_steps(), settings.mujoco_substeps()
    mj = MujocoVehicle(model_path, h / substeps)
    mj.set_state(scenario.qpos0, scenario.qvel0)
    twins = []
    for nudge in twin_nudges(len(scenario.qvel0), settings.seed, settings.twins):
        twins.append(MujocoVehicle(model_path, h / substeps))
        twins[-1].set_state(scenario.qpos0, scenario.qvel0 + nudge)
    # The FMU starts from the same θ and from MuJoCo's ν of the same qvel.
    fmu = open_fmu(package, fmu_path, settings, scenario.qpos0, mj.nu(), unzip_dir)
    fmu_samples, mj_samples, twin_samples = _Samples(), _Samples(), [_Samples() for _ in twins]
    held, held_ctrl = [], []

    def sample():
        theta = fmu.array("theta")
        fmu_samples.add(theta, fmu.array("nu"), fmu.real("kinetic_energy"), fmu.array("momentum"),
                        mj.potential_energy_at(theta), fmu.array("sensordata"), fmu.array("act"))
        for side, samples in ((mj, mj_samples), *zip(twins, twin_samples)):
            samples.add(side.theta(), side.nu(), side.kinetic_energy(), side.momentum(), side.potential_energy(),
                        side.data.sensordata.copy(), side.data.act.copy())

    try:
        sample()
        for k in range(steps):
            t = k * h
            eps = np.asarray(scenario.eps_law(t, fmu_samples.rows["nu"][-1]), float)
            held.append(eps)
            ctrl = None if scenario.ctrl_law is None else np.asarray(scenario.ctrl_law(k), float)
            held_ctrl.append(ctrl)
            wrenches = None if scenario.wrench_law is None else scenario.wrench_law(k)
            start = time.perf_counter()
            try:
                fmu.set_array("eps", eps)
                if ctrl is not None:
                    fmu.set_array("ctrl", ctrl)
                if wrenches is not None:
                    fmu.set_array("xfrc_applied", wrenches.ravel())
                fmu.step(h, communication_point=t)
            except FMICallException as e:
                raise ValidationError(
                    f"{scenario.name}: the FMU failed the step from t = {t:g} s: {e} ({fmu.log.last_problem()})"
                ) from None
            fmu_samples.wall_time += time.perf_counter() - start
            wrench_by_body = None if wrenches is None else dict(zip(scenario.wrench_bodies, wrenches))
            start = time.perf_counter()
            mj.advance(eps, substeps, ctrl, wrench_by_body)
            mj_samples.wall_time += time.perf_counter() - start
            for twin in twins:
                twin.advance(eps, substeps, ctrl, wrench_by_body)
            for label, side in (("", mj), *(("'s twin", twin) for twin in twins)):
                problem = side.instability()
                if problem:
                    raise ValidationError(
                        f"{scenario.name}: MuJoCo{label}'s simulation became unstable ({problem}) "
                        f"between t = {t:g} s and {t + h:g} s; try a smaller --mujoco-step"
                    )
            sample()
    finally:
        fmu.close()

    return ScenarioResult(
        scenario=scenario,
        time=h * np.arange(steps + 1),
        eps=np.array(held),
        ctrl=None if scenario.ctrl_law is None else np.array(held_ctrl),
        fmu=fmu_samples.trajectory(),
        mujoco=mj_samples.trajectory(),
        twins=[samples.trajectory() for samples in twin_samples],
        quaternion_starts=quaternion_starts(mj.model),
        energy_is_conserved=scenario.unforced and mj.conserves_energy_unforced,
    )


def check_real_parameters(package: FmuPackage, parameters: dict[str, float]) -> None:
    known = sorted(package.parameters("Real"))
    unknown = sorted(set(parameters) - set(known))
    if unknown:
        raise ValidationError(f"the FMU has no Real parameter {', '.join(unknown)} (it has: {', '.join(known)})")


@dataclass
class ModelValidation:
    model_path: Path
    fmu_path: Path
    settings: Settings
    results: list[ScenarioResult]
    # A vehicle with modal bodies: `results` compare the FMU with its modes
    # frozen (`rigid_fmu_path`) with MuJoCo; `modal` is the FMU with them
    # (`fmu_path`) over the same inputs, per scenario (modal_part.py).
    modal: list[ModalPart] | None = None
    rigid_fmu_path: Path | None = None

    @property
    def passed(self) -> bool:
        return all(r.summary()["passed"] for r in self.results)


def validate_model(
    model_path: Path,
    fmu_path: Path,
    nudyn: Path,
    scenario_names: list[str] | None = None,
    settings: Settings | None = None,
) -> ModelValidation:
    """Export model_path to fmu_path and run every scenario (all that apply
    when scenario_names is None)."""
    settings = settings or Settings()
    settings.check()
    # nudyn's importer first: its messages name the unsupported element.
    options = {"fmi_version": settings.fmi_version, "wrench_inputs": settings.wrench_bodies}
    Nudyn(nudyn).export(model_path, fmu_path, outputs=EXTRA_OUTPUTS, **options)
    try:
        files = modal_files(load_model(model_path), model_path)
    except ValueError as e:
        raise ValidationError(str(e)) from None
    if not files:
        return run_scenarios(model_path, fmu_path, scenario_names, settings)
    # MuJoCo's twin is the rigid vehicle: the comparison is of the modes frozen.
    Nudyn(nudyn).export(model_path, fmu_path, outputs=EXTRA_OUTPUTS + MODAL_OUTPUTS, **options)
    rigid_fmu = fmu_path.with_name(f"{fmu_path.stem}.rigid.fmu")
    try:
        export_frozen(nudyn, model_path, files, rigid_fmu, outputs=EXTRA_OUTPUTS, **options)
    except FreezeError as e:
        raise ValidationError(str(e)) from None
    validation = run_scenarios(model_path, rigid_fmu, scenario_names, settings)
    validation.fmu_path, validation.rigid_fmu_path = fmu_path, rigid_fmu
    validation.modal = [run_modal_part(fmu_path, nudyn, model_path, r, settings, open_fmu) for r in validation.results]
    return validation


def run_scenarios(
    model_path: Path, fmu_path: Path, scenario_names: list[str] | None, settings: Settings
) -> ModelValidation:
    """Run the scenarios on an FMU exported from model_path with
    EXTRA_OUTPUTS (and the settings' FMI version and wrench inputs)."""
    settings.check()
    try:
        model = load_model(model_path)
        names = scenario_names or default_scenarios(model, settings.wrench_bodies)
        scenarios = [make_scenario(name, model, settings.seed, settings.wrench_bodies) for name in names]
    except ValueError as e:
        raise ValidationError(str(e)) from None
    if settings.fmi_version != 2 or settings.interface != "cs":
        with tempfile.TemporaryDirectory(prefix="nudyn-fmu-") as unzip_dir:
            results = [run_scenario(None, model_path, s, settings, fmu_path, Path(unzip_dir) / s.name)
                       for s in scenarios]
        return ModelValidation(model_path, fmu_path, settings, results)
    with tempfile.TemporaryDirectory(prefix="nudyn-fmu-") as unzip_dir:
        package = FmuPackage.unzip(fmu_path, Path(unzip_dir))
        check_real_parameters(package, settings.parameters())
        if (package.nq, package.nv) != (model.nq, model.nv):
            raise ValidationError(
                f"the FMU has nq = {package.nq}, nv = {package.nv} but MuJoCo's model has "
                f"nq = {model.nq}, nv = {model.nv}"
            )
        results = [run_scenario(package, model_path, s, settings) for s in scenarios]
    return ModelValidation(model_path, fmu_path, settings, results)
