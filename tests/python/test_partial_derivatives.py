"""The plant FMU's partial derivatives (docs/fmi.md, "Partial derivatives"),
through FMPy: fmi2GetDirectionalDerivative (model exchange and
co-simulation) and fmi3GetDirectionalDerivative / fmi3GetAdjointDerivative
(both interfaces) of bus_arm7 (free base, 7 hinges) and
tests/fixtures/springs/springdamper.xml (free base, hinge, ball and slide
joints with springs and dampers, under gravity).

At a state off every symmetry (quaternions a little off unit length, which
the FMU normalizes) the derivatives of the state derivatives and outputs
with respect to θ (along its coordinates), ν and ε equal central
differences of the same FMU's values, moved through fmi2SetContinuousStates
(model exchange) or the initial state (co-simulation's initialization
mode); the adjoint is the transpose of the directional derivative; an FMU
the derivatives do not cover (one with the energy residual, a record of
its integration) declares none and refuses the call, naming what is
missing. The outputs include the momentum, and the flexible bench's modal
strain energy. Constrained vehicles,
tests/fixtures/actuators/kinds.xml (every actuator kind, ctrl a known)
and tests/fixtures/sensors/every_sensor.xml (its sensors among the
unknowns) too; the docked servicer's force, torque and limit sensors in
the ModelStructure check. Activation states (tests/fixtures/activation/
shortcut_servos.xml: MuJoCo's intvelocity and cylinder) as knowns and
unknowns: act among the states, der(act) among the derivatives."""

from __future__ import annotations

import xml.etree.ElementTree as ET
import json
import zipfile
from ctypes import c_double, c_uint

import mujoco
import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Model, FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, defaultCallbacks
from fmpy.fmi3 import FMU3Model, FMU3Slave, fmi3LogMessageCallback

from conftest import EXAMPLES_DIR, ROOT
from nudyn_driver.package import FmuPackage

MODELS = {
    "bus_arm7": EXAMPLES_DIR / "bus_arm7.xml",
    "springdamper": ROOT / "tests" / "fixtures" / "springs" / "springdamper.xml",
    # A flexible bench on a hinge of a free bus: its modes are a block of the passes (docs/flexible.md).
    "bench_vehicle": ROOT / "tests" / "fixtures" / "flex" / "bench_vehicle.xml",
    # Constraint forces: a connect, a joint coupling, friction loss and
    # limits (slider_hand); a connect, joint and tendon limits on a spatial
    # tendon, refsafe off (refsafe_off). In model exchange the FMU holds
    # its constraint mode between events, and its derivatives are that mode's.
    "slider_hand": ROOT / "tests" / "fixtures" / "constraints" / "slider_hand.xml",
    "refsafe_off": ROOT / "tests" / "fixtures" / "constraints" / "refsafe_off.xml",
    # MuJoCo's no-slip pass over friction rows in two islands: its
    # decisions (each sweep's clamps, each island's sweeps) held with the mode.
    "noslip_trees": ROOT / "tests" / "fixtures" / "constraints" / "noslip_trees.xml",
    # The tendons' armature, with a connect, a tendon coupling, friction loss and limits.
    "tendon_armature": ROOT / "tests" / "fixtures" / "tendons" / "tendon_armature.xml",
    # Every actuator kind, transmission, gain and clamp, its ctrl a known
    # (set inside each range, away from the clamps), and joint limits.
    "kinds": ROOT / "tests" / "fixtures" / "actuators" / "kinds.xml",
    # Sensors as unknowns: every kind but the limits' and the force and
    # torque (joint, ball, frame, subtree, gyro, velocimeter, magnetometer,
    # accelerometer, actuator sensors, cutoffs, the clock).
    "every_sensor": ROOT / "tests" / "fixtures" / "sensors" / "every_sensor.xml",
    # Activation states (integrators limited to their ranges, filters):
    # act a state after θ and ν, set inside each range, clear of the clamps.
    "shortcut_servos": ROOT / "tests" / "fixtures" / "activation" / "shortcut_servos.xml",
}
# The docked servicer's force, torque and joint limit sensors through welds
# and a connect: its ModelStructure is checked against the exact Jacobian.
# (Its stiff welds leave the FMU's own differences 1e-5 off at 0.01 rad
# from qpos0, 0.7 at this test's 0.2: round-off of forces of 1e9 N.)
DOCKED = ROOT / "tests" / "fixtures" / "constraints" / "docked_servicer.xml"
# Their rows of der(nu) reach 1e8 at these states (the constraints pulled
# 0.2 rad off): the differences' round-off is of the row's size, so their
# error is taken relative to each row's largest entry (measured 2e-8 at
# STEP, 2e-10 at 1e-6 on slider_hand), and ε reaches ν̇ through the
# constraint forces, not as the identity.
CONSTRAINED = {"slider_hand", "refsafe_off", "noslip_trees", "tendon_armature", "kinds", "docked_servicer"}
OUTPUTS = ("qvel", "kinetic_energy", "power", "momentum")
# Central differences' step; with it the exact derivatives are within
# 2e-8 relative of them on bus_arm7 and 2e-9 on springdamper (measured).
STEP = 1e-5


