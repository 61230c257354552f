"""FMI 3.0 FMUs (`nudyn export --fmi-version 3`): FMPy validates every
example's plant and controller; co-simulation gives the FMI 2.0 FMU's
numbers to the bit (one core behind both layers); CVODE on model exchange
agrees with co-simulation; a host's fixed-step RK4 on model exchange agrees
with the FMU's own RK4; FMU states round-trip; the per-element
dependencies are the true ones (checked by perturbing inputs); and misuse
through the C API is refused with the right status."""

from __future__ import annotations

import ctypes
import math
import subprocess
from ctypes import byref, c_bool, c_double, c_int64, c_size_t, c_uint32, c_void_p

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi3 import FMU3Model, FMU3Slave
from fmpy.validation import validate_fmu

from conftest import EXAMPLES, EXAMPLES_DIR, example_ids

OK, DISCARD, ERROR = 0, 2, 3


@pytest.fixture(scope="module")
def fmus(cli, tmp_path_factory):
    directory = tmp_path_factory.mktemp("fmi3")
    made = {}
    for path in EXAMPLES:
        made[path.stem] = cli.export(path, directory / f"{path.stem}.fmu", outputs=("qvel", "kinetic_energy"),
                                     fmi_version=3)
        made[f"{path.stem}_controller"] = cli.export(path, directory / f"{path.stem}_controller.fmu",
                                                     controller=True, fmi_version=3)
    made["fmi2"] = cli.export(EXAMPLES_DIR / "bus_arm7.xml", directory / "bus_fmi2.fmu", outputs=("qvel",))
    made["fmi2_controller"] = cli.export(EXAMPLES_DIR / "bus_arm7.xml", directory / "ctrl_fmi2.fmu", controller=True)
    return made


def variables(fmu):
    return {v.name: v for v in read_model_description(str(fmu)).modelVariables}


def size(variable) -> int:
    return math.prod(int(d.start) for d in variable.dimensions) if variable.dimensions else 1


@pytest.mark.parametrize("name", example_ids())
def test_fmpy_validates_and_runs_plant_and_controller(fmus, name):
    plant, controller = fmus[name], fmus[f"{name}_controller"]
    assert validate_fmu(str(plant)) == []
    assert validate_fmu(str(controller)) == []
    description = read_model_description(str(plant))
    assert description.fmiVersion == "3.0"
    assert description.modelExchange is not None and description.coSimulation is not None
    by_name = variables(plant)
    nq, nv = size(by_name["theta"]), size(by_name["nu"])
    assert size(by_name["eps"]) == size(by_name["qvel"]) == size(by_name["der(nu)"]) == nv
    assert size(by_name["der(theta)"]) == nq
    assert [d.variable.name for d in description.derivatives] == ["der(theta)", "der(nu)"]
    assert read_model_description(str(controller)).modelExchange is None
    # FMPy runs each interface: 0.1 s from a moving start.
    nu = [0.1] * nv
    for interface in ("CoSimulation", "ModelExchange"):
        result = simulate_fmu(str(plant), fmi_type=interface, stop_time=0.1, output_interval=0.05,
                              start_values={"nu": nu}, output=["theta", "nu"])
        assert np.all(np.isfinite(np.array(result["nu"].tolist()))) and len(result) == 3, interface
    result = simulate_fmu(str(controller), stop_time=0.1, output_interval=0.05, output=["eps"])
    assert np.all(np.isfinite(np.array(result["eps"].tolist())))


@pytest.mark.parametrize("method", [2, 4], ids=["dopri5", "ros34pw2"])
def test_co_simulation_gives_the_fmi2_numbers_to_the_bit(fmus, method):
    """The same run of the tumbling bus through FMI 2.0 and FMI 3.0: θ and ν
    are equal to the last bit at every communication point."""
    nu = [0.0] * 13
    nu[3], nu[4], nu[7], nu[11] = 0.5, -0.2, 0.2, -0.3
    three = simulate_fmu(str(fmus["bus_arm7"]), stop_time=1, output_interval=0.05,
                         start_values={"nu": nu, "method": method}, output=["theta", "nu", "qvel"])
    two_start = {f"nu[{k + 1}]": v for k, v in enumerate(nu) if v}
    names2 = [f"theta[{k}]" for k in range(1, 15)] + [f"nu[{k}]" for k in range(1, 14)]
    two = simulate_fmu(str(fmus["fmi2"]), stop_time=1, output_interval=0.05,
                       start_values={**two_start, "method": method}, output=names2)
    theta3 = np.array(three["theta"].tolist())
    nu3 = np.array(three["nu"].tolist())
    theta2 = np.column_stack([two[f"theta[{k}]"] for k in range(1, 15)])
    nu2 = np.column_stack([two[f"nu[{k}]"] for k in range(1, 14)])
    assert theta3.shape == theta2.shape == (21, 14)
    assert np.array_equal(theta3, theta2) and np.array_equal(nu3, nu2)
    assert np.ptp(nu3[:, 11]) > 1e-3, "the arm must move"


