"""The FMU under stress: instances with a chosen method, tolerance,
max_step and energy projection, stepped with every status and logged
message kept, since a refused call or a discarded step is a result here,
not a crash."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import fmi2OK

from nudyn_driver.instance import Instance, status_of
from nudyn_driver.package import FmuPackage

# Every optional output: the invariants (K, momentum) and the integration's
# own energy error are what the suite watches.
OUTPUTS = ("kinetic_energy", "momentum", "energy_residual")


@dataclass
class Setup:
    """How one instance integrates: the FMU's parameters."""

    method: str = "dop853"
    tolerance: float | None = None  # None: the FMU's default
    max_step: float | None = None  # None: the FMU's default
    energy_projection: bool = False

    def start(self) -> dict:
        """The FMU's parameters, by name; those left None keep the FMU's default."""
        reals = {"tolerance": self.tolerance, "max_step": self.max_step}
        return {"method": self.method, **{name: value for name, value in reals.items() if value is not None},
                "energy_projection": self.energy_projection}

    def label(self) -> str:
        parts = [self.method]
        if self.method != "rk4" and self.tolerance is not None:
            parts.append(f"tol {self.tolerance:g}")
        if self.max_step is not None:
            parts.append(f"max_step {self.max_step:g}")
        if self.energy_projection:
            parts.append("projected")
        return ", ".join(parts)


def start_instance(package: FmuPackage, setup: Setup, theta0, nu0) -> Instance:
    """An instance at (θ₀, ν₀) with a Setup, logging on: fmi2DoStep's
    logStepStatistics messages give the internal step counts."""
    return Instance(package, name="stress", start=setup.start(), theta=theta0, nu=nu0, logging_on=True)


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
        """Reads the state and the outputs; an output the FMU refuses (with
        fmi2Error: K, say, overflows on a state that an unstable run left
        huge but finite) is recorded as NaN, and the refusal kept as the
        run's message."""
        def read(get, name, series):
            try:
                return get(name)
            except FMICallException:
                self.message = self.message or instance.log.last_problem()
                return np.full_like(series[-1], np.nan) if series else np.nan

        self.time.append(instance.time)
        for get, name, series in ((instance.array, "theta", self.theta), (instance.array, "nu", self.nu),
                                  (instance.real, "kinetic_energy", self.kinetic_energy),
                                  (instance.array, "momentum", self.momentum),
                                  (instance.real, "energy_residual", self.energy_residual)):
            series.append(read(get, name, series))

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


def simulate(package: FmuPackage, setup: Setup, theta0, nu0, duration: float, comm_step: float, eps_law=None) -> Run:
    """Runs one instance from (θ₀, ν₀) for `duration` in communication
    steps of `comm_step`, ε = eps_law(t) held over each step (0 if None);
    stops at the first step that is not fmi2OK."""
    fmu = start_instance(package, setup, theta0, nu0)
    run = Run(setup)
    steps = round(duration / comm_step)
    try:
        run.sample(fmu)
        for k in range(steps):
            if eps_law is not None:
                status_of(fmu.set_array, "eps", eps_law(k * comm_step))
            start = time.perf_counter()
            run.status = status_of(fmu.step, comm_step)
            run.wall_time += time.perf_counter() - start
            run.do_steps += 1
            if run.status != fmi2OK:
                run.message = fmu.log.last_problem()
            run.sample(fmu)
            if run.status != fmi2OK:
                break
    finally:
        run.steps_taken, run.steps_rejected = fmu.log.internal_steps()
        run.held_tolerance = fmu.log.held_tolerance()
        fmu.close()
    return run
