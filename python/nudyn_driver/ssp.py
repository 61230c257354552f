"""A nudyn system file (`nudyn system MODEL.xml -o LOOP.ssp`, docs/systems.md)
read and run: by FMPy's SSP runner, by OSP's libcosim, and by a loop of
this driver over the same two FMUs that steps as either master steps, so
that each importer's run has a reference computed apart from it.

How the masters step (ε_k is the ε the plant holds over [t_k, t_k+1),
s_k the plant's (θ, ν) at t_k, law(s) the controller's output at inputs s):

- "gauss-seidel" (nudyn_driver, nudyn-campaign): ε_k = law(s_k).
- "libcosim": Jacobi after an initialization that passes outputs to
  inputs: ε_0 = law(s_0), ε_k = law(s_{k-1}).
- "fmpy" (fmpy.ssp.simulation.simulate_ssp): Jacobi from connections that
  all start at 0: ε_0 = 0, ε_1 = law(0), ε_k = law(s_{k-1})."""

from __future__ import annotations

import io
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import SystemFileError
from .instance import Instance
from .package import FmuPackage

NAMESPACES = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
}
MASTERS = ("gauss-seidel", "libcosim", "fmpy")


@dataclass
class System:
    """What a system file holds: the DefaultExperiment's stop time and
    libcosim step, each component's FMU (its path in the archive) and the
    values its ParameterValues file sets."""

    path: Path
    stop_time: float
    step: float
    sources: dict[str, str]
    values: dict[str, dict[str, float]]


@dataclass
class Run:
    """The plant's state at the communication points t_0 = 0 ... t_N."""

    master: str
    time: np.ndarray
    theta: np.ndarray
    nu: np.ndarray


def read(path: Path) -> System:
    """The system file at `path`, or a SystemFileError naming the file, the
    entry and what is wrong (not a zip, an entry missing, not well-formed,
    no plant or controller component, a component that is no FMU)."""
    path = Path(path)
    try:
        archive = zipfile.ZipFile(path)
    except zipfile.BadZipFile:
        raise SystemFileError(f"{path}: not a zip archive (an SSP file is one)") from None
    with archive:
        root = _xml(archive, path, "SystemStructure.ssd", "the system structure")
        experiment = root.find("ssd:DefaultExperiment", NAMESPACES)
        algorithm = experiment.find(".//osp:FixedStepAlgorithm", NAMESPACES) if experiment is not None else None
        if algorithm is None:
            raise SystemFileError(f"{path}: SystemStructure.ssd has no ssd:DefaultExperiment with an "
                                  "osp:FixedStepAlgorithm (the step)")
        stop_time = _number(experiment.get("stopTime"), f"{path}: SystemStructure.ssd: DefaultExperiment stopTime")
        step = _number(algorithm.get("baseStepSize"), f"{path}: SystemStructure.ssd: FixedStepAlgorithm baseStepSize")
        sources, values = {}, {}
        for component in root.iterfind("ssd:System/ssd:Elements/ssd:Component", NAMESPACES):
            name = component.get("name")
            sources[name] = component.get("source")
            _check_fmu(archive, path, sources[name], name)
            values[name] = {}
            for binding in component.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NAMESPACES):
                source = binding.get("source")
                parameters = _xml(archive, path, source, f"the parameter values of component {name}")
                for parameter in parameters.iterfind("ssv:Parameters/ssv:Parameter", NAMESPACES):
                    values[name][parameter.get("name")] = _real(parameter, f"{path}: {source}")
    for name in ("plant", "controller"):
        if name not in sources:
            found = ", ".join(sources) or "none"
            raise SystemFileError(f"{path}: no component named {name} (its components: {found}); a nudyn system "
                                  "file has a plant and a controller")
    return System(path, stop_time, step, sources, values)


def _entry(archive: zipfile.ZipFile, path: Path, entry: str | None, what: str) -> bytes:
    """The bytes of `entry` (`what` it is, for the message)."""
    if entry is None or entry not in archive.namelist():
        raise SystemFileError(f"{path}: no entry {entry} ({what})")
    try:
        return archive.read(entry)
    except (zipfile.BadZipFile, EOFError, zlib.error) as error:
        raise SystemFileError(f"{path}: entry {entry} cannot be read: {error}") from None


def _xml(archive: zipfile.ZipFile, path: Path, entry: str | None, what: str) -> ET.Element:
    try:
        return ET.fromstring(_entry(archive, path, entry, what))
    except ET.ParseError as error:
        raise SystemFileError(f"{path}: {entry} is not well-formed XML: {error}") from None


def _check_fmu(archive: zipfile.ZipFile, path: Path, source: str | None, component: str) -> None:
    """Component `component`'s FMU is in the archive and is an FMU (a zip with a model description)."""
    fmu = io.BytesIO(_entry(archive, path, source, f"the FMU of component {component}"))
    if not zipfile.is_zipfile(fmu):
        raise SystemFileError(f"{path}: {source}, the FMU of component {component}, is not a zip archive "
                              "(an FMU is one)")
    with zipfile.ZipFile(fmu) as inner:
        if "modelDescription.xml" not in inner.namelist():
            raise SystemFileError(f"{path}: {source}, the FMU of component {component}, has no modelDescription.xml")


def _number(text: str | None, what: str) -> float:
    try:
        return float(text)
    except (TypeError, ValueError):
        raise SystemFileError(f"{what}: expected a number, found {text!r}") from None


def _real(parameter: ET.Element, where: str) -> float:
    """A ParameterValues entry's value: nudyn's values are all ssv:Real."""
    real = parameter.find("ssv:Real", NAMESPACES)
    name = parameter.get("name")
    if real is None:
        raise SystemFileError(f"{where}: parameter {name} has no ssv:Real value (a nudyn system's values are Real)")
    return _number(real.get("value"), f"{where}: parameter {name}")