@pytest.fixture(scope="module")
def fmus(cli, tmp_path_factory):
    directory = tmp_path_factory.mktemp("partials")
    def outputs(name):
        return OUTPUTS + (("modal_strain_energy",) if name == "bench_vehicle" else ())

    return {(name, version): cli.export(path, directory / f"{name}{version}.fmu", outputs=outputs(name),
                                        fmi_version=version)
            for name, path in MODELS.items() for version in (2, 3)}


class Names:
    """The knowns (θ, ν, act, ε, ctrl) and unknowns (der(θ), der(ν),
    der(act), θ, ν, act and the continuous outputs) of an FMU, element by
    element, as FMI 2.0 names."""

    def __init__(self, fmu2, model=None):
        package = FmuPackage.unzip(fmu2, fmu2.parent / (fmu2.stem + "-unzipped"))
        self.package = package
        self.theta, self.nu, self.eps = package.names("theta"), package.names("nu"), package.names("eps")
        self.ctrl, self.act = package.names("ctrl"), package.names("act")
        # MuJoCo's ctrlrange of each actuator and actrange of each
        # activation ((0, 0) without one) of the MJCF `model`.
        self.ctrl_ranges, self.act_ranges = [], []
        if self.ctrl:
            compiled = mujoco.MjModel.from_xml_path(str(model))
            limited = compiled.actuator_ctrllimited == 1
            self.ctrl_ranges = [tuple(r) if on else (0.0, 0.0) for r, on in zip(compiled.actuator_ctrlrange, limited)]
            self.act_ranges = [tuple(compiled.actuator_actrange[i]) if compiled.actuator_actlimited[i] else (0.0, 0.0)
                               for i in range(compiled.nu) if compiled.actuator_dyntype[i] != 0]
        self.states = self.theta + self.nu + self.act
        self.knowns = self.states + self.eps + self.ctrl
        self.sensordata = package.names("sensordata")
        self.momentum = package.names("momentum")
        self.scalars = [name for name in ("kinetic_energy", "power", "modal_strain_energy") if name in package.vr]
        self.unknowns = ([f"der({n})" for n in self.states] + self.states + self.sensordata
                         + package.names("qvel") + self.momentum + self.scalars)


def random_point(names: Names, seed: int) -> np.ndarray:
    """θ near its start (quaternions off unit length), ν and ε at random,
    ctrl and act inside each range's middle (within ±0.5 without one),
    clear of the clamps, whose pieces a difference would straddle."""
    rng = np.random.default_rng(seed)
    theta = np.array(names.package.starts("theta")) + rng.normal(0, 0.2, len(names.theta))

    def within(ranges):
        return [low + (high - low) * rng.uniform(0.3, 0.7) if low < high else rng.uniform(-0.5, 0.5)
                for low, high in ranges]

    ctrl = within(names.ctrl_ranges)
    act = within(names.act_ranges) if names.act else []
    return np.concatenate([theta, rng.normal(0, 0.7, len(names.nu)), act, rng.normal(0, 2.0, len(names.eps)), ctrl])


