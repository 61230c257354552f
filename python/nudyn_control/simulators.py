"""The closed loop plant FMU + controller FMU in two co-simulation masters,
each run the way a user of it would run it:

- FMPy: a master loop over FMU2Slave instances (FMPy has no connection
  language of its own). Gauss-Seidel order at each communication point t_k:
  the plant's θ and ν go to the controller's inputs, the controller's ε
  (direct feedthrough, read at once) to the plant's input, then both step
  over h. ε on [t_k, t_k + h) is the law at the state at t_k.
- libcosim (Open Simulation Platform, `libcosimpy`): an OspSystemStructure.xml
  that connects the variables name to name, the fixed-step algorithm, and a
  last-value observer. libcosim steps all simulators in parallel and then
  passes outputs to inputs (Jacobi), so ε on [t_k, t_k + h) is the law at
  the state at t_{k-1}: one step of delay, which the analysis measures.

In both, the plant steps `substeps` times per h with ε held, so that the
state is seen between the controller's communication points; the plant's
integration does not depend on how its steps are cut (ε is held)."""

from __future__ import annotations

import math
import time
import xml.sax.saxutils as xml
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nudyn_driver.cli import Nudyn
from nudyn_driver.instance import Instance
from nudyn_driver.package import FmuPackage

from .scenarios import Scenario

OSP_NAMESPACE = "http://opensimulationplatform.com/MSMI/OSPSystemStructure"


@dataclass
class Trajectory:
    """Samples every h/substeps: state at time[j], and the ε the plant
    held over [time[j], time[j+1])."""

    simulator: str
    time: np.ndarray  # J+1
    theta: np.ndarray  # (J+1, nq)
    nu: np.ndarray  # (J+1, nv)
    eps: np.ndarray  # (J, nv)
    step: float
    substeps: int
    wall_time: float


def export(nudyn: Path, scenario: Scenario, directory: Path) -> tuple[Path, Path]:
    """The plant FMU and the controller FMU of the scenario's vehicle."""
    cli = Nudyn(nudyn)
    plant = cli.export(scenario.mjcf, directory / "plant.fmu")
    controller = cli.export(scenario.mjcf, directory / "controller.fmu", controller=True,
                            end_effector=scenario.end_effector)
    return plant, controller


def run_fmpy(plant_fmu: Path, controller_fmu: Path, scenario: Scenario, workdir: Path) -> Trajectory:
    plant_package = FmuPackage.unzip(plant_fmu, workdir / "fmpy_plant")
    controller_package = FmuPackage.unzip(controller_fmu, workdir / "fmpy_controller")
    nq, nv = plant_package.nq, plant_package.nv
    h, m = scenario.step, scenario.substeps
    periods = round(scenario.duration / h)
    samples = periods * m
    theta, nu, eps = np.zeros((samples + 1, nq)), np.zeros((samples + 1, nv)), np.zeros((samples, nv))

    started = time.perf_counter()
    plant = Instance(plant_package, name="plant", start=scenario.plant_start, stop_time=scenario.duration)
    controller = Instance(controller_package, name="controller", start=scenario.controller,
                          stop_time=scenario.duration)
    theta[0], nu[0] = plant.array("theta"), plant.array("nu")
    for k in range(periods):
        j0 = k * m
        controller.set_array("theta", theta[j0])
        controller.set_array("nu", nu[j0])
        held = controller.array("eps")
        plant.set_array("eps", held)
        for i in range(m):
            j = j0 + i
            plant.step(h / m, communication_point=j * h / m)
            eps[j] = held
            theta[j + 1], nu[j + 1] = plant.array("theta"), plant.array("nu")
        controller.step(h, communication_point=k * h)
    wall = time.perf_counter() - started
    plant.close()
    controller.close()
    return Trajectory("FMPy", np.arange(samples + 1) * h / m, theta, nu, eps, h, m, wall)