def fmpy_parameter_set(system: System):
    """The values of the components' ParameterValues files as the one
    ParameterSet that `simulate_ssp(parameter_set=...)` applies (FMPy's
    runner reads no binding itself), names prefixed with the component."""
    from fmpy.ssp.ssd import Parameter, ParameterSet

    parameter_set = ParameterSet(name="values")
    for component, values in system.values.items():
        for name, value in values.items():
            parameter = Parameter(name=f"{component}.{name}")
            parameter.type, parameter.value = "Real", repr(value)
            parameter_set.parameters.append(parameter)
    return parameter_set


def run_fmpy(system: System) -> Run:
    """fmpy.ssp.simulation.simulate_ssp over the DefaultExperiment."""
    from fmpy.ssp.simulation import simulate_ssp

    result = simulate_ssp(str(system.path), stop_time=system.stop_time, step_size=system.step,
                          parameter_set=fmpy_parameter_set(system))
    with tempfile.TemporaryDirectory() as directory:
        plant = package(system, "plant", Path(directory))
        start = _start_state(system, plant)
    # Row k holds the outputs after the step from t_k (labelled t_k).
    theta = np.array([result[f"plant.{name}"] for name in plant.names("theta")]).T
    nu = np.array([result[f"plant.{name}"] for name in plant.names("nu")]).T
    times = np.concatenate([[0.0], result["time"] + system.step])
    return Run("fmpy", times, np.vstack([start[0], theta]), np.vstack([start[1], nu]))


def run_libcosim(system: System) -> Run:
    """libcosim's CosimExecution.from_ssp_file, in a process of its own
    (libcosim's failures end the process rather than raise)."""
    with tempfile.TemporaryDirectory() as directory:
        out = Path(directory) / "run.npz"
        done = subprocess.run([sys.executable, "-m", "nudyn_driver.ssp", str(system.path), str(out)],
                              capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(f"libcosim failed on {system.path} (exit {done.returncode}): {done.stderr[-2000:]}")
        data = np.load(out)
        return Run("libcosim", data["time"], data["theta"], data["nu"])


def _libcosim_main(ssp: str, out: str) -> None:
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    system = read(Path(ssp))
    log_output_level(CosimLogLevel.ERROR)
    execution = CosimExecution.from_ssp_file(ssp)
    index = execution.slave_index_from_instance_name("plant")
    references = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
    with tempfile.TemporaryDirectory() as directory:
        plant = package(system, "plant", Path(directory))
        start = _start_state(system, plant)
    theta_refs = [references[name] for name in plant.names("theta")]
    nu_refs = [references[name] for name in plant.names("nu")]
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    steps = round(system.stop_time / system.step)
    times, theta, nu = [0.0], [start[0]], [start[1]]
    for _ in range(steps):
        if not execution.step(1):
            raise RuntimeError(f"libcosim failed at t = {times[-1]}")
        times.append(execution.status().current_time * 1e-9)
        theta.append(observer.last_real_values(index, theta_refs))
        nu.append(observer.last_real_values(index, nu_refs))
    np.savez(out, time=np.array(times), theta=np.array(theta), nu=np.array(nu))


def run_loop(system: System, master: str) -> Run:
    """The two FMUs of the file stepped by this driver as `master` steps
    them (module docstring), with the file's values and experiment."""
    if master not in MASTERS:
        raise ValueError(f"unknown master {master!r} (known: {', '.join(MASTERS)})")
    with tempfile.TemporaryDirectory() as directory:
        plant_package = package(system, "plant", Path(directory))
        controller_package = package(system, "controller", Path(directory))
        h, steps = system.step, round(system.stop_time / system.step)
        with Instance(plant_package, name="plant", start=system.values.get("plant"), stop_time=system.stop_time) as plant, \
                Instance(controller_package, name="controller", start=system.values.get("controller"),
                         stop_time=system.stop_time) as controller:
            def law(theta: np.ndarray, nu: np.ndarray) -> np.ndarray:
                controller.set_array("theta", theta)
                controller.set_array("nu", nu)
                return controller.array("eps")

            theta, nu = [plant.array("theta")], [plant.array("nu")]
            # Jacobi: `held` is the ε the plant holds this step, `seen` the
            # controller's inputs this step; both pass on after the step.
            if master == "fmpy":
                held, seen = np.zeros(plant_package.nv), (np.zeros(plant_package.nq), np.zeros(plant_package.nv))
            else:
                held, seen = law(theta[0], nu[0]), (theta[0], nu[0])
            for k in range(steps):
                if master == "gauss-seidel":
                    held = law(theta[-1], nu[-1])
                else:
                    output = law(*seen)
                plant.set_array("eps", held)
                plant.step(h, communication_point=k * h)
                controller.step(h, communication_point=k * h)
                theta.append(plant.array("theta"))
                nu.append(plant.array("nu"))
                if master != "gauss-seidel":
                    held, seen = output, (theta[-1], nu[-1])
    return Run(master, np.arange(steps + 1) * h, np.array(theta), np.array(nu))


def package(system: System, component: str, directory: Path) -> FmuPackage:
    """The component's FMU, extracted under `directory`."""
    directory.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(system.path) as archive:
        fmu = directory / f"{component}.fmu"
        fmu.write_bytes(archive.read(system.sources[component]))
    return FmuPackage.unzip(fmu, directory / component)


def _start_state(system: System, plant: FmuPackage) -> tuple[np.ndarray, np.ndarray]:
    """The plant's θ and ν at t = 0: its start values (which carry the file's)."""
    return np.array(plant.starts("theta")), np.array(plant.starts("nu"))


if __name__ == "__main__":
    _libcosim_main(*sys.argv[1:3])
