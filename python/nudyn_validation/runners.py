"""The FMU side of a validation run through the interfaces other than FMI 2.0
co-simulation (which `nudyn_driver.instance.Instance` drives): FMI 3.0
co-simulation, and model exchange of either version under FMPy's CVODE.
Each offers what `compare.run_scenario` uses of an Instance: `array`,
`real`, `set_array`, `step`, `close` and `log.last_problem()`."""

from __future__ import annotations

from ctypes import c_double
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Model
from fmpy.fmi3 import FMU3Model, FMU3Slave
from fmpy.sundials import CVodeSolver
from nudyn_driver.instance import Log


class Messages:
    """What an FMI 3.0 FMU logged, as (status, category, message) (FMI 2.0:
    `nudyn_driver.instance.Log`)."""

    def __init__(self):
        self.messages: list[tuple[int, str, str]] = []

    def fmi3(self, _env, status, category, message):
        self.messages.append((status, category.decode(), message.decode(errors="replace")))

    def last_problem(self) -> str:
        return next((m for _, c, m in reversed(self.messages) if c != "logCalls"), "")


class _Variables:
    """Names to value references and sizes: FMI 3.0 arrays, or FMI 2.0 `name[k]` scalars."""

    def __init__(self, description):
        self.version = 3 if description.fmiVersion.startswith("3") else 2
        self.by_name = {v.name: v for v in description.modelVariables}
        self.items = {t.name: {item.name: item.value for item in t.items}
                      for t in description.typeDefinitions if getattr(t, "items", None)}

    def references(self, name: str) -> list[int]:
        if self.version == 3:
            return [self.by_name[name].valueReference]
        k, found = 1, []
        while f"{name}[{k}]" in self.by_name:
            found.append(self.by_name[f"{name}[{k}]"].valueReference)
            k += 1
        return found or [self.by_name[name].valueReference]

    def has(self, name: str) -> bool:
        return name in self.by_name or f"{name}[1]" in self.by_name

    def size(self, name: str) -> int:
        if self.version == 3:
            variable = self.by_name[name]
            return int(np.prod([int(d.start) for d in variable.dimensions])) if variable.dimensions else 1
        return len(self.references(name))

    def enumeration_value(self, name: str, item: str) -> int:
        return int(self.items[self.by_name[name].declaredType.name][item])


def _start(fmu, variables: _Variables, start: dict, theta, nu) -> None:
    """Parameters by name (the method by item name), then θ and ν, before initialization."""
    reals = {name: value for name, value in start.items() if name != "method"}
    arrays = {"theta": theta, "nu": nu}
    if variables.version == 3:
        if "method" in start:
            fmu.setInt64([variables.by_name["method"].valueReference],
                         [variables.enumeration_value("method", start["method"])])
        for name, value in reals.items():
            fmu.setFloat64(variables.references(name), [float(value)])
        for name, values in arrays.items():
            fmu.setFloat64(variables.references(name), [float(v) for v in values])
    else:
        if "method" in start:
            fmu.setInteger([variables.by_name["method"].valueReference],
                           [variables.enumeration_value("method", start["method"])])
        for name, value in reals.items():
            fmu.setReal(variables.references(name), [float(value)])
        for name, values in arrays.items():
            fmu.setReal(variables.references(name), [float(v) for v in values])


class _Reading:
    """`array`, `real` and `set_array` over either version's getters and setters."""

    fmu = None
    variables: _Variables

    def array(self, name: str) -> np.ndarray:
        if not self.variables.has(name):  # an array of no entries (no sensors, no actuators)
            return np.zeros(0)
        refs, n = self.variables.references(name), self.variables.size(name)
        if self.variables.version == 3:
            return np.array(self.fmu.getFloat64(refs, n))
        return np.array(self.fmu.getReal(refs))

    def real(self, name: str) -> float:
        return float(self.array(name)[0])

    def set_array(self, name: str, values) -> None:
        values = [float(v) for v in values]
        if self.variables.version == 3:
            self.fmu.setFloat64(self.variables.references(name), values)
        else:
            self.fmu.setReal(self.variables.references(name), values)