def system_structure(scenario: Scenario, nq: int, nv: int) -> str:
    """OspSystemStructure.xml: the plant stepping at h/substeps, the
    controller at h, connected name to name."""

    def initial_values(values: dict[str, float]) -> str:
        if not values:
            return ""
        rows = "\n".join(f'        <InitialValue variable="{xml.escape(name)}"><Real value="{value!r}"/></InitialValue>'
                         for name, value in values.items())
        return f"\n      <InitialValues>\n{rows}\n      </InitialValues>\n    "

    def connection(source: str, target: str, name: str) -> str:
        return (f'    <VariableConnection>\n      <Variable simulator="{source}" name="{name}"/>\n'
                f'      <Variable simulator="{target}" name="{name}"/>\n    </VariableConnection>')

    names = [f"theta[{k}]" for k in range(1, nq + 1)] + [f"nu[{k}]" for k in range(1, nv + 1)]
    connections = [connection("plant", "controller", n) for n in names]
    connections += [connection("controller", "plant", f"eps[{k}]") for k in range(1, nv + 1)]
    base = scenario.step / scenario.substeps
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<!-- {xml.escape(scenario.title)}
     plant.fmu: nudyn export {scenario.mjcf.name}; controller.fmu: the same with the options
     controller{', end-effector ' + scenario.end_effector if scenario.end_effector else ''} (XML comments cannot hold two dashes) -->
<OspSystemStructure xmlns="{OSP_NAMESPACE}" version="0.1">
  <StartTime>0.0</StartTime>
  <BaseStepSize>{base!r}</BaseStepSize>
  <Algorithm>fixedStep</Algorithm>
  <Simulators>
    <Simulator name="plant" source="plant.fmu" stepSize="{base!r}">{initial_values(scenario.plant_start)}</Simulator>
    <Simulator name="controller" source="controller.fmu" stepSize="{scenario.step!r}">{initial_values(scenario.controller)}</Simulator>
  </Simulators>
  <Connections>
{chr(10).join(connections)}
  </Connections>
</OspSystemStructure>
"""


def run_libcosim(plant_fmu: Path, controller_fmu: Path, scenario: Scenario, workdir: Path) -> Trajectory:
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    plant = FmuPackage.unzip(plant_fmu, workdir / "libcosim_plant")
    nq, nv = plant.nq, plant.nv
    case = workdir / "libcosim"
    case.mkdir(parents=True, exist_ok=True)
    for fmu, name in ((plant_fmu, "plant.fmu"), (controller_fmu, "controller.fmu")):
        (case / name).write_bytes(fmu.read_bytes())
    (case / "OspSystemStructure.xml").write_text(system_structure(scenario, nq, nv))

    # libcosim warns that it ignores the plant's Enumeration parameter `method` (the default, dop853, is used).
    log_output_level(CosimLogLevel.ERROR)
    h, m = scenario.step, scenario.substeps
    samples = round(scenario.duration / h) * m
    started = time.perf_counter()
    execution = CosimExecution.from_osp_config_file(str(case))
    index = execution.slave_index_from_instance_name("plant")
    references = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
    theta_refs, nu_refs, eps_refs = ([references[name] for name in plant.names(prefix)] for prefix in ("theta", "nu", "eps"))
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    theta, nu, eps = np.zeros((samples + 1, nq)), np.zeros((samples + 1, nv)), np.zeros((samples, nv))
    times = np.zeros(samples + 1)
    # The plant starts from the FMU's start values, overridden by the scenario's.
    start = {name: value for prefix in ("theta", "nu") for name, value in zip(plant.names(prefix), plant.starts(prefix))}
    start |= scenario.plant_start
    theta[0] = [start[name] for name in plant.names("theta")]
    nu[0] = [start[name] for name in plant.names("nu")]
    for j in range(samples):
        if not execution.step(1):
            raise RuntimeError(f"libcosim failed at step {j}")
        times[j + 1] = execution.status().current_time * 1e-9
        theta[j + 1] = observer.last_real_values(index, theta_refs)
        nu[j + 1] = observer.last_real_values(index, nu_refs)
        # The plant's input as observed after step j: the ε it held during step j.
        eps[j] = observer.last_real_values(index, eps_refs)
    wall = time.perf_counter() - started
    if not math.isclose(times[-1], scenario.duration, rel_tol=1e-9):
        raise RuntimeError(f"libcosim stopped at t = {times[-1]}, expected {scenario.duration}")
    return Trajectory("libcosim", times, theta, nu, eps, h, m, wall)

