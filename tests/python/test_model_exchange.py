"""The plant FMU's Model Exchange interface (FMI 2.0): FMPy validates every
example's FMU, its CVODE run agrees with the FMU's own co-simulation, a
host's fixed-step RK4 on the ME interface converges at 4th order to the
FMU's own co-simulation solution, and quaternions a host has let drift off
unit length do not change the motion."""

from __future__ import annotations

from ctypes import c_double

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Model
from fmpy.validation import validate_fmu

from conftest import EXAMPLES, EXAMPLES_DIR, example_ids
from nudyn_driver.package import FmuPackage


@pytest.fixture(scope="module")
def fmus(cli, tmp_path_factory):
    directory = tmp_path_factory.mktemp("me")
    return {path.stem: cli.export(path, directory / f"{path.stem}.fmu", outputs=("qvel", "kinetic_energy"))
            for path in EXAMPLES}


@pytest.mark.parametrize("name", example_ids())
def test_fmpy_validates_the_model_exchange_description(fmus, name):
    fmu = fmus[name]
    assert validate_fmu(str(fmu)) == []
    description = read_model_description(str(fmu))
    assert description.modelExchange is not None and description.coSimulation is not None
    nq = len([v for v in description.modelVariables if v.name.startswith("theta[")])
    nv = len([v for v in description.modelVariables if v.name.startswith("nu[")])
    assert len(description.derivatives) == nq + nv
    assert [d.variable.derivative.name for d in description.derivatives] == (
        [f"theta[{k}]" for k in range(1, nq + 1)] + [f"nu[{k}]" for k in range(1, nv + 1)])


def test_cvode_on_model_exchange_agrees_with_co_simulation(fmus):
    """FMPy's CVODE at rtol 1e-10 against the FMU's DOP853 at 1e-12, 2 s of
    the tumbling bus with its arm moving (measured: 3e-10)."""
    start = {"nu[4]": 0.5, "nu[5]": -0.2, "nu[8]": 0.2, "nu[12]": -0.3}
    outputs = ["theta[4]", "theta[5]", "theta[9]", "nu[8]", "nu[12]", "kinetic_energy"]
    me = simulate_fmu(str(fmus["bus_arm7"]), fmi_type="ModelExchange", stop_time=2, start_values=start,
                      relative_tolerance=1e-10, output_interval=0.1, output=outputs)
    cs = simulate_fmu(str(fmus["bus_arm7"]), fmi_type="CoSimulation", stop_time=2,
                      start_values={**start, "tolerance": 1e-12}, output_interval=0.1, output=outputs)
    assert len(me) == len(cs) == 21
    for name in outputs:
        assert np.max(np.abs(me[name] - cs[name])) <= 1e-8, name
    assert np.ptp(me["nu[12]"]) > 1e-3, "the arm must move"


def get_states(fmu: FMU2Model, n: int) -> np.ndarray:
    x = (c_double * n)()
    fmu.getContinuousStates(x, n)
    return np.array(x)


def set_states(fmu: FMU2Model, x) -> None:
    fmu.setContinuousStates((c_double * len(x))(*x), len(x))


def get_derivatives(fmu: FMU2Model, n: int) -> np.ndarray:
    dx = (c_double * n)()
    fmu.getDerivatives(dx, n)
    return np.array(dx)


def rk4_on_model_exchange(fmu: FMU2Model, x0, h: float, steps: int) -> np.ndarray:
    """A host's classic RK4 through fmi2SetTime, fmi2SetContinuousStates and fmi2GetDerivatives."""
    def f(t, x):
        fmu.setTime(t)
        set_states(fmu, x)
        return get_derivatives(fmu, len(x))

    x, t = np.array(x0, dtype=float), 0.0
    for _ in range(steps):
        k1 = f(t, x)
        k2 = f(t + h / 2, x + h / 2 * k1)
        k3 = f(t + h / 2, x + h / 2 * k2)
        k4 = f(t + h, x + h * k3)
        x, t = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), t + h
    return x


def model_exchange_instance(fmu_path, tmp_path, start):
    package = FmuPackage.unzip(fmu_path, tmp_path / "unzipped")
    fmu = FMU2Model(guid=package.guid, unzipDirectory=str(package.directory), modelIdentifier=package.model_identifier,
                    instanceName="me")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.setReal([package.vr[name] for name in start], list(start.values()))
    fmu.exitInitializationMode()
    fmu.newDiscreteStates()
    fmu.enterContinuousTimeMode()
    return package, fmu


