"""The FMU side: export with `nudyn export`, and one FMPy FMU2Slave instance
started from a chosen state and stepped with a held ε."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

# The optional outputs the comparison reads besides theta and nu.
EXTRA_OUTPUTS = "kinetic_energy,momentum"


class ValidationError(Exception):
    """A problem with the user's input or set-up, reported as a message."""


def export_fmu(nudyn: Path, model_path: Path, fmu_path: Path) -> Path:
    """`nudyn export MODEL -o FMU --outputs kinetic_energy,momentum`; the
    importer's message (element, line) is passed on when it refuses the MJCF."""
    if not nudyn.is_file():
        raise ValidationError(
            f"nudyn binary not found at {nudyn}: build it with `cargo build --release --workspace`"
        )
    cmd = [str(nudyn), "export", str(model_path), "-o", str(fmu_path), "--outputs", EXTRA_OUTPUTS]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise ValidationError(f"`{' '.join(cmd)}` failed:\n{proc.stderr.strip()}")
    return fmu_path


class FmuPackage:
    """An exported FMU, unzipped once, from which instances are made."""

    def __init__(self, fmu_path: Path, unzip_dir: Path):
        self.description = read_model_description(str(fmu_path))
        self.unzip_dir = extract(str(fmu_path), str(unzip_dir))
        self.variables = {v.name: v for v in self.description.modelVariables}
        self.nq = self._count("theta")
        self.nv = self._count("nu")

    def _count(self, prefix: str) -> int:
        return sum(1 for name in self.variables if name.startswith(prefix + "["))

    def method_value(self, item_name: str) -> int:
        """The value of the `method` enumeration item called item_name."""
        items = self.variables["method"].declaredType.items
        for item in items:
            if item.name == item_name:
                return int(item.value)
        names = ", ".join(item.name for item in items)
        raise ValidationError(f"the FMU has no integration method '{item_name}' (it has: {names})")

    def check_real_parameters(self, parameters: dict[str, float]) -> None:
        known = sorted(
            v.name for v in self.variables.values() if v.causality == "parameter" and v.type == "Real"
        )
        unknown = sorted(set(parameters) - set(known))
        if unknown:
            raise ValidationError(
                f"the FMU has no Real parameter {', '.join(unknown)} (it has: {', '.join(known)})"
            )


class FmuVehicle:
    """One initialized FMU instance; theta and nu chosen before
    fmi2ExitInitializationMode (they are initial="exact")."""

    def __init__(self, package: FmuPackage, method: str, parameters: dict[str, float], theta0, nu0):
        package.check_real_parameters(parameters)
        self.vr = {name: v.valueReference for name, v in package.variables.items()}
        self._theta = self._refs("theta", package.nq)
        self._nu = self._refs("nu", package.nv)
        self._eps = self._refs("eps", package.nv)
        self._momentum = self._refs("momentum", 6)
        self.fmu = FMU2Slave(
            guid=package.description.guid,
            unzipDirectory=package.unzip_dir,
            modelIdentifier=package.description.coSimulation.modelIdentifier,
            instanceName="validation",
        )
        self.fmu.instantiate()
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.setInteger([self.vr["method"]], [package.method_value(method)])
        if parameters:
            self.fmu.setReal([self.vr[name] for name in parameters], list(parameters.values()))
        self.fmu.setReal(self._theta + self._nu, [*map(float, theta0), *map(float, nu0)])
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()

    def _refs(self, prefix: str, count: int) -> list[int]:
        return [self.vr[f"{prefix}[{k}]"] for k in range(1, count + 1)]

    def do_step(self, time: float, step: float, eps) -> None:
        self.fmu.setReal(self._eps, list(map(float, eps)))
        self.fmu.doStep(currentCommunicationPoint=time, communicationStepSize=step)

    def theta(self) -> np.ndarray:
        return np.array(self.fmu.getReal(self._theta))

    def nu(self) -> np.ndarray:
        return np.array(self.fmu.getReal(self._nu))

    def kinetic_energy(self) -> float:
        return self.fmu.getReal([self.vr["kinetic_energy"]])[0]

    def momentum(self) -> np.ndarray:
        return np.array(self.fmu.getReal(self._momentum))

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()
