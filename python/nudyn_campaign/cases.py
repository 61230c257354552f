"""What a worker does: fly a chunk of cases through the campaign's FMUs.

Each chunk extracts its FMUs into a temporary folder of its own, removed
when the chunk ends however it ends (inside the Dask worker's own folder,
which Dask purges once it finds the worker dead, so that a worker killed
mid-chunk leaves nothing behind either), and makes one instance per FMU; between
cases it resets them (fmi2Reset) rather than instantiating again. A case
that the FMU refuses or discards is a row with its status and message,
never an exception.
"""

from __future__ import annotations

import hashlib
import importlib
import io
import math
import tempfile
import zipfile
from pathlib import Path

import numpy as np
from fmpy.fmi1 import FMICallException

from nudyn_driver.errors import DriverError
from nudyn_driver.instance import Instance
from nudyn_driver.package import FmuPackage
from nudyn_validation.mujoco_reference import Reference

from .metrics import metrics

# The MuJoCo reference (qvel → ν) of the vehicle, by the MJCF text's hash.
_REFERENCES: dict[str, Reference] = {}
STATUS = {1: "warning", 2: "discard", 3: "error", 4: "fatal"}


def _package(fmu: bytes, directory: Path) -> FmuPackage:
    """The FMU `fmu` extracted into `directory`."""
    with zipfile.ZipFile(io.BytesIO(fmu)) as zipped:
        zipped.extractall(directory)
    return FmuPackage(directory)


def _scratch_parent() -> str | None:
    """Where a chunk's temporary folders go: the Dask worker's own folder
    when a worker runs the chunk (a worker killed with SIGKILL, by a user or
    a cluster's preemption, cannot remove its files; the next worker started
    on that machine purges the folder of a dead one), else the temporary
    directory."""
    try:
        from distributed import get_worker

        return get_worker().local_directory
    except (ImportError, ValueError):  # not in a worker
        return None


def _reference(mjcf: str) -> Reference:
    key = hashlib.sha256(mjcf.encode()).hexdigest()
    if key not in _REFERENCES:
        # MuJoCo reads the model whole: the file is not needed once it is loaded.
        with tempfile.TemporaryDirectory(prefix="nudyn-campaign-", dir=_scratch_parent()) as directory:
            path = Path(directory) / "model.xml"
            path.write_text(mjcf)
            _REFERENCES[key] = Reference.from_file(path)
    return _REFERENCES[key]


def _split(drawn: dict, names: dict) -> tuple[dict, dict, dict]:
    """The case's values as (plant values by FMU name, controller values by
    FMU name, qvel entries by 0-based index); `names` maps each key to the
    variables it sets and its scope."""
    plant, controller, qvel = {}, {}, {}
    for key, value in drawn.items():
        scope, variables = names[key]
        values = value if isinstance(value, list) else [value] * len(variables)
        for variable, v in zip(variables, values):
            if variable.startswith("qvel["):
                qvel[int(variable[5:-1]) - 1] = v
            elif scope == "controller":
                controller[variable] = v
            else:
                plant[variable.removeprefix("plant.")] = v
    return plant, controller, qvel


def _expand(package: FmuPackage, values: dict) -> dict:
    """A parameter given without an index (c1) sets every entry (c1[1..])."""
    out = {}
    for name, value in values.items():
        entries = package.names(name)
        out.update({entry: value for entry in entries} if entries else {name: value})
    return out


class _NonFinite(Exception):
    """The FMU handed out a non-finite value with fmi2OK."""


class _Flight:
    """One case's samples at the communication points."""

    def __init__(self, steps: int, nv: int, nu: int, controller: bool):
        self.time = np.zeros(steps + 1)
        self.ctrl = np.zeros((steps, nu))  # the actuators' controls held over each step
        self.nu = np.full((steps + 1, nv), np.nan)
        self.kinetic_energy = np.full(steps + 1, np.nan)
        self.momentum = np.full((steps + 1, 6), np.nan)
        self.eps = np.zeros((steps, nv))
        self.target_error = np.full(steps + 1, np.nan) if controller else None
        self.reached = 0  # samples taken

    def sample(self, k: int, plant: Instance, controller: Instance | None) -> None:
        self.nu[k] = plant.array("nu")
        self.kinetic_energy[k] = plant.real("kinetic_energy")
        self.momentum[k] = plant.array("momentum")
        if controller is not None:
            self.target_error[k] = float(np.linalg.norm(controller.array("target_error")))
        self.reached = k + 1


def run_chunk(spec: dict, plant_fmu: bytes, controller_fmu: bytes | None, mjcf: str | None, cases: list[tuple[int, dict]]) -> list[dict]:
    """Rows (drawn values, metrics, status, message) of `cases`: pairs of
    the case index and its drawn values. `mjcf` (for qvel) is None for a
    system file's FMUs."""
    with tempfile.TemporaryDirectory(prefix="nudyn-campaign-", dir=_scratch_parent()) as scratch:
        plant_package = _package(plant_fmu, Path(scratch) / "plant")
        controller_package = None
        if controller_fmu is not None:
            controller_package = _package(controller_fmu, Path(scratch) / "controller")
        return _fly_chunk(spec, plant_package, controller_package, mjcf, cases)


