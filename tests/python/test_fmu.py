"""The exported FMI 2.0 co-simulation FMU, driven by FMPy: validation of
every example, agreement with the core library's own integration
(`nudyn simulate`, which does not go through the FMI layer), FMU states,
reset, independent instances, and the rejections of the FMI layer."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, fmi2LastSuccessfulTime, fmi2OK, fmi2Terminated, fmi2Warning
from fmpy.validation import validate_fmu

from conftest import EXAMPLES, ROOT, example_ids
from nudyn_driver.instance import Instance, Log
from nudyn_driver.package import FmuPackage

ALL_OUTPUTS = ("qvel", "kinetic_energy", "power", "momentum", "energy_residual")
STEP = 0.01


@pytest.fixture(scope="session")
def exported(exported_fmu):
    """Each example exported once with every optional output."""
    return {model.stem: exported_fmu(model, outputs=ALL_OUTPUTS) for model in EXAMPLES}


@pytest.fixture(scope="session")
def packages(exported, tmp_path_factory):
    """Each exported example unzipped once."""
    directory = tmp_path_factory.mktemp("unzipped")
    return {name: FmuPackage.unzip(path, directory / name) for name, path in exported.items()}


@pytest.fixture(scope="session")
def structures(cli):
    """Each example's joints and their θ/ν addresses (`nudyn describe`)."""
    return {model.stem: cli.describe(model) for model in EXAMPLES}


def variables(description, prefix: str):
    return [v for v in description.modelVariables if v.name.startswith(prefix + "[")]


def initial_state(structure, seed: int):
    """A tumbling start: qpos0 with hinge/slide offsets and random unit
    quaternions, random nu, constant random eps; as FMPy start values."""
    rng = np.random.default_rng(seed)
    quaternions = set(structure.quaternion_starts)
    start = {}
    k = 0
    while k < structure.nq:
        if k in quaternions:
            q = rng.normal(size=4)
            q /= np.linalg.norm(q)
            start.update({f"theta[{k + 1 + i}]": float(q[i]) for i in range(4)})
            k += 4
        else:
            start[f"theta[{k + 1}]"] = structure.qpos0[k] + float(rng.uniform(-0.5, 0.5))
            k += 1
    nu = {f"nu[{k + 1}]": float(rng.uniform(-1, 1)) for k in range(structure.nv)}
    eps = [float(rng.uniform(-1, 1)) for _ in range(structure.nv)]
    return start, nu, eps


def core_trajectory(cli, model: Path, theta, nu, eps, step: float, stop: float, *options: str):
    request = json.dumps({"theta": theta, "nu": nu, "eps": eps})
    stdout = cli.run("simulate", model, "--step", repr(step), "--stop", repr(stop), *options, stdin=request)
    return json.loads(stdout)


def advance(instance: Instance, steps: int = 1) -> None:
    """`steps` communication steps of STEP."""
    for _ in range(steps):
        instance.step(STEP)


@pytest.mark.parametrize("model", EXAMPLES, ids=example_ids())
def test_model_description_is_valid(model, exported):
    path = exported[model.stem]
    assert validate_fmu(str(path)) == []
    description = read_model_description(str(path), validate=True)
    assert description.variableNamingConvention == "structured"
    cs = description.coSimulation
    assert cs.canHandleVariableCommunicationStepSize and cs.canInterpolateInputs
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate
    assert cs.maxOutputDerivativeOrder == 1 and not cs.canBeInstantiatedOnlyOncePerProcess
    theta, nu, eps = (variables(description, p) for p in ("theta", "nu", "eps"))
    assert len(nu) == len(eps) and len(theta) >= len(nu)
    assert [v.name for v in theta] == [f"theta[{k + 1}]" for k in range(len(theta))]
    assert all(v.causality == "output" and v.initial == "exact" for v in theta + nu)
    assert all(v.causality == "input" and float(v.start) == 0.0 for v in eps)
    assert all("joint '" in v.description and "(" in v.description for v in theta + nu + eps)
    assert len(variables(description, "momentum")) == 6


def test_outputs_not_chosen_do_not_exist(cli, tmp_path):
    path = cli.export(ROOT / "examples/fixed_rig.xml", tmp_path / "rig.fmu", model_identifier="rig")
    description = read_model_description(str(path), validate=True)
    names = {v.name for v in description.modelVariables}
    assert description.coSimulation.modelIdentifier == "rig"
    assert not names & {"kinetic_energy", "power", "qvel[1]", "momentum[1]"}
    assert {"theta[1]", "nu[1]", "eps[1]", "method", "tolerance", "max_step"} <= names


