"""The FMU under stress: exported once per vehicle, then instances with a
chosen method, tolerance, max_step and energy projection, stepped through
FMPy's FMU2Slave with every status and logged message kept, since a refused
call or a discarded step is a result here, not a crash."""

from __future__ import annotations

import os
import re
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2LastSuccessfulTime,
    fmi2Terminated,
)

# Every optional output: the invariants (K, momentum) and the integration's
# own energy error are what the suite watches.
OUTPUTS = "kinetic_energy,momentum,energy_residual"

FMI_STATUS = {0: "fmi2OK", 1: "fmi2Warning", 2: "fmi2Discard", 3: "fmi2Error", 4: "fmi2Fatal", 5: "fmi2Pending"}


class StressError(Exception):
    """The suite cannot run (a missing binary, an export that fails)."""


def export(nudyn: Path, model: Path, fmu: Path) -> Path:
    fmu.parent.mkdir(parents=True, exist_ok=True)
    cmd = [str(nudyn), "export", str(model), "-o", str(fmu), "--outputs", OUTPUTS]
    fmu_lib = nudyn.parent / "libnudyn_fmu.so"
    env = {**os.environ, "NUDYN_FMU_LIB": str(fmu_lib)} if fmu_lib.is_file() else None
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        raise StressError(f"`{' '.join(cmd)}` failed:\n{proc.stderr.strip()}")
    return fmu


class Package:
    """An exported FMU, unzipped once; instances are made from it."""

    def __init__(self, fmu: Path, unzip_dir: Path):
        self.path = fmu
        self.description = read_model_description(str(fmu))
        self.unzip_dir = extract(str(fmu), str(unzip_dir))
        self.vr = {v.name: v.valueReference for v in self.description.modelVariables}
        self.nq = sum(1 for name in self.vr if name.startswith("theta["))
        self.nv = sum(1 for name in self.vr if name.startswith("nu["))
        method = next(t for t in self.description.typeDefinitions if t.name == "Method")
        self.methods = {item.name: int(item.value) for item in method.items}
        theta = [v for v in self.description.modelVariables if v.name.startswith("theta[")]
        # Each quaternion's w (qpos index): q and −q are the same rotation.
        self.quaternion_starts = [k for k, v in enumerate(theta) if "quaternion w" in v.description]

    def refs(self, prefix: str, count: int) -> list[int]:
        return [self.vr[f"{prefix}[{k}]"] for k in range(1, count + 1)]


class Log:
    """An FMPy logger that keeps (status, category, message), except the
    logCalls debug messages, of which it counts the internal steps that
    fmi2DoStep reports."""

    STEPS = re.compile(r"fmi2DoStep: (\d+) internal steps taken, (\d+) rejected")

    def __init__(self):
        self.messages: list[tuple[int, str, str]] = []
        self.steps_taken = 0
        self.steps_rejected = 0
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(self._log)
        self.callbacks.allocateMemory = fmi2CallbackFunctions._fields_[1][1](lambda n, size: None)
        self.callbacks.freeMemory = fmi2CallbackFunctions._fields_[2][1](lambda p: None)

    def _log(self, _env, _name, status, category, message):
        category, message = category.decode(), message.decode()
        if category != "logCalls":
            self.messages.append((status, category, message))
        elif steps := self.STEPS.match(message):
            self.steps_taken += int(steps.group(1))
            self.steps_rejected += int(steps.group(2))

    def held_tolerance(self) -> float | None:
        """The per-second tolerance the FMU last said it held instead of
        the one asked for (round-off in the rates), if it said so."""
        held = [re.search(r"held to (\S+) per second", m) for _, c, m in self.messages if c == "logStatusWarning"]
        return float(held[-1].group(1)) if held else None

    def last(self) -> str:
        return self.messages[-1][2] if self.messages else ""


@dataclass
class Setup:
    """How one instance integrates: the FMU's parameters."""

    method: str = "dop853"
    tolerance: float | None = None  # None: the FMU's default
    max_step: float | None = None  # None: the FMU's default
    energy_projection: bool = False

    def label(self) -> str:
        parts = [self.method]
        if self.method != "rk4" and self.tolerance is not None:
            parts.append(f"tol {self.tolerance:g}")
        if self.max_step is not None:
            parts.append(f"max_step {self.max_step:g}")
        if self.energy_projection:
            parts.append("projected")
        return ", ".join(parts)