class Fmi2:
    """An FMI 2.0 instance at a point: model exchange after initialization
    (the state through fmi2SetContinuousStates), or co-simulation in
    initialization mode (θ and ν settable as initial values)."""

    def __init__(self, fmu, names: Names, interface: str, directory):
        package = FmuPackage.unzip(fmu, directory)
        self.names, self.vr = names, package.vr
        self.messages: list[str] = []
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(
            lambda env, instance, status, category, message: self.messages.append(message.decode()))
        self.callbacks.allocateMemory = defaultCallbacks.allocateMemory
        self.callbacks.freeMemory = defaultCallbacks.freeMemory
        kind = FMU2Model if interface == "ME" else FMU2Slave
        self.fmu = kind(guid=package.guid, unzipDirectory=str(package.directory),
                        modelIdentifier=package.model_identifier, instanceName="partials")
        self.interface = interface
        self.fmu.instantiate(callbacks=self.callbacks)
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        if interface == "ME":
            self.fmu.exitInitializationMode()
            self.fmu.newDiscreteStates()
            self.fmu.enterContinuousTimeMode()

    def refs(self, names):
        return [self.vr[n] for n in names]

    def set(self, point):
        names, nx = self.names, len(self.names.states)
        if self.interface == "ME":
            self.fmu.setContinuousStates((c_double * nx)(*point[:nx]), nx)
            self.fmu.setReal(self.refs(names.knowns[nx:]), list(point[nx:]))
        else:
            self.fmu.setReal(self.refs(names.knowns), list(point))

    def values(self):
        return np.array(self.fmu.getReal(self.refs(self.names.unknowns)))

    def directional(self, seed, unknowns=None, knowns=None):
        unknowns = self.names.unknowns if unknowns is None else unknowns
        knowns = self.names.knowns if knowns is None else knowns
        return np.array(self.fmu.getDirectionalDerivative(self.refs(unknowns), self.refs(knowns), list(seed)))


class Fmi3:
    """The same through FMI 3.0, whose value references name whole arrays."""

    def __init__(self, fmu, names: Names, interface: str, directory):
        description = read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in description.modelVariables}
        self.names = names
        self.messages: list[str] = []
        kind = FMU3Model if interface == "ME" else FMU3Slave
        self.fmu = kind(guid=description.guid, unzipDirectory=str(self._unzip(fmu, directory)),
                        modelIdentifier=description.coSimulation.modelIdentifier, instanceName="partials")
        self.interface = interface
        self.fmu.instantiate(logMessage=fmi3LogMessageCallback(
            lambda env, status, category, message: self.messages.append(message.decode())))
        self.fmu.enterInitializationMode(startTime=0.0)
        if interface == "ME":
            self.fmu.exitInitializationMode()
            self.fmu.updateDiscreteStates()
            self.fmu.enterContinuousTimeMode()
        nq, nv, na = len(names.theta), len(names.nu), len(names.act)
        acts = [("act", na)] if na else []
        # The arrays, and how many elements each has.
        self.known_arrays = ([("theta", nq), ("nu", nv), *acts, ("eps", nv)]
                             + ([("ctrl", len(names.ctrl))] if names.ctrl else []))
        self.unknown_arrays = [("der(theta)", nq), ("der(nu)", nv), *([("der(act)", na)] if na else []),
                               ("theta", nq), ("nu", nv), *acts,
                               *([("sensordata", len(names.sensordata))] if names.sensordata else []),
                               ("qvel", nv), *([("momentum", 6)] if names.momentum else []),
                               *[(name, 1) for name in names.scalars]]
        self.states = 2 + len(acts)

    @staticmethod
    def _unzip(fmu, directory):
        return FmuPackage.unzip(fmu, directory).directory

    def set(self, point):
        nx = sum(n for _, n in self.known_arrays[:self.states])
        if self.interface == "ME":
            self.fmu.setContinuousStates((c_double * nx)(*point[:nx]), nx)
            self.fmu.setFloat64([self.vr[a] for a, _ in self.known_arrays[self.states:]], list(point[nx:]))
        else:
            self.fmu.setFloat64([self.vr[a] for a, _ in self.known_arrays], list(point))

    def values(self):
        arrays = [a for a, _ in self.unknown_arrays]
        return np.array(self.fmu.getFloat64([self.vr[a] for a in arrays], nValues=len(self.names.unknowns)))

    def directional(self, seed):
        unknowns = [self.vr[a] for a, _ in self.unknown_arrays]
        knowns = [self.vr[a] for a, _ in self.known_arrays]
        return np.array(self.fmu.getDirectionalDerivative(unknowns, knowns, list(seed),
                                                          nSensitivity=len(self.names.unknowns)))

    def adjoint(self, seed):
        unknowns = [self.vr[a] for a, _ in self.unknown_arrays]
        knowns = [self.vr[a] for a, _ in self.known_arrays]
        return np.array(self.fmu.getAdjointDerivative(unknowns, knowns, list(seed),
                                                      nSensitivity=len(self.names.knowns)))