def fmu_run(package: FmuPackage, start, eps, stop: float, max_step: float, output_names):
    """simulate_fmu with RK4, the start values and a constant eps input table."""
    signals = np.array(
        [(0.0, *eps), (stop, *eps)],
        dtype=[("time", np.float64)] + [(name, np.float64) for name in package.names("eps")],
    )
    return simulate_fmu(
        str(package.directory),
        stop_time=stop,
        output_interval=STEP,
        start_values={**start, "max_step": max_step, "method": package.methods["rk4"]},
        input=signals,
        output=output_names,
    )


@pytest.mark.parametrize("model", EXAMPLES, ids=example_ids())
@pytest.mark.parametrize("substeps", [1, 4])
def test_fmu_equals_core_integration(model, substeps, packages, structures, cli):
    """The FMU's outputs equal `nudyn simulate` from the same state with the
    same RK4 step, to round-off."""
    package = packages[model.stem]
    start, nu_start, eps = initial_state(structures[model.stem], seed=len(model.stem))
    theta_names, nu_names = package.names("theta"), package.names("nu")
    stop = 0.1
    result = fmu_run(package, {**start, **nu_start}, eps, stop, STEP / substeps, theta_names + nu_names)

    theta0 = [start.get(name, value) for name, value in zip(theta_names, package.starts("theta"))]
    core = core_trajectory(cli, model, theta0, [nu_start[n] for n in nu_names], eps, STEP / substeps, stop)
    core_theta = np.array(core["theta"])[::substeps]
    core_nu = np.array(core["nu"])[::substeps]
    fmu_theta = np.column_stack([result[n] for n in theta_names])
    fmu_nu = np.column_stack([result[n] for n in nu_names])
    assert np.allclose(result["time"], np.array(core["time"])[::substeps], rtol=0, atol=1e-12)
    np.testing.assert_allclose(fmu_theta, core_theta, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(fmu_nu, core_nu, rtol=1e-13, atol=1e-13)
    assert not np.allclose(fmu_nu[-1], fmu_nu[0]), "the state must actually move"


@pytest.fixture
def bus(packages, structures):
    package = packages["bus_arm7"]
    start, nu, eps = initial_state(structures["bus_arm7"], seed=7)
    eps_values = dict(zip(package.names("eps"), eps))
    slaves = []

    def make(name="instance", with_start=True, method=None):
        parameters = {} if method is None else {"method": method}
        slave = Instance(package, name=name, start={**start, **nu, **parameters} if with_start else None)
        slave.set(eps_values)
        slaves.append(slave)
        return slave

    yield make
    for slave in slaves:
        # Legal in every state, error included (FMI 2.0 §4.2.4).
        slave.fmu.freeInstance()


@pytest.mark.parametrize("scale", [1e-160, 1e160, 1e300], ids=lambda s: f"{s:.0e}")
def test_start_quaternions_of_any_finite_scale_are_the_same_rotation(packages, structures, scale):
    """The free base's start quaternion scaled by 1e-160 or 1e300 initializes
    to the unit quaternion, with the same momentum as the unit one gives."""
    package = packages["bus_arm7"]
    start, nu, _ = initial_state(structures["bus_arm7"], seed=7)
    quaternion = package.names("theta")[3:7]
    scaled = {**start, **{name: start[name] * scale for name in quaternion}}
    with Instance(package, start={**start, **nu}) as unit, Instance(package, start={**scaled, **nu}) as edge:
        got, want = edge.array("theta"), unit.array("theta")
        # 1e-160 and 1e300 scale with rounding: the direction given differs in the last bits.
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)
        assert abs(np.linalg.norm(got[3:7]) - 1.0) <= 4e-16
        momentum = unit.array("momentum")
        assert np.linalg.norm(edge.array("momentum") - momentum) <= 1e-14 * np.linalg.norm(momentum)