class Instance:
    """One FMU instance, initialized at (θ₀, ν₀) with a Setup."""

    def __init__(self, package: Package, setup: Setup, theta0, nu0, name: str = "stress"):
        self.package = package
        self.setup = setup
        self.log = Log()
        self.fmu = FMU2Slave(
            guid=package.description.guid,
            unzipDirectory=package.unzip_dir,
            modelIdentifier=package.description.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.fmu.instantiate(callbacks=self.log.callbacks, loggingOn=True)  # logCalls: the step counts
        self.fmu.setupExperiment(startTime=0.0)
        vr = package.vr
        self.fmu.setInteger([vr["method"]], [package.methods[setup.method]])
        reals = {"tolerance": setup.tolerance, "max_step": setup.max_step}
        for name, value in reals.items():
            if value is not None:
                self.fmu.setReal([vr[name]], [value])
        self.fmu.setBoolean([vr["energy_projection"]], [setup.energy_projection])
        self._theta = package.refs("theta", package.nq)
        self._nu = package.refs("nu", package.nv)
        self._eps = package.refs("eps", package.nv)
        self._momentum = package.refs("momentum", 6)
        self.fmu.setReal(self._theta + self._nu, [*map(float, theta0), *map(float, nu0)])
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        self.time = 0.0

    def set_eps(self, eps) -> int:
        """Sets ε; returns the status (the FMU refuses non-finite values)."""
        try:
            self.fmu.setReal(self._eps, list(map(float, eps)))
        except FMICallException as e:
            return e.status
        return 0

    def do_step(self, step: float) -> int:
        """One doStep from the current time; returns the status.  On a
        discard the time becomes fmi2LastSuccessfulTime."""
        try:
            self.fmu.doStep(currentCommunicationPoint=self.time, communicationStepSize=step)
        except FMICallException as e:
            self.time = self.last_successful_time()
            return e.status
        self.time += step
        return 0

    def last_successful_time(self) -> float:
        return self.fmu.getRealStatus(fmi2LastSuccessfulTime)

    def terminated(self) -> bool:
        return bool(self.fmu.getBooleanStatus(fmi2Terminated))

    def theta(self) -> np.ndarray:
        return np.array(self.fmu.getReal(self._theta))

    def nu(self) -> np.ndarray:
        return np.array(self.fmu.getReal(self._nu))

    def kinetic_energy(self) -> float:
        return self.fmu.getReal([self.package.vr["kinetic_energy"]])[0]

    def energy_residual(self) -> float:
        return self.fmu.getReal([self.package.vr["energy_residual"]])[0]

    def momentum(self) -> np.ndarray:
        return np.array(self.fmu.getReal(self._momentum))

    def all_reals(self) -> np.ndarray:
        refs = [v.valueReference for v in self.package.description.modelVariables if v.type == "Real"]
        return np.array(self.fmu.getReal(refs))

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()


@dataclass
class Run:
    """Samples of one instance at its communication points."""

    setup: Setup
    time: list[float] = field(default_factory=list)
    theta: list[np.ndarray] = field(default_factory=list)
    nu: list[np.ndarray] = field(default_factory=list)
    kinetic_energy: list[float] = field(default_factory=list)
    momentum: list[np.ndarray] = field(default_factory=list)
    energy_residual: list[float] = field(default_factory=list)
    wall_time: float = 0.0  # seconds inside fmi2DoStep
    do_steps: int = 0
    status: int = 0  # of the last doStep
    message: str = ""  # the FMU's message when a step failed
    steps_taken: int = 0  # internal steps, as the FMU reports them
    steps_rejected: int = 0
    held_tolerance: float | None = None  # set when the FMU relaxed the tolerance

    def sample(self, instance: Instance) -> None:
        self.time.append(instance.time)
        self.theta.append(instance.theta())
        self.nu.append(instance.nu())
        self.kinetic_energy.append(instance.kinetic_energy())
        self.momentum.append(instance.momentum())
        self.energy_residual.append(instance.energy_residual())

    @property
    def completed(self) -> bool:
        return self.status == 0

    def arrays(self) -> dict[str, np.ndarray]:
        return {
            "time": np.array(self.time),
            "theta": np.array(self.theta),
            "nu": np.array(self.nu),
            "kinetic_energy": np.array(self.kinetic_energy),
            "momentum": np.array(self.momentum),
            "energy_residual": np.array(self.energy_residual),
        }


def simulate(package: Package, setup: Setup, theta0, nu0, duration: float, comm_step: float, eps_law=None) -> Run:
    """Runs one instance from (θ₀, ν₀) for `duration` in communication
    steps of `comm_step`, ε = eps_law(t) held over each step (0 if None);
    stops at the first step that is not fmi2OK."""
    instance = Instance(package, setup, theta0, nu0)
    run = Run(setup)
    steps = round(duration / comm_step)
    try:
        run.sample(instance)
        for k in range(steps):
            if eps_law is not None:
                instance.set_eps(eps_law(k * comm_step))
            start = time.perf_counter()
            run.status = instance.do_step(comm_step)
            run.wall_time += time.perf_counter() - start
            run.do_steps += 1
            run.sample(instance)
            if run.status != 0:
                run.message = instance.log.last()
                break
    finally:
        run.steps_taken, run.steps_rejected = instance.log.steps_taken, instance.log.steps_rejected
        run.held_tolerance = instance.log.held_tolerance()
        instance.close()
    return run