def instance(fmus, name, version, interface, tmp_path):
    names = Names(fmus[(name, 2)], MODELS[name])
    kind = Fmi2 if version == 2 else Fmi3
    return kind(fmus[(name, version)], names, interface, tmp_path / "unzipped"), names


def jacobian(host, n):
    return np.column_stack([host.directional(np.eye(n)[j]) for j in range(n)])


def central_differences(host, point):
    columns = []
    for j in range(len(point)):
        moved = np.eye(len(point))[j] * STEP
        host.set(point + moved)
        ahead = host.values()
        host.set(point - moved)
        behind = host.values()
        columns.append((ahead - behind) / (2 * STEP))
    host.set(point)
    return np.column_stack(columns)


CASES = [(name, version, interface) for name in MODELS for version in (2, 3) for interface in ("ME", "CS")]


@pytest.mark.parametrize("name,version,interface", CASES, ids=[f"{n}-fmi{v}-{i}" for n, v, i in CASES])
def test_directional_derivatives_are_central_differences_of_the_fmu(fmus, tmp_path, name, version, interface):
    host, names = instance(fmus, name, version, interface, tmp_path)
    point = random_point(names, seed=version * 10 + len(interface))
    host.set(point)
    exact = jacobian(host, len(point))
    differences = central_differences(host, point)
    scale = np.maximum(1.0, np.abs(differences))
    if name in CONSTRAINED:
        scale = np.maximum(scale, np.abs(differences).max(axis=1, keepdims=True))
    error = np.max(np.abs(exact - differences) / scale)
    assert error <= 1e-6, (error, np.unravel_index(np.argmax(np.abs(exact - differences) / scale), exact.shape))
    # ∂ν̇/∂ε = I exactly (without constraint forces), and θ, ν and act pass their seeds through.
    nq, nv, nx = len(names.theta), len(names.nu), len(names.states)
    if name not in CONSTRAINED:
        assert np.array_equal(exact[nq:nq + nv, nx:nx + nv], np.eye(nv))
    assert np.array_equal(exact[nx:2 * nx, :nx], np.eye(nx))
    host.fmu.freeInstance()