def test_cvode_on_model_exchange_agrees_with_co_simulation(fmus):
    """FMPy's CVODE at rtol 1e-10 on FMI 3.0 model exchange against the FMU's
    DOP853 at 1e-12 (FMI 2.0's figure: 3e-10)."""
    nu = [0.0] * 13
    nu[3], nu[4], nu[7], nu[11] = 0.5, -0.2, 0.2, -0.3
    kwargs = dict(stop_time=2, output_interval=0.1, output=["theta", "nu", "kinetic_energy"])
    me = simulate_fmu(str(fmus["bus_arm7"]), fmi_type="ModelExchange", relative_tolerance=1e-10,
                      start_values={"nu": nu}, **kwargs)
    cs = simulate_fmu(str(fmus["bus_arm7"]), fmi_type="CoSimulation", start_values={"nu": nu, "tolerance": 1e-12},
                      **kwargs)
    assert len(me) == len(cs) == 21
    for name in ("theta", "nu"):
        assert np.max(np.abs(np.array(me[name].tolist()) - np.array(cs[name].tolist()))) <= 1e-8, name
    assert np.max(np.abs(me["kinetic_energy"] - cs["kinetic_energy"])) <= 1e-8


def unzipped(fmu, tmp_path):
    directory = extract(str(fmu), str(tmp_path / fmu.stem))
    description = read_model_description(str(fmu))
    return directory, description


def model_exchange(fmu, tmp_path, nu):
    directory, description = unzipped(fmu, tmp_path)
    instance = FMU3Model(guid=description.instantiationToken, unzipDirectory=directory,
                         modelIdentifier=description.modelExchange.modelIdentifier, instanceName="me")
    instance.instantiate()
    instance.enterInitializationMode(startTime=0.0)
    by_name = {v.name: v for v in description.modelVariables}
    instance.setFloat64([by_name["nu"].valueReference], nu)
    instance.exitInitializationMode()
    instance.updateDiscreteStates()
    instance.enterContinuousTimeMode()
    return instance, by_name


def host_rk4(fmu, tmp_path, nu0, h, name):
    """A host's classic RK4 over FMI 3.0 model exchange to t = 0.1 s: (θ, ν) at the end."""
    instance, by_name = model_exchange(fmu, tmp_path / name, nu0)
    nx = instance.getNumberOfContinuousStates()
    assert nx == size(by_name["theta"]) + size(by_name["nu"])

    def f(t, x):
        instance.setTime(t)
        instance.setContinuousStates((c_double * nx)(*x), nx)
        dx = (c_double * nx)()
        instance.getContinuousStateDerivatives(dx, nx)
        return np.array(dx)

    x = (c_double * nx)()
    instance.getContinuousStates(x, nx)
    x, t = np.array(x), 0.0
    for _ in range(round(0.1 / h)):
        k1 = f(t, x)
        k2 = f(t + h / 2, x + h / 2 * k1)
        k3 = f(t + h / 2, x + h / 2 * k2)
        k4 = f(t + h, x + h * k3)
        x, t = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), t + h
    instance.terminate()
    instance.freeInstance()
    return x


def test_a_hosts_fixed_step_rk4_converges_to_the_fmus_own_solution(fmus, tmp_path):
    """A host's RK4 over FMI 3.0 model exchange (on the FMU's states θ, ν)
    converges at 4th order to the FMU's co-simulation solution (DOP853 at
    1e-13, on θ and θ̇): the derivatives the FMU reports are those of the
    motion it integrates. (The FMU's own RK4 advances θ̇, so at equal steps
    it is another 4th-order solution: 3e-10 apart here at 1 ms.)"""
    nu0 = [0.3, -0.5, 0.0, 1.0]
    cs = simulate_fmu(str(fmus["fixed_rig"]), stop_time=0.1, output_interval=0.1,
                      start_values={"nu": nu0, "tolerance": 1e-13}, output=["theta", "nu"])
    own = np.concatenate([cs["theta"][-1], cs["nu"][-1]])
    errors = [np.max(np.abs(host_rk4(fmus["fixed_rig"], tmp_path, nu0, h, f"h{k}") - own))
              for k, h in enumerate([2e-3, 1e-3])]
    assert errors[1] < 1e-8, errors
    assert errors[0] / errors[1] > 12, errors


def co_simulation(fmu, tmp_path, name="cs"):
    directory, description = unzipped(fmu, tmp_path)
    instance = FMU3Slave(guid=description.instantiationToken, unzipDirectory=directory,
                         modelIdentifier=description.coSimulation.modelIdentifier, instanceName=name)
    instance.instantiate()
    return instance, {v.name: v for v in description.modelVariables}