@pytest.mark.parametrize("method", ["dop853", "ros34pw2", "bs3", "tsit5", "auto"])
def test_fmu_state_round_trips_bit_exactly(bus, method):
    """With ros34pw2 too, whose matrix W is kept across communication
    points and so is part of the state: restored from the object or from
    its bytes, the run continues bit for bit."""
    slave = bus(method=method)
    advance(slave, 3)
    state = slave.fmu.getFMUstate()
    blob = slave.fmu.serializeFMUstate(state)
    saved = slave.all_reals()
    advance(slave, 5)
    after = slave.all_reals()

    slave.fmu.setFMUstate(state)
    assert np.array_equal(slave.all_reals(), saved)
    slave.time = 3 * STEP
    advance(slave, 5)
    assert np.array_equal(slave.all_reals(), after)

    restored = slave.fmu.deSerializeFMUstate(blob)
    assert slave.fmu.serializeFMUstate(restored) == blob
    slave.fmu.setFMUstate(restored)
    assert np.array_equal(slave.all_reals(), saved)
    slave.time = 3 * STEP
    advance(slave, 5)
    assert np.array_equal(slave.all_reals(), after)
    slave.fmu.freeFMUstate(restored)
    slave.fmu.freeFMUstate(state)


def test_corrupt_or_foreign_states_are_rejected(bus, packages):
    """Each rejection is fmi2Error, so the instance enters the error state
    (FMI 2.0 §2.1.3); its values are unchanged, and restoring a state saved
    before lets it go on."""
    slave = bus()
    advance(slave, 2)
    state = slave.fmu.getFMUstate()
    blob = bytearray(slave.fmu.serializeFMUstate(state))
    before = slave.all_reals()
    corrupt = bytearray(blob)
    corrupt[len(corrupt) // 2] ^= 0x10
    for bad in (bytes(corrupt), bytes(blob[:-1]), bytes(blob) + b"\0", b"not a state"):
        with pytest.raises(FMICallException):
            slave.fmu.deSerializeFMUstate(bad)
        slave.fmu.setFMUstate(state)
    assert "corrupted" in slave.log.text() and "truncated" in slave.log.text()
    # A state of another FMU (another GUID) is refused too.
    rig = Instance(packages["fixed_rig"])
    rig_blob = rig.fmu.serializeFMUstate(rig.fmu.getFMUstate())
    with pytest.raises(FMICallException):
        slave.fmu.deSerializeFMUstate(rig_blob)
    assert "belongs to the FMU with GUID" in slave.log.text()
    assert np.array_equal(slave.all_reals(), before), "a rejected state changes nothing"
    slave.fmu.setFMUstate(state)
    slave.fmu.freeFMUstate(state)
    advance(slave)


def test_reset_then_rerun_is_identical(bus):
    slave = bus()
    start = {n: float(x) for n, x in zip(slave.package.reals, slave.all_reals()) if n.startswith(("theta", "nu", "eps"))}
    advance(slave, 10)
    first = slave.all_reals()
    slave.fmu.reset()
    slave.fmu.setupExperiment(startTime=0.0)
    slave.set(start)
    slave.fmu.enterInitializationMode()
    slave.fmu.exitInitializationMode()
    slave.time = 0.0
    advance(slave, 10)
    assert np.array_equal(slave.all_reals(), first)


def test_reset_returns_to_the_model_start(bus):
    slave = bus()
    advance(slave, 2)
    slave.fmu.reset()
    slave.fmu.setupExperiment(startTime=0.0)
    slave.fmu.enterInitializationMode()
    theta = [v for v in slave.package.variables.values() if v.name.startswith(("theta[", "nu[", "eps["))]
    assert np.array_equal(slave.get([v.name for v in theta]), [float(v.start) for v in theta])
    slave.fmu.exitInitializationMode()


def test_two_instances_do_not_interfere(bus):
    alone = bus("alone")
    advance(alone, 6)
    expected = alone.all_reals()
    a, b = bus("a"), bus("b", with_start=False)
    for _ in range(6):
        advance(a)
        advance(b)
    assert np.array_equal(a.all_reals(), expected)
    assert not np.array_equal(b.all_reals(), expected)


def test_terminate_keeps_final_values_readable(bus):
    slave = bus()
    advance(slave, 3)
    final = slave.all_reals()
    slave.fmu.terminate()
    assert np.array_equal(slave.all_reals(), final)
    with pytest.raises(FMICallException):
        slave.fmu.terminate()
    assert "fmi2Terminate may not be called in state terminated" in slave.log.text()


def test_output_derivatives(bus, cli):
    """d(nu)/dt is nu_dot of `nudyn eval`; d(theta)/dt of a hinge is its qvel."""
    slave = bus()
    advance(slave, 2)
    nu_names = slave.package.names("nu")
    request = {p: list(slave.array(p)) for p in ("theta", "nu", "eps")}
    expected = cli.eval(ROOT / "examples/bus_arm7.xml", request)
    nu_rate = slave.fmu.getRealOutputDerivatives([slave.package.vr[n] for n in nu_names], [1] * len(nu_names))
    np.testing.assert_allclose(nu_rate, expected["nu_dot"], rtol=1e-12, atol=1e-12)
    # theta[8..14] are the arm's hinges, qvel[7..13].
    theta_rate = slave.fmu.getRealOutputDerivatives([slave.package.vr[f"theta[{k}]"] for k in range(8, 15)], [1] * 7)
    np.testing.assert_allclose(theta_rate, expected["qvel"][6:], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(slave.get([f"qvel[{k}]" for k in range(1, 14)]), expected["qvel"], rtol=1e-12, atol=1e-12)


def test_input_ramp_changes_the_step(bus):
    """fmi2SetRealInputDerivatives makes eps ramp within the next step only."""
    held, ramped = bus("held"), bus("ramped")
    ramped.fmu.setRealInputDerivatives([ramped.package.vr["eps[7]"]], [1], [50.0])
    advance(held)
    advance(ramped)
    assert not np.array_equal(held.get(["nu[7]"]), ramped.get(["nu[7]"]))
    # After the step the ramp is over: both go on with the same held eps.
    state = held.fmu.getFMUstate()
    held_blob = held.fmu.serializeFMUstate(state)
    held.fmu.freeFMUstate(state)
    copy = ramped.fmu.deSerializeFMUstate(held_blob)
    ramped.fmu.setFMUstate(copy)
    ramped.fmu.freeFMUstate(copy)
    advance(held)
    advance(ramped)
    assert np.array_equal(held.all_reals(), ramped.all_reals())


def test_input_ramp_equals_core_integration(bus, cli):
    """One communication step of 4 internal steps with dε/dt set equals the
    core integration of ε(t) = ε + dε/dt·t with the same internal step."""
    slave = bus()
    state = {p: [float(x) for x in slave.array(p)] for p in ("theta", "nu", "eps")}
    rate = [float(x) for x in np.linspace(-20.0, 20.0, slave.package.nv)]
    slave.fmu.setRealInputDerivatives(slave.package.refs("eps"), [1] * len(rate), rate)
    slave.fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=4e-3)
    request = json.dumps({**state, "eps_rate": rate})
    core = json.loads(cli.run("simulate", ROOT / "examples/bus_arm7.xml", "--step", "1e-3", "--stop", "4e-3", stdin=request))
    np.testing.assert_allclose(slave.array("theta"), core["theta"][-1], rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(slave.array("nu"), core["nu"][-1], rtol=1e-13, atol=1e-13)


def test_rejections_are_logged_and_change_nothing(bus):
    """A call refused with fmi2Error leaves the values as they were and the
    instance in the error state, where fmi2SetFMUstate to a state saved
    before goes on (FMI 2.0 §2.1.3); a value out of its range passed to
    fmi2SetReal is fmi2Discard and the instance stays usable."""
    slave = bus()
    advance(slave)
    before = slave.all_reals()
    saved = slave.fmu.getFMUstate()
    refusals = [
        (lambda: slave.fmu.doStep(currentCommunicationPoint=0.5, communicationStepSize=STEP),
         f"expected currentCommunicationPoint = {STEP} but was 0.5"),
        (lambda: slave.set({"theta[8]": 1.0}), "theta[8] (value reference"),
        (lambda: slave.fmu.getReal([99999]), "unknown value reference 99999"),
        (lambda: slave.set({"kinetic_energy": 1.0}), "calculated output"),
        (lambda: slave.fmu.enterInitializationMode(), "fmi2EnterInitializationMode may not be called in state stepComplete"),
    ]
    for call, message in refusals:
        with pytest.raises(FMICallException) as refused:
            call()
        assert refused.value.status == 3 and message in slave.log.text()
        assert np.array_equal(slave.all_reals(), before)
        with pytest.raises(FMICallException, match="error"):
            advance(slave)
        assert "fmi2DoStep may not be called in state error" in slave.log.text()
        slave.fmu.setFMUstate(saved)
    with pytest.raises(FMICallException) as discarded:
        slave.set({"eps[1]": float("nan")})
    assert discarded.value.status == 2 and "eps[1] = NaN is not finite" in slave.log.text()
    assert np.array_equal(slave.all_reals(), before)
    slave.fmu.freeFMUstate(saved)
    advance(slave)


def test_non_finite_state_is_discarded_not_output(bus):
    slave = bus()
    slave.set({"eps[1]": 1e300, "eps[2]": -1e300})
    before = slave.all_reals()
    with pytest.raises(FMICallException) as failure:
        advance(slave)
    assert failure.value.status == 2  # fmi2Discard
    assert slave.fmu.getBooleanStatus(fmi2Terminated)
    assert np.array_equal(slave.all_reals(), before)
    assert np.all(np.isfinite(slave.all_reals()))
    assert slave.fmu.getRealStatus(fmi2LastSuccessfulTime) == 0.0
    assert "stopped at t = 0: " in slave.log.text()
    assert "is not finite" in slave.log.text()


def test_discarded_step_stops_where_the_integration_stopped(bus):
    """A ramp to an overflowing ε: the step gets partway, the state stays
    there, finite, and fmi2LastSuccessfulTime says where."""
    slave = bus()
    slave.fmu.setRealInputDerivatives([slave.package.vr["eps[8]"]], [1], [1e20])
    with pytest.raises(FMICallException) as failure:
        advance(slave)
    assert failure.value.status == 2  # fmi2Discard
    reached = slave.fmu.getRealStatus(fmi2LastSuccessfulTime)
    assert 0.0 < reached < STEP
    stopped_at = re.search(r"stopped at t = ([0-9.e+-]+)", slave.log.text())
    assert stopped_at and float(stopped_at.group(1)) == reached
    assert np.all(np.isfinite(slave.all_reals()))


def test_guid_mismatch_fails_instantiation(packages):
    package = packages["fixed_rig"]
    log = Log()
    fmu = FMU2Slave(guid="{00000000-0000-0000-0000-000000000000}", unzipDirectory=str(package.directory),
                    modelIdentifier=package.model_identifier, instanceName="wrong")
    with pytest.raises(Exception):
        fmu.instantiate(callbacks=log.callbacks)
    assert "does not match the FMU's resources" in log.text()


def test_resource_location_with_spaces(exported, tmp_path):
    """The resource URI is percent-encoded by FMPy; the FMU decodes it."""
    path = exported["fixed_rig"]
    unzipdir = tmp_path / "dir with spaces"
    shutil.unpack_archive(str(path), str(unzipdir), "zip")
    slave = Instance(FmuPackage(unzipdir))
    advance(slave, 2)
    assert np.all(np.isfinite(slave.all_reals()))


def test_logging_honours_set_debug_logging(bus):
    slave = bus()
    slave.fmu.setDebugLogging(False, [])
    with pytest.raises(FMICallException):
        slave.fmu.getReal([99999])
    assert slave.log.messages == [], "all categories off"
    slave.fmu.setDebugLogging(True, ["logCalls", "logStatusError"])
    slave.fmu.getReal([slave.package.vr["nu[1]"]])
    assert any(c == "logCalls" and "fmi2GetReal returned status 0" in m for _, c, m in slave.log.messages)
    with pytest.raises(FMICallException):
        slave.fmu.setDebugLogging(True, ["noSuchCategory"])
    assert "unknown log category 'noSuchCategory'" in slave.log.text()


def test_setup_experiment_tolerance_replaces_the_parameter(packages):
    package = packages["bus_arm7"]
    chosen = Instance(package, name="parameter", start={"tolerance": 1e-10})
    assert chosen.real("tolerance") == 1e-10
    importer = Instance(package, name="importer", start={"tolerance": 1e-10}, experiment_tolerance=1e-4)
    assert importer.real("tolerance") == 1e-4
    # Hosts pass their own default without a word (OMSimulator, PyFMI: 1e-4): the FMU says it.
    assert importer.log.method_choices() == [
        "the tolerance 1e-4 the host passed (fmi2SetupExperiment, fmi3EnterInitializationMode) replaces the FMU's "
        "tolerance parameter 1e-10: the error is held to 1e-4 per second"
    ]
    same = Instance(package, name="same", start={"tolerance": 1e-4}, experiment_tolerance=1e-4)
    assert chosen.log.method_choices() == same.log.method_choices() == []
    for slave in (chosen, importer, same):
        slave.close()


@pytest.mark.parametrize("method", ["dopri5", "dop853", "ros34pw2", "bs3", "tsit5"])
def test_adaptive_methods_meet_their_tolerance_through_fmi(packages, structures, method):
    """1 s of bus_arm7 tumbling under a constant eps, at tolerance 1e-8 (per
    second), against RK4 with 1e-4 s steps (error ~1e-14), through the FMU."""
    package = packages["bus_arm7"]
    start, nu, eps = initial_state(structures["bus_arm7"], seed=3)
    eps_values = dict(zip(package.names("eps"), eps))
    outputs = package.names("theta") + package.names("nu")

    def trajectory(slave):
        slave.set(eps_values)
        rows = []
        for _ in range(100):
            advance(slave)
            rows.append(slave.get(outputs))
        slave.close()
        return np.array(rows)

    reference = trajectory(Instance(package, name="rk4", start={**start, **nu, "max_step": 1e-4, "method": "rk4"}))
    adaptive = trajectory(Instance(package, name=method, start={**start, **nu, "tolerance": 1e-8, "method": method}))
    error = np.max(np.abs(adaptive - reference) / (1 + np.abs(reference)))
    assert 0 < error <= 1.5e-8, error


def test_energy_projection_keeps_kinetic_energy_through_fmi(packages, structures):
    """bus_arm7 tumbling without input for 20 s in 1 s communication steps
    at a loose tolerance: the energy residual shows the drift, and
    energy_projection removes it."""
    package = packages["bus_arm7"]
    start, nu, _ = initial_state(structures["bus_arm7"], seed=4)
    drift = {}
    for projection in (False, True):
        slave = Instance(package, name=str(projection), start={**start, **nu, "tolerance": 1e-3, "max_step": 1.0,
                                                               "energy_projection": projection})
        k0 = slave.real("kinetic_energy")
        for _ in range(20):
            slave.step(1.0)
        k, residual = slave.get(["kinetic_energy", "energy_residual"])
        assert abs(residual - (k - k0)) <= 1e-12 * k0  # no force acts: the residual is the drift
        drift[projection] = abs(k - k0) / k0
        slave.close()
    assert drift[False] > 1e-9, drift
    assert drift[True] < 1e-13, drift
    assert drift[False] > 1e4 * drift[True], drift


@pytest.mark.parametrize("method", ["dopri5", "dop853", "ros34pw2", "bs3", "tsit5", "auto"])
def test_fmu_equals_core_integration_with_adaptive_methods(packages, structures, cli, method):
    """The FMU's adaptive runs are `nudyn simulate`'s, to round-off: same
    steps, same carried step size across communication points."""
    model = next(m for m in EXAMPLES if m.stem == "bus_arm7")
    package = packages["bus_arm7"]
    start, nu_start, eps = initial_state(structures["bus_arm7"], seed=9)
    theta_names, nu_names = package.names("theta"), package.names("nu")
    signals = np.array([(0.0, *eps), (1.0, *eps)],
                       dtype=[("time", np.float64)] + [(name, np.float64) for name in package.names("eps")])
    parameters = {"method": package.methods[method], "tolerance": 1e-7, "max_step": 0.05}
    result = simulate_fmu(str(package.directory), stop_time=0.5, output_interval=STEP,
                          start_values={**start, **nu_start, **parameters}, input=signals, output=theta_names + nu_names)
    theta0 = [start.get(name, value) for name, value in zip(theta_names, package.starts("theta"))]
    core = core_trajectory(cli, model, theta0, [nu_start[n] for n in nu_names], eps, STEP, 0.5,
                           "--method", method, "--tolerance", "1e-7", "--max-step", "0.05")
    fmu = np.column_stack([result[n] for n in theta_names + nu_names])
    np.testing.assert_allclose(fmu, np.hstack([core["theta"], core["nu"]]), rtol=1e-13, atol=1e-13)


def test_unattainable_tolerance_is_a_warning_not_a_failure(nudyn, cli, tmp_path):
    """Rods of inertia diag(1e-9, 1, 1): round-off in ν̇ exceeds 1e-8 per
    second at any step size. The steps complete with fmi2Warning, a
    logStatusWarning message says what tolerance was held instead, and the
    outputs stay finite (before, every adaptive step was discarded)."""
    from nudyn_stress.measures import nu_of

    model = ROOT / "tests" / "fixtures" / "thin_rods.xml"
    path = cli.export(model, tmp_path / "thin_rods.fmu")
    theta = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.9553, 0.0, 0.0, 0.2955, 0.9801, 0.0, 0.1987, 0.0, 0.0]
    qvel = np.random.default_rng(8).normal(0.0, 2.0, len(theta) - 3)
    nu = nu_of(nudyn, model, theta, qvel)
    start = {f"theta[{k + 1}]": x for k, x in enumerate(theta)} | {f"nu[{k + 1}]": x for k, x in enumerate(nu)}
    slave = Instance(FmuPackage.unzip(path, tmp_path / "unzipped"), start={**start, "method": "dop853"},
                     experiment_tolerance=1e-8)
    statuses = [slave.step(STEP) for _ in range(50)]
    assert fmi2Warning in statuses and set(statuses) <= {fmi2OK, fmi2Warning}, statuses
    warnings = [m for s, c, m in slave.log.messages if c == "logStatusWarning"]
    assert len(warnings) == statuses.count(fmi2Warning) and all(s == fmi2Warning for s, c, _ in slave.log.messages)
    held = [float(re.search(r"held to ([0-9.e+-]+) per second", m).group(1)) for m in warnings]
    assert all("tolerance 1e-8 per second is below what round-off" in m for m in warnings), warnings[0]
    assert not any("diverges" in m for m in warnings), warnings[0]
    assert held == sorted(held) and held[0] > 1e-8, held
    assert slave.fmu.getRealStatus(fmi2LastSuccessfulTime) == pytest.approx(50 * STEP)
    assert np.all(np.isfinite(slave.all_reals()))
    slave.fmu.freeInstance()


def test_a_diverging_closed_loop_is_not_blamed_on_round_off(cli, tmp_path):
    """The plant and its controller FMU in a Gauss–Seidel loop at h = 0.01 s
    with c1 = 300 /s: c1·h = 3 is past the sampled loop's limit of 2, so |ν|
    doubles each step. The plant's warning used to blame round-off in the
    vehicle's rates ("tolerance 1e-8 per second is below what round-off ...
    allows"); it must say the motion diverges, by how much the rates grew,
    and the error held relative to the state's size."""
    model = EXAMPLES[0].parent / "bus_arm7.xml"
    plant_package = FmuPackage.unzip(cli.export(model, tmp_path / "plant.fmu"), tmp_path / "plant")
    controller_package = FmuPackage.unzip(cli.export(model, tmp_path / "controller.fmu", controller=True),
                                          tmp_path / "controller")
    plant = Instance(plant_package, name="plant", nu=[0.1] * plant_package.nv)
    controller = Instance(controller_package, name="controller",
                          start={name: 300.0 for name in controller_package.names("c1")})
    start = np.linalg.norm(plant.array("nu"))
    try:
        for k in range(40):
            controller.set_array("theta", plant.array("theta"))
            controller.set_array("nu", plant.array("nu"))
            plant.set_array("eps", controller.array("eps"))
            if plant.step(STEP, communication_point=k * STEP) == fmi2Warning:
                break
            controller.step(STEP, communication_point=k * STEP)
        else:
            pytest.fail(f"no warning in 40 steps: |nu| = {np.linalg.norm(plant.array('nu')):.1e}")
        grown = np.linalg.norm(plant.array("nu")) / start
        (warning,) = [m for _, c, m in plant.log.messages if c == "logStatusWarning"]
        assert grown > 1e4, grown
        assert warning.startswith("fmi2DoStep: the motion diverges: the rates grew "), warning
        factor = float(re.search(r"grew (\S+)-fold since the start", warning).group(1))
        assert factor > grown and "an unstable loop around the FMU" in warning and "round-off" not in warning, warning
        assert re.search(r"held to \S+ per second, relative to 1 \+ \|x\| for each coordinate and velocity x", warning)
        assert plant.log.held_tolerance() > 1e-8
    finally:
        plant.close()
        controller.close()