@pytest.mark.parametrize("name", MODELS)
@pytest.mark.parametrize("interface", ["ME", "CS"])
def test_the_adjoint_is_the_transpose(fmus, tmp_path, name, interface):
    """vᵀ(Ju) = (Jᵀv)ᵀu, here after a step in co-simulation. To 1e-12 of
    |vᵀ(Ju)|, but 1e-9 with the no-slip pass in model exchange: the mode
    held there is the start's (set when initialization ended), and this
    point, set without an event, lies far from it; the pass's sweeps held
    at decisions so far from their own amplify round-off, and a derivative
    along u differs from the sum of its halves' by up to 1.3e-10 of the
    largest entry, vᵀ(Ju) from (Jᵀv)ᵀu by 4.0e-10 of itself. After an
    event at the point, 1.7e-16 (measured)."""
    host, names = instance(fmus, name, 3, interface, tmp_path)
    point = random_point(names, seed=7)
    host.set(point)
    if interface == "CS":
        host.fmu.exitInitializationMode()
        host.fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.01)
    rng = np.random.default_rng(3)
    for _ in range(3):
        u, v = rng.normal(size=len(names.knowns)), rng.normal(size=len(names.unknowns))
        forward, backward = v @ host.directional(u), host.adjoint(v) @ u
        tolerance = 1e-9 if name == "noslip_trees" else 1e-12
        assert abs(forward - backward) <= tolerance * max(1.0, abs(forward)), (forward, backward)
    host.fmu.terminate()
    host.fmu.freeInstance()


def test_an_fmu_beyond_the_derivatives_declares_none_and_says_why(cli, tmp_path):
    """The energy residual, a record of the FMU's own integration, has no
    derivative: an FMU with it (here of a vehicle with sensors, which have
    derivatives; co-simulation only) declares none."""
    servicer = EXAMPLES_DIR / "servicer.xml"
    fmu2 = cli.export(servicer, tmp_path / "servicer2.fmu", fmi_version=2, outputs=("energy_residual",))
    fmu3 = cli.export(servicer, tmp_path / "servicer3.fmu", fmi_version=3, outputs=("energy_residual",))
    for fmu, flags in ((fmu2, ["providesDirectionalDerivative"]),
                       (fmu3, ["providesDirectionalDerivatives", "providesAdjointDerivatives"])):
        root = ET.fromstring(zipfile.ZipFile(fmu).read("modelDescription.xml"))
        assert root.find("ModelExchange") is None, fmu
        assert [root.find("CoSimulation").get(flag) for flag in flags] == ["false"] * len(flags), fmu
    names = Names(fmu2, servicer)
    for version, fmu in ((2, fmu2), (3, fmu3)):
        host = (Fmi2 if version == 2 else Fmi3)(fmu, names, "CS", tmp_path / f"unzipped{version}")
        with pytest.raises(Exception):
            if version == 2:
                host.directional([1.0], unknowns=[names.nu[0]], knowns=[names.eps[0]])
            else:
                host.fmu.getDirectionalDerivative([host.vr["nu"]], [host.vr["eps"]], [1.0] * len(names.eps),
                                                  nSensitivity=len(names.nu))
        assert any("providesDirectionalDerivative" in m and "energy_residual" in m for m in host.messages), \
            host.messages
        host.fmu.freeInstance()


def test_misuse_is_an_error_with_a_message(fmus, tmp_path):
    """A NaN seed, an unknown value reference, a parameter as a known, an
    input as an unknown: each an error, logged."""
    host, names = instance(fmus, "springdamper", 2, "ME", tmp_path)
    cases = [
        (dict(seed=[float("nan")], unknowns=[names.nu[0]], knowns=[names.eps[0]]), "dvKnown[0] = NaN"),
        (dict(seed=[1.0], unknowns=[names.nu[0]], knowns=["tolerance"]), "is not a known"),
        (dict(seed=[1.0], unknowns=[names.eps[0]], knowns=[names.nu[0]]), "is not an unknown"),
    ]
    for arguments, says in cases:
        with pytest.raises(Exception):
            host.directional(**arguments)
        assert any(says in m for m in host.messages), (says, host.messages)
        host.messages.clear()
        host.fmu.reset()
        host.fmu.setupExperiment(startTime=0.0)
        host.fmu.enterInitializationMode()
        host.fmu.exitInitializationMode()
    with pytest.raises(Exception):
        host.fmu.getDirectionalDerivative([10_000], [host.vr[names.eps[0]]], [1.0])
    assert any("unknown value reference 10000" in m for m in host.messages), host.messages
    host.messages.clear()
    host.fmu.reset()
    # Before initialization mode the state machine refuses the call.
    with pytest.raises(Exception):
        host.directional([1.0], unknowns=[names.nu[0]], knowns=[names.eps[0]])
    assert any("may not be called in state instantiated" in m for m in host.messages), host.messages
    host.messages.clear()
    host.fmu.reset()
    host.fmu.setupExperiment(startTime=0.0)
    host.fmu.enterInitializationMode()
    out, refs = (c_double * 1)(), (c_uint * 1)(host.vr[names.nu[0]])
    with pytest.raises(Exception):
        host.fmu.fmi2GetDirectionalDerivative(host.fmu.component, refs, 1, refs, 1, None, out)
    assert any("dvKnown is NULL" in m for m in host.messages), host.messages
    host.fmu.freeInstance()