def _fly_chunk(spec: dict, plant_package: FmuPackage, controller_package: FmuPackage | None, mjcf: str | None,
               cases: list[tuple[int, dict]]) -> list[dict]:
    """run_chunk's rows, from the FMUs extracted; the instances are closed before it returns."""
    reference = _reference(mjcf) if mjcf is not None else None
    names = {key: (scope, tuple(variables)) for key, scope, variables in spec["targets"]}
    custom = [_function(name) for name in spec["metrics"]]
    plant = controller = None
    rows = []
    try:
        for case, drawn in cases:
            row = {"case": case, **{key: value for key, value in drawn.items()}}
            plant_values, controller_values, qvel = _split(drawn, names)
            start = {**spec["plant_parameters"], **plant_values}
            # The plant's own start (qpos0, or a system file's values).
            theta = np.array(plant_package.starts("theta"))
            for name, value in start.items():
                if name.startswith("theta["):
                    theta[int(name[6:-1]) - 1] = value
            nu = None
            if qvel:
                velocity = np.zeros(plant_package.nv)
                for index, value in qvel.items():
                    velocity[index] = value
                nu = reference.nu(theta, velocity)
            start = {name: value for name, value in start.items() if not name.startswith("theta[")}
            steps = round(spec["duration"] / spec["step"])
            flight = _Flight(steps, plant_package.nv, len(plant_package.names("ctrl")), controller_package is not None)
            try:
                if plant is None:
                    plant = Instance(plant_package, name="plant", start=start, theta=theta, nu=nu)
                else:
                    plant.reset(start, theta=theta, nu=nu)
                if controller_package is not None:
                    controller_start = _expand(controller_package, {**spec["controller_parameters"], **controller_values})
                    if controller is None:
                        controller = Instance(controller_package, name="controller", start=controller_start)
                    else:
                        controller.reset(controller_start)
                _fly(spec, flight, plant, controller)
                status, message = "ok", ""
            except FMICallException as refused:
                status = STATUS.get(refused.status, "error")
                log = plant.log.last_problem() if plant is not None else ""
                message = f"{refused} {log}".strip()
            except (DriverError, _NonFinite) as refused:
                status, message = "error", str(refused)
            except Exception as unexpected:  # noqa: BLE001 (a case never aborts the campaign)
                status, message = "error", f"{type(unexpected).__name__}: {unexpected}"
                # The instances may be in any state now: make fresh ones for the next case.
                for instance in (plant, controller):
                    if instance is not None:
                        instance.close()
                plant = controller = None
            row.update(metrics(flight, spec["settle_threshold"], spec["step"]))
            for function in custom:
                row.update(function(flight))
            row.update(status=status, message=message)
            if spec["trajectories"]:
                row["_trajectory"] = {
                    "time": flight.time[: flight.reached],
                    **{f"nu[{k + 1}]": flight.nu[: flight.reached, k] for k in range(flight.nu.shape[1])},
                }
            rows.append(row)
    finally:
        for instance in (plant, controller):
            if instance is not None:
                instance.close()
    return rows


def _held(points: list, t: float, tolerance: float) -> float | None:
    """A schedule's value at communication point t (None before its first time)."""
    value = None
    for time, point in points:
        if time <= t + tolerance:
            value = point
    return value


def _fly(spec: dict, flight: _Flight, plant: Instance, controller: Instance | None) -> None:
    h, steps = spec["step"], round(spec["duration"] / spec["step"])
    schedules = spec["schedules"]
    flight.sample(0, plant, controller)
    for k in range(steps):
        t = k * h
        flight.time[k] = t
        scheduled = {name: _held(points, t, 1e-9 * h) for name, points in schedules.items()}
        scheduled = {name: value for name, value in scheduled.items() if value is not None}
        if scheduled:
            plant.set(scheduled)
        if flight.ctrl.shape[1]:
            flight.ctrl[k] = plant.array("ctrl")
        if controller is not None:
            controller.set_array("theta", plant.array("theta"))
            controller.set_array("nu", plant.array("nu"))
            eps = controller.array("eps")
            plant.set_array("eps", eps)
            flight.eps[k] = eps
        plant.step(h, communication_point=t)
        if controller is not None:
            controller.step(h, communication_point=t)
        flight.time[k + 1] = t + h
        flight.sample(k + 1, plant, controller)
        if not math.isfinite(flight.kinetic_energy[k + 1]):
            raise _NonFinite(f"the state is not finite at t = {t + h:g} s")


def _function(name: str):
    """`module:function`, imported on the worker."""
    module, _, attribute = name.partition(":")
    return getattr(importlib.import_module(module), attribute)