def test_fmu_states_round_trip(fmus, tmp_path):
    """A state saved (and serialized) at t = 0.1 replays the next step to the bit."""
    instance, by_name = co_simulation(fmus["bus_arm7"], tmp_path)
    instance.enterInitializationMode(startTime=0.0)
    instance.setFloat64([by_name["nu"].valueReference], [0, 0, 0, 0.5] + [0.1] * 9)
    instance.exitInitializationMode()
    instance.doStep(0.0, 0.1)
    saved = instance.getFMUState()
    serialized = instance.serializeFMUState(saved)
    theta_vr = by_name["theta"].valueReference
    instance.doStep(0.1, 0.1)
    first = instance.getFloat64([theta_vr], 14)
    instance.setFMUState(instance.deserializeFMUState(serialized))
    instance.doStep(0.1, 0.1)
    assert instance.getFloat64([theta_vr], 14) == first
    instance.freeFMUState(saved)
    instance.terminate()
    instance.freeInstance()


def test_the_controller_gives_the_fmi2_controllers_eps(fmus, tmp_path):
    """The controller FMU of both versions computes the same ε from the same θ, ν."""
    rng = np.random.default_rng(3)
    three, by_name = co_simulation(fmus["bus_arm7_controller"], tmp_path, "c3")
    three.enterInitializationMode(startTime=0.0)
    three.exitInitializationMode()
    theta = three.getFloat64([by_name["theta"].valueReference], 14)
    theta[7:] = list(np.array(theta[7:]) + rng.uniform(-0.3, 0.3, 7))
    nu = list(rng.uniform(-0.5, 0.5, 13))
    three.setFloat64([by_name["theta"].valueReference, by_name["nu"].valueReference], theta + nu)
    eps3 = three.getFloat64([by_name["eps"].valueReference], 13)
    three.terminate()
    three.freeInstance()

    from fmpy.fmi2 import FMU2Slave
    directory = extract(str(fmus["fmi2_controller"]), str(tmp_path / "c2"))
    description = read_model_description(str(fmus["fmi2_controller"]))
    two = FMU2Slave(guid=description.guid, unzipDirectory=directory,
                    modelIdentifier=description.coSimulation.modelIdentifier, instanceName="c2")
    vr = {v.name: v.valueReference for v in description.modelVariables}
    two.instantiate()
    two.setupExperiment(startTime=0.0)
    two.enterInitializationMode()
    two.exitInitializationMode()
    two.setReal([vr[f"theta[{k}]"] for k in range(1, 15)] + [vr[f"nu[{k}]"] for k in range(1, 14)], theta + nu)
    eps2 = two.getReal([vr[f"eps[{k}]"] for k in range(1, 14)])
    two.terminate()
    two.freeInstance()
    assert eps3 == eps2 and max(map(abs, eps3)) > 1e-3


def raw(instance):
    """The instance's C functions with statuses returned, not raised."""
    return instance.dll


def test_dependencies_are_the_true_ones(fmus, tmp_path):
    """fmi3GetVariableDependencies says der(nu)[k] depends on θ (but the free
    base's position theta[1..3]: gravity is uniform), ν and eps[k] only, and
    the model description says the same per array; perturbing
    eps[j] moves der(nu)[k] exactly when j = k."""
    instance, by_name = model_exchange(fmus["bus_arm7"], tmp_path, [0, 0, 0, 0.5] + [0.1] * 9)
    dll, c = raw(instance), instance.component
    der_nu, eps = by_name["der(nu)"].valueReference, by_name["eps"].valueReference
    n = c_size_t()
    assert dll.fmi3GetNumberOfVariableDependencies(c, der_nu, byref(n)) == OK
    assert n.value == 13 * (11 + 13 + 1)
    elements, knowns = (c_size_t * n.value)(), (c_uint32 * n.value)()
    known_elements, kinds = (c_size_t * n.value)(), (ctypes.c_int * n.value)()
    assert dll.fmi3GetVariableDependencies(c, der_nu, elements, knowns, known_elements, kinds, n.value) == OK
    on_eps = sorted((elements[i], known_elements[i]) for i in range(n.value) if knowns[i] == eps)
    assert on_eps == [(k, k) for k in range(1, 14)]
    description = read_model_description(str(fmus["bus_arm7"]))
    listed = next(d for d in description.derivatives if d.variable.name == "der(nu)")
    assert sorted(v.valueReference for v in listed.dependencies) == sorted(set(knowns))

    nx = 27

    def derivatives():
        dx = (c_double * nx)()
        instance.getContinuousStateDerivatives(dx, nx)
        return np.array(dx[14:])

    base = derivatives()
    for j in range(13):
        pushed = [0.0] * 13
        pushed[j] = 1.0
        instance.setFloat64([eps], pushed)
        moved = derivatives() != base
        assert list(np.flatnonzero(moved)) == [j], j
    instance.freeInstance()