def test_the_quaternion_rate_is_half_q_times_omega(fmus, tmp_path):
    """der(theta) of the ball joint and the free base: ½ q ⊗ (0, ω) with
    the FMU's θ̇ (qvel), to the last bit (the same operations in the same
    order as the formula's), at quaternions of exactly unit length (which
    the FMU's normalization leaves as they are)."""
    host, names = instance(fmus, "springdamper", 2, "ME", tmp_path)
    point = random_point(names, seed=5)
    quaternions = {3: 3, 8: 7}  # the free base's and the ball's (w, x, y, z) at θ, and their ω at θ̇
    for q in quaternions:
        point[q:q + 4] = [0.5, -0.5, 0.5, 0.5]
    host.set(point)
    rates = np.array(host.fmu.getReal(host.refs([f"der({n})" for n in names.theta])))
    qvel = np.array(host.fmu.getReal(host.refs(names.package.names("qvel"))))
    for q, dof in quaternions.items():
        (w, x, y, z), (a, b, c) = point[q:q + 4], qvel[dof:dof + 3]
        expected = [-0.5 * (x * a + y * b + z * c), 0.5 * (w * a + y * c - z * b),
                    0.5 * (w * b + z * a - x * c), 0.5 * (w * c + x * b - y * a)]
        assert list(rates[q:q + 4]) == expected
    host.fmu.freeInstance()


COVERED = ["bus_arm7", "chain60", "fixed_rig", "flexible_boom"]


@pytest.mark.parametrize("name", COVERED + ["springdamper", "bench_vehicle", "slider_hand", "refsafe_off", "kinds",
                                  "every_sensor", "docked_servicer", "servicer", "shortcut_servos"])
def test_the_model_structure_lists_every_dependence_the_derivatives_have(cli, tmp_path, name):
    """ModelStructure's dependencies (FMI 2.0) against the exact Jacobian at
    a random state: every non-zero entry is listed (a host may take an
    unlisted one to be 0), and a ν̇ lists exactly the ν it depends on (its
    tree's branch: the dofs from the root to its joint and below it). The
    other lists are exact to the joint: a multi-dof joint's block is listed
    whole, where θ̇ = ℓ*ν may leave an entry of it 0. A constrained vehicle
    lists every state and input (complete, not exact)."""
    model = DOCKED if name == "docked_servicer" else MODELS.get(name, EXAMPLES_DIR / f"{name}.xml")
    fmu = cli.export(model, tmp_path / f"{name}.fmu", outputs=OUTPUTS)
    root = ET.fromstring(zipfile.ZipFile(fmu).read("modelDescription.xml"))
    assert root.find("ModelExchange").get("providesDirectionalDerivative") == "true"
    index = {v.get("name"): i for i, v in enumerate(root.iterfind("ModelVariables/ScalarVariable"), start=1)}
    listed = {int(u.get("index")): {int(i) for i in u.get("dependencies").split()}
              for u in root.iterfind("ModelStructure/*/Unknown") if u.get("dependencies") is not None}
    names = Names(fmu, model)
    host = Fmi2(fmu, names, "ME", tmp_path / "unzipped")
    point = random_point(names, seed=11)
    host.set(point)
    exact = jacobian(host, len(point))
    # A mode's ν̇ is listed on its tree's branch like a joint's, but its
    # shape may decouple it from some of those ν at every state (the
    # bench's axis-aligned modes: torsion does not feel the turn about z):
    # for the modes only the listing's completeness is checked.
    modes = json.loads(cli.run("describe", model, "--json")).get("modes", [])
    modal_nu = {index[f"nu[{m['dof_adr'] + 1}]"] for m in modes}
    for row, unknown in enumerate(names.unknowns):
        depends = {index[known] for known, d in zip(names.knowns, exact[row]) if d != 0}
        assert depends <= listed[index[unknown]], (unknown, sorted(depends - listed[index[unknown]]))
        # With constraint forces the listing is every state (they couple
        # any dof to any other through the rows), and with actuators (they
        # reach every dof through ℓ): completeness only.
        if unknown.startswith("der(nu[") and name not in CONSTRAINED | {"every_sensor", "servicer", "docked_servicer",
                                                                       "shortcut_servos"}:
            on_nu = {index[known] for known in names.nu}
            if index[unknown[4:-1]] not in modal_nu:
                assert listed[index[unknown]] & on_nu == depends & on_nu, unknown
    host.fmu.freeInstance()


