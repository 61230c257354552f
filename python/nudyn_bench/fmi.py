"""FMI overhead per doStep: the exported FMU stepped from Python by FMPy,
against nudyn's own loop over the same steps (`nudyn-bench simulate`,
timed in Rust), same method, step and start."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from nudyn_driver.cli import Nudyn
from nudyn_driver.instance import Instance
from nudyn_driver.package import FmuPackage

from .vehicles import Vehicle
from .work_precision import Plan, nudyn_runs


def fmpy_loop(package: FmuPackage, vehicle: Vehicle, step: float, steps: int, with_io: bool) -> float:
    """Seconds for `steps` doSteps of `step` (RK4, one internal step each);
    with_io: also set ε and get θ and ν at every step, as a co-simulation does."""
    fmu = Instance(package, name="bench", start={"method": "rk4", "max_step": step}, theta=vehicle.qpos, nu=vehicle.nu)
    eps = np.zeros(package.nv)
    start = time.perf_counter()
    if with_io:
        for n in range(steps):
            fmu.set_array("eps", eps)
            fmu.step(step, communication_point=n * step)
            fmu.array("theta")
            fmu.array("nu")
    else:
        do_step = fmu.fmu.doStep
        for n in range(steps):
            do_step(currentCommunicationPoint=n * step, communicationStepSize=step)
    seconds = time.perf_counter() - start
    fmu.close()
    return seconds


def fmi_overhead(nudyn: Path, bench: Path, vehicle: Vehicle, step: float, duration: float, repetitions: int, work: Path) -> dict:
    """Seconds per repetition of: the native loop, FMPy doStep only, FMPy with ε in and θ, ν out."""
    # With the validation's outputs, as the FMU measured in docs/bench.
    fmu_path = Nudyn(nudyn).export(vehicle.path, work / f"{vehicle.name}.fmu", outputs=("kinetic_energy", "momentum"))
    steps = int(round(duration / step))
    plan = Plan(duration, step, 0, 0, [], [], [], [])
    results = {"native": [], "fmpy_do_step": [], "fmpy_with_io": []}
    with tempfile.TemporaryDirectory() as unzip:
        package = FmuPackage.unzip(fmu_path, Path(unzip))
        for _ in range(repetitions):
            [native] = nudyn_runs(bench, vehicle, [f"rk4:{step:g}"], plan, samples=False)
            results["native"].append(native["seconds"][0])
            results["fmpy_do_step"].append(fmpy_loop(package, vehicle, step, steps, with_io=False))
            results["fmpy_with_io"].append(fmpy_loop(package, vehicle, step, steps, with_io=True))
    return {"step": step, "steps": steps, "seconds": results}