def test_misuse_is_refused_with_the_right_status(fmus, tmp_path):
    """Wrong types, counts and sequences, NaN, time set, what is not
    provided, a model exchange function on a co-simulation instance, and
    NULL instances: each refused, none crashes."""
    instance, by_name = co_simulation(fmus["bus_arm7"], tmp_path)
    dll, c = raw(instance), instance.component
    eps = by_name["eps"].valueReference
    thirteen = (c_double * 13)()
    one = (c_uint32 * 1)
    step_flags = [c_bool(), c_bool(), c_bool()]
    last = c_double()
    do_step = lambda t, h: dll.fmi3DoStep(c, c_double(t), c_double(h), c_bool(True), *map(byref, step_flags),  # noqa: E731
                                          byref(last))
    assert do_step(0.0, 0.1) == ERROR, "doStep before initialization"
    assert dll.fmi3Reset(c) == OK
    assert dll.fmi3EnterInitializationMode(c, c_bool(False), c_double(0), c_double(0), c_bool(False),
                                           c_double(0)) == OK
    assert dll.fmi3ExitInitializationMode(c) == OK
    assert dll.fmi3GetFloat64(c, one(eps), c_size_t(1), thirteen, c_size_t(12)) == ERROR, "nValues"
    assert dll.fmi3Reset(c) == OK and dll.fmi3EnterInitializationMode(c, False, c_double(0), c_double(0), False,
                                                                      c_double(0)) == OK
    assert dll.fmi3ExitInitializationMode(c) == OK
    method = (c_int64 * 1)()
    assert dll.fmi3GetInt64(c, one(by_name["method"].valueReference), c_size_t(1), method, c_size_t(1)) == OK
    assert method[0] == 3
    assert dll.fmi3GetInt64(c, one(eps), c_size_t(1), method, c_size_t(1)) == ERROR, "Float64 read as Int64"
    assert dll.fmi3Reset(c) == OK
    assert dll.fmi3EnterInitializationMode(c, False, c_double(0), c_double(0), False, c_double(0)) == OK
    assert dll.fmi3ExitInitializationMode(c) == OK
    nan = (c_double * 13)(*([math.nan] + [0.0] * 12))
    assert dll.fmi3SetFloat64(c, one(eps), c_size_t(1), nan, c_size_t(13)) == DISCARD, "NaN"
    assert dll.fmi3SetFloat64(c, one(0), c_size_t(1), (c_double * 1)(1.0), c_size_t(1)) == ERROR, "time"
    assert dll.fmi3Reset(c) == OK
    assert dll.fmi3EnterConfigurationMode(c) == ERROR
    assert dll.fmi3Reset(c) == OK
    nx = c_size_t()
    assert dll.fmi3GetNumberOfContinuousStates(c, byref(nx)) == ERROR, "model exchange on co-simulation"
    instance.freeInstance()

    # Every function that takes an instance, called with NULL (a library handle without FMPy's argument types).
    symbols = subprocess.run(["nm", "-D", "--defined-only", dll._name], capture_output=True, text=True,
                             check=True).stdout.split()
    takes_instance = [name for name in symbols if name.startswith("fmi3") and not name.startswith("fmi3Instantiate")
                      and name not in ("fmi3GetVersion", "fmi3FreeInstance")]
    assert len(takes_instance) == 75 - 5
    bare = ctypes.CDLL(dll._name)
    for function in takes_instance:
        assert getattr(bare, function)(None, 0, 0, 0, 0, 0, 0, 0) == ERROR, function
    bare.fmi3FreeInstance(None)

    directory, description = unzipped(fmus["bus_arm7"], tmp_path / "again")
    callback = ctypes.CFUNCTYPE(None, c_void_p, ctypes.c_uint, ctypes.c_char_p, ctypes.c_char_p)
    messages = []
    log = callback(lambda env, status, category, message: messages.append(message.decode()))
    instantiate = bare.fmi3InstantiateCoSimulation
    instantiate.restype = c_void_p
    resources = (str(directory) + "/resources/").encode()
    token = description.instantiationToken.encode()
    made = instantiate(b"x", token, resources, False, True, True, False, None, c_size_t(0), None, log, None)
    assert made is None and "eventModeUsed" in messages[-1]
    made = instantiate(b"x", b"{wrong}", resources, False, True, False, False, None, c_size_t(0), None, log, None)
    assert made is None and "does not match" in messages[-1]
    scheduled = bare.fmi3InstantiateScheduledExecution
    scheduled.restype = c_void_p
    assert scheduled(b"x", token, resources, False, True, None, log, None, None, None) is None
    assert "scheduled execution" in messages[-1]