def test_fmi3_counts_and_time_are_checked(fmus, tmp_path):
    """FMI 3.0: nSeed and nSensitivity must be the elements of the arrays
    named, and time is neither a known nor an unknown; each an error, logged."""
    host, names = instance(fmus, "springdamper", 3, "ME", tmp_path)
    nv = len(names.nu)
    nu, eps = host.vr["nu"], host.vr["eps"]
    cases = [
        (lambda: host.fmu.getDirectionalDerivative([nu], [eps], [1.0] * (nv - 1), nSensitivity=nv),
         f"nSeed = {nv - 1}, but the value references of the knowns name {nv} values"),
        (lambda: host.fmu.getAdjointDerivative([nu], [eps], [1.0] * nv, nSensitivity=nv + 1),
         f"nSensitivity = {nv + 1}, but the value references of the knowns name {nv} values"),
        (lambda: host.fmu.getDirectionalDerivative([nu], [0], [1.0], nSensitivity=nv),
         "time (value reference 0) is neither a known nor an unknown"),
    ]
    for call, says in cases:
        with pytest.raises(Exception):
            call()
        assert any(says in m for m in host.messages), (says, host.messages)
        host.messages.clear()
        host.fmu.reset()
        host.fmu.enterInitializationMode(startTime=0.0)
    host.fmu.freeInstance()


def test_fmi3_initial_unknowns_depend_on_what_they_depend_on_after_initialization(cli, tmp_path):
    """In Initialization Mode the plant's knowns are the states' exact start
    values and the inputs, as after it (its parameters set how it
    integrates, not what it computes): each <InitialUnknown> lists the
    dependencies of its <Output> or <ContinuousStateDerivative>, which the
    FMI 2.0 test above holds to the exact Jacobian. The controller's gains
    are parameters, so its initial unknowns list none (all knowns)."""
    bus = EXAMPLES_DIR / "bus_arm7.xml"
    plant = cli.export(bus, tmp_path / "plant3.fmu", outputs=OUTPUTS, fmi_version=3)
    controller = cli.export(bus, tmp_path / "controller3.fmu", controller=True, fmi_version=3)
    for fmu, listed in ((plant, True), (controller, False)):
        structure = ET.fromstring(zipfile.ZipFile(fmu).read("modelDescription.xml")).find("ModelStructure")
        after = {u.get("valueReference"): u.get("dependencies") for u in structure
                 if u.tag in ("Output", "ContinuousStateDerivative")}
        initial = [u for u in structure if u.tag == "InitialUnknown"]
        assert initial
        for unknown in initial:
            expected = after[unknown.get("valueReference")] if listed else None
            assert unknown.get("dependencies") == expected, ET.tostring(unknown)