def test_a_hosts_fixed_step_rk4_converges_to_the_fmus_own_solution(fmus, tmp_path):
    """A host's RK4 over ME (on the FMU's states θ, ν) converges at 4th
    order to the FMU's co-simulation solution (DOP853 at 1e-13): the
    derivatives the FMU reports are those of the motion it integrates. (Its
    own RK4 advances θ̇, another 4th-order solution at equal steps.)"""
    start = {"nu[1]": 0.3, "nu[2]": -0.5, "nu[4]": 1.0}
    hosts = []
    for k, h in enumerate([2e-3, 1e-3]):
        package, fmu = model_exchange_instance(fmus["fixed_rig"], tmp_path / f"h{k}", start)
        names = package.names("theta") + package.names("nu")
        hosts.append(rk4_on_model_exchange(fmu, get_states(fmu, len(names)), h, round(0.1 / h)))
        fmu.terminate()
        fmu.freeInstance()
    cs = simulate_fmu(str(fmus["fixed_rig"]), stop_time=0.1, output_interval=0.1,
                      start_values={**start, "tolerance": 1e-13}, output=names)
    own = np.array([cs[name][-1] for name in names])
    errors = [np.max(np.abs(host - own)) for host in hosts]
    assert errors[1] < 1e-8, errors
    assert errors[0] / errors[1] > 12, errors


def test_quaternion_drift_in_the_host_does_not_change_the_motion(fmus, tmp_path):
    """ν̇ at a state whose quaternions are 1.1 long is ν̇ at the unit ones,
    and the quaternion rates are orthogonal to them (the drift does not grow)."""
    package, fmu = model_exchange_instance(fmus["bus_arm7"], tmp_path, {"nu[4]": 0.5, "nu[9]": 0.4})
    nq, nx = len(package.names("theta")), len(package.names("theta")) + len(package.names("nu"))
    x = get_states(fmu, nx)
    unit = get_derivatives(fmu, nx)
    drifted = x.copy()
    drifted[3:7] *= 1.1
    set_states(fmu, drifted)
    assert np.array_equal(get_states(fmu, nx), drifted), "x is the host's"
    derivatives = get_derivatives(fmu, nx)
    np.testing.assert_allclose(derivatives[nq:], unit[nq:], rtol=0, atol=1e-14)
    assert abs(derivatives[3:7] @ drifted[3:7]) <= 1e-15
    fmu.terminate()
    fmu.freeInstance()


def test_fmus_without_model_exchange_say_so(cli, tmp_path):
    """A plant with the energy residual (whose work integral only the FMU's
    own integration keeps) and the controller are co-simulation only."""
    residual = cli.export(EXAMPLES_DIR / "fixed_rig.xml", tmp_path / "residual.fmu", outputs=("energy_residual",))
    controller = cli.export(EXAMPLES_DIR / "fixed_rig.xml", tmp_path / "controller.fmu", controller=True)
    for fmu in (residual, controller):
        description = read_model_description(str(fmu))
        assert description.modelExchange is None and not description.derivatives
        assert validate_fmu(str(fmu)) == []


def test_cvode_locates_the_constraint_switches_of_a_docked_servicer(cli, tmp_path):
    """docked_servicer (welds, a connect, friction loss, hinge, slide and
    ball limits) through model exchange: the FMU declares the switches of
    its constraint forces as event indicators and holds the mode between
    events, FMPy's CVODE meets them as state events, and the run converges
    with the tolerance to the FMU's own co-simulation at 1e-11 (before, no
    indicator was declared and CVODE stepped across the jumps blindly)."""
    from conftest import ROOT

    fmu = cli.export(ROOT / "tests" / "fixtures" / "constraints" / "docked_servicer.xml", tmp_path / "docked.fmu")
    description = read_model_description(str(fmu))
    assert description.numberOfEventIndicators > 0
    assert validate_fmu(str(fmu)) == []
    names = [v.name for v in description.modelVariables]
    eps = {name: 0.3 * np.sin(k) for k, name in enumerate(n for n in names if n.startswith("eps["))}
    outputs = [n for n in names if n.startswith(("theta[", "nu["))]
    reference = simulate_fmu(str(fmu), fmi_type="CoSimulation", stop_time=1, output_interval=0.05,
                             start_values={**eps, "tolerance": 1e-11}, output=outputs)
    end = np.array(list(reference[-1])[1:])
    errors = []
    for rtol in (1e-6, 1e-8):
        run = simulate_fmu(str(fmu), fmi_type="ModelExchange", stop_time=1, output_interval=0.05,
                           start_values=eps, relative_tolerance=rtol, output=outputs, record_events=True)
        assert len(run) > 21, "FMPy recorded no state event"
        errors.append(np.max(np.abs(np.array(list(run[-1])[1:]) - end) / (1 + np.abs(end))))
    assert errors[1] < 1e-4 and errors[1] < errors[0] / 10, errors
