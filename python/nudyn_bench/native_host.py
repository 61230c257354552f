"""The native co-simulation master of issue 36 (`bench/native/fmu_host.c`):
built with the system's C compiler, it loads an FMU's library, steps it
over the whole experiment reading θ and ν at every communication point,
and times that loop, with no Python in it."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from nudyn_driver.package import FmuPackage

from .vehicles import ROOT, Vehicle

SOURCE = ROOT / "bench" / "native" / "fmu_host.c"


def build(directory: Path) -> Path:
    """Compiles the host into `directory`; returns the executable."""
    executable = Path(directory) / "fmu_host"
    subprocess.run(["cc", "-O2", "-Wall", "-Wextra", "-Werror", "-o", str(executable), str(SOURCE), "-ldl"], check=True)
    return executable


def run(host: Path, package: FmuPackage, vehicle: Vehicle, settings: dict, communication_step: float, steps: int,
        repetitions: int = 1) -> dict:
    """`repetitions` timed runs from the vehicle's state with `settings`
    (method by item name, other parameters by value): {"seconds": [...],
    "theta": rows, "nu": rows} read after each communication step of the last run."""
    theta_refs, nu_refs = package.refs("theta"), package.refs("nu")
    assignments = [f"r:{vr}={value!r}" for vr, value in zip(theta_refs, map(float, vehicle.qpos))]
    assignments += [f"r:{vr}={value!r}" for vr, value in zip(nu_refs, map(float, vehicle.nu))]
    for name, value in settings.items():
        if name == "method":
            assignments.append(f"i:{package.vr['method']}={package.enumeration_value('method', value)}")
        else:
            assignments.append(f"r:{package.vr[name]}={float(value)!r}")
    reads = ",".join(str(vr) for vr in theta_refs + nu_refs)
    cmd = [str(host), str(package.directory), package.model_identifier, package.guid, repr(communication_step),
           str(steps), str(repetitions), reads, *assignments]
    result = json.loads(subprocess.run(cmd, capture_output=True, text=True, check=True).stdout)
    rows = result["values"]
    return {"seconds": result["seconds"], "theta": [row[: len(theta_refs)] for row in rows],
            "nu": [row[len(theta_refs):] for row in rows]}