class Fmi3CoSimulation(_Reading):
    """An FMI 3.0 FMU in co-simulation, initialized from θ, ν and `start`."""

    def __init__(self, fmu_path: Path, unzip_dir: Path, *, start: dict, theta, nu):
        description = read_model_description(str(fmu_path))
        self.variables = _Variables(description)
        self.log = Messages()
        directory = extract(str(fmu_path), str(unzip_dir))
        self.fmu = FMU3Slave(guid=description.instantiationToken, unzipDirectory=directory,
                             modelIdentifier=description.coSimulation.modelIdentifier, instanceName="validation")
        self.fmu.instantiate(logMessage=self.log.fmi3)
        self.fmu.enterInitializationMode(startTime=0.0)
        _start(self.fmu, self.variables, start, theta, nu)
        self.fmu.exitInitializationMode()

    def step(self, size: float, communication_point: float) -> None:
        self.fmu.doStep(communication_point, size)

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()


class _NoInputs:
    """FMPy's CVODE wrapper applies inputs in its root function; the inputs here are set between steps."""

    def apply(self, _time):
        pass


class ModelExchange(_Reading):
    """A model-exchange FMU (FMI 2.0 or 3.0) integrated by FMPy's CVODE at
    `relative_tolerance`, restarted at a communication point when a held
    input (ε, ctrl) jumps there (when one does)."""

    def __init__(self, fmu_path: Path, unzip_dir: Path, *, start: dict, theta, nu, relative_tolerance: float):
        description = read_model_description(str(fmu_path))
        self.variables = _Variables(description)
        self.log = Messages()
        directory = extract(str(fmu_path), str(unzip_dir))
        identifier = description.modelExchange.modelIdentifier
        start = {name: value for name, value in start.items() if name == "method"}
        if self.variables.version == 3:
            self.fmu = FMU3Model(guid=description.instantiationToken, unzipDirectory=directory,
                                 modelIdentifier=identifier, instanceName="validation")
            self.fmu.instantiate(logMessage=self.log.fmi3)
            self.fmu.enterInitializationMode(startTime=0.0)
            _start(self.fmu, self.variables, start, theta, nu)
            self.fmu.exitInitializationMode()
            self.fmu.updateDiscreteStates()
            derivatives = self.fmu.getContinuousStateDerivatives
        else:
            self.fmu = FMU2Model(guid=description.guid, unzipDirectory=directory, modelIdentifier=identifier,
                                 instanceName="validation")
            self.log = Log()
            self.fmu.instantiate(callbacks=self.log.callbacks)
            self.fmu.setupExperiment(startTime=0.0)
            self.fmu.enterInitializationMode()
            _start(self.fmu, self.variables, start, theta, nu)
            self.fmu.exitInitializationMode()
            self.fmu.newDiscreteStates()
            derivatives = self.fmu.getDerivatives
        self.fmu.enterContinuousTimeMode()
        self.nx = self.variables.size("theta") + self.variables.size("nu")
        self.held: dict[str, list[float]] = {}
        self.restart = False
        self.solver = CVodeSolver(
            nx=self.nx, nz=0, get_x=self.fmu.getContinuousStates, set_x=self.fmu.setContinuousStates,
            get_dx=derivatives, get_z=lambda z, n: None, get_nominals=self.fmu.getNominalsOfContinuousStates,
            set_time=self.fmu.setTime, input=_NoInputs(), startTime=0.0, relativeTolerance=relative_tolerance,
            maxNumSteps=100000,
        )

    def set_array(self, name: str, values) -> None:
        values = [float(v) for v in values]
        if values != self.held.get(name, [0.0] * len(values)):
            # The solver's history does not hold across a jump in the inputs.
            self.restart = True
            self.held[name] = values
        super().set_array(name, values)

    def step(self, size: float, communication_point: float) -> None:
        if self.restart:
            self.solver.reset(communication_point)
            self.restart = False
        _, _, reached = self.solver.step(communication_point, communication_point + size)
        self.fmu.setTime(reached)
        self.fmu.completedIntegratorStep()

    def states(self) -> np.ndarray:
        x = (c_double * self.nx)()
        self.fmu.getContinuousStates(x, self.nx)
        return np.array(x)

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()
