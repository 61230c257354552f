"""`nudyn system`: the plant and the controller as one SSP file
(docs/systems.md). The archive's SSD and SSV validate against the SSP 1.0
schemas FMPy ships; libcosim and FMPy run it closed loop, each against
this driver's loop over the same two FMUs stepped as that master steps
(nudyn_driver.ssp); bad --set values are refused by name, nothing written."""

import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
from lxml import etree

from conftest import EXAMPLES_DIR as EXAMPLES
from nudyn_driver import ssp
from nudyn_driver.instance import Instance

SCHEMAS = Path(__import__("fmpy").__file__).parent / "ssp" / "schema"


def write_system(nudyn, model, out, *options):
    done = subprocess.run([str(nudyn), "system", str(model), "-o", str(out), *options],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return ssp.read(out)


@pytest.fixture(scope="module")
def detumble(nudyn, fmu_library, tmp_path_factory):
    """bus_arm7 tumbling (bus rates 0.5 and -0.3 rad/s), rate feedback c1 = 2/s."""
    out = tmp_path_factory.mktemp("system") / "loop.ssp"
    return write_system(nudyn, EXAMPLES / "bus_arm7.xml", out, "--stop", "30", "--step", "0.05",
                        "--set", "plant.nu[4]=0.5", "--set", "plant.nu[5]=-0.3", "--set", "controller.c1=2")


def test_the_archive_validates_against_the_ssp_schemas(detumble):
    with zipfile.ZipFile(detumble.path) as archive:
        names = set(archive.namelist())
        assert names == {"SystemStructure.ssd", "resources/plant.fmu", "resources/controller.fmu",
                         "resources/plant.ssv", "resources/controller.ssv"}
        ssd = etree.fromstring(archive.read("SystemStructure.ssd"))
        schema = etree.XMLSchema(file=str(SCHEMAS / "SystemStructureDescription.xsd"))
        assert schema.validate(ssd), schema.error_log
        values_schema = etree.XMLSchema(file=str(SCHEMAS / "SystemStructureParameterValues.xsd"))
        for name in ("resources/plant.ssv", "resources/controller.ssv"):
            values = etree.fromstring(archive.read(name))
            assert values_schema.validate(values), values_schema.error_log
    # Every θ and ν entry to the controller and every ε entry back: nq + 2 nv = 14 + 26.
    connections = ssd.findall(".//ssd:Connection", ssp.NAMESPACES)
    assert len(connections) == 40
    assert all(c.get("startConnector") == c.get("endConnector") for c in connections)
    assert detumble.step == 0.05 and detumble.stop_time == 30.0
    assert detumble.values["plant"] == {"nu[4]": 0.5, "nu[5]": -0.3}
    assert detumble.values["controller"] == {f"c1[{k}]": 2.0 for k in range(1, 14)}


OMS = "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd"


def test_the_system_carries_omsimulators_master_annotation(detumble, nudyn, fmu_library, tmp_path):
    """OMSimulator takes a system's master from its own annotation of the
    ssd:System (OMSimulator's oms:FixedStepMaster, the element it writes in
    its own SSDs), and aborts the import without one: the step is the
    DefaultExperiment's, the tolerances the plant's (OMSimulator passes them
    to fmi2SetupExperiment, where they replace the plant's `tolerance`).
    OMSimulator matches the `oms:` prefix itself, not the namespace."""
    def master(system):
        with zipfile.ZipFile(system.path) as archive:
            text = archive.read("SystemStructure.ssd")
        assert b"<oms:Annotations " in text and b"<oms:FixedStepMaster " in text
        root = etree.fromstring(text)
        namespaces = {**ssp.NAMESPACES, "oms": OMS}
        (annotation,) = root.findall("ssd:System/ssd:Annotations/ssc:Annotation", namespaces)
        assert annotation.get("type") == "org.openmodelica"
        (fixed_step,) = annotation.findall("oms:Annotations/oms:SimulationInformation/oms:FixedStepMaster", namespaces)
        return fixed_step.attrib

    assert master(detumble) == {"description": "oms-ma", "stepSize": "0.05", "absoluteTolerance": "1e-8",
                                "relativeTolerance": "1e-8"}
    tight = write_system(nudyn, EXAMPLES / "fixed_rig.xml", tmp_path / "rig.ssp", "--step", "0.02", "--stop", "1",
                         "--set", "plant.tolerance=1e-10")
    assert master(tight) == {"description": "oms-ma", "stepSize": "0.02", "absoluteTolerance": "1e-10",
                             "relativeTolerance": "1e-10"}


def test_a_schema_violation_is_caught():
    """The schema check above can fail: an SSD with its elements out of order does."""
    broken = etree.fromstring(
        f'<ssd:SystemStructureDescription xmlns:ssd="{ssp.NAMESPACES["ssd"]}" version="1.0" name="x">'
        '<ssd:DefaultExperiment/><ssd:System name="x"/></ssd:SystemStructureDescription>')
    assert not etree.XMLSchema(file=str(SCHEMAS / "SystemStructureDescription.xsd")).validate(broken)


def test_libcosim_detumbles_as_the_driver_steps_it(detumble):
    run = ssp.run_libcosim(detumble)
    reference = ssp.run_loop(detumble, "libcosim")
    assert np.allclose(run.time, reference.time, atol=1e-12)
    assert np.abs(run.nu - reference.nu).max() < 1e-12
    assert np.abs(run.theta - reference.theta).max() < 1e-12
    speed = np.linalg.norm(run.nu, axis=1)
    assert speed[0] == pytest.approx(np.hypot(0.5, 0.3))
    assert speed[-1] < speed[0] * 1e-3
    # The driver's own master (Gauss-Seidel, no delay) flies the same file
    # to the same end, along a path that differs by libcosim's one step of delay.
    gauss_seidel = ssp.run_loop(detumble, "gauss-seidel")
    assert np.linalg.norm(gauss_seidel.nu[-1]) < speed[0] * 1e-3
    assert 1e-6 < np.abs(gauss_seidel.nu - run.nu).max() < 0.1


def test_fmpy_runs_a_fixed_base_system_as_the_driver_steps_it(nudyn, fmu_library, tmp_path):
    system = write_system(nudyn, EXAMPLES / "fixed_rig.xml", tmp_path / "rig.ssp", "--stop", "5", "--step", "0.01",
                          "--set", "plant.nu=0.5")
    run = ssp.run_fmpy(system)
    reference = ssp.run_loop(system, "fmpy")
    # FMPy's loop adds its step to the time until it reaches the stop time:
    # rounding gives it one step more than stop/step (to 5.01 s here).
    steps = len(reference.time) - 1
    assert len(run.time) - 1 in (steps, steps + 1)
    assert np.abs(run.nu[: steps + 1] - reference.nu).max() < 1e-12
    assert np.abs(run.theta[: steps + 1] - reference.theta).max() < 1e-12
    assert np.linalg.norm(run.nu[steps]) < 1e-2 * np.linalg.norm(run.nu[0])


def test_fmpy_detumbles_as_the_driver_steps_it(detumble):
    """FMPy's runner starts every connection at 0: the controller's first θ
    has a zero quaternion, read as the identity with a warning; the rest is
    FMPy's Jacobi order, which the driver's "fmpy" loop repeats."""
    run = ssp.run_fmpy(detumble)
    reference = ssp.run_loop(detumble, "fmpy")
    steps = len(reference.time) - 1
    assert len(run.time) - 1 in (steps, steps + 1)
    assert np.abs(run.nu[: steps + 1] - reference.nu).max() < 1e-12
    assert np.abs(run.theta[: steps + 1] - reference.theta).max() < 1e-12
    speed = np.linalg.norm(run.nu, axis=1)
    assert speed[steps] < speed[0] * 1e-3


def test_servicer_reaches_its_target_pose_in_libcosim_and_fmpy(nudyn, fmu_library, tmp_path):
    """Control 1(b): the hand back to its pose at qpos0 from a bent arm."""
    gains = ["--set", "controller.c2[1]=600", "--set", "controller.c2[2]=600", "--set", "controller.c2[3]=600",
             "--set", "controller.c2[4]=20", "--set", "controller.c2[5]=20", "--set", "controller.c2[6]=10"]
    system = write_system(nudyn, EXAMPLES / "servicer.xml", tmp_path / "servicer.ssp", "--end-effector", "hand",
                          "--stop", "20", "--step", "0.02", "--set", "plant.theta[12]=-0.3",
                          "--set", "plant.theta[13]=0.4", *gains)
    runs = [ssp.run_libcosim(system), ssp.run_fmpy(system)]
    steps = round(system.stop_time / system.step)
    for run in runs:
        reference = ssp.run_loop(system, run.master)
        assert np.abs(run.nu[: steps + 1] - reference.nu).max() < 1e-12, run.master
        assert np.abs(run.theta[: steps + 1] - reference.theta).max() < 1e-12, run.master

    controller = ssp.package(system, "controller", tmp_path / "check")

    def pose_error(theta, nu):
        with Instance(controller, name="check", start=system.values["controller"]) as instance:
            instance.set_array("theta", theta)
            instance.set_array("nu", nu)
            return np.linalg.norm(instance.array("target_error"))

    for run in runs:
        assert pose_error(run.theta[steps], run.nu[steps]) < 1e-2 * pose_error(run.theta[0], run.nu[0]), run.master


@pytest.mark.parametrize("value, message", [
    ("plant.omega[1]=1", "plant has no variable omega[1] with a start value (it has tolerance, max_step, eps[1..13]"),
    ("controller.c1=-2", "c1[1] = -2 is refused: it must be non-negative"),
    ("plant.tolerance=0", "tolerance = 0 is refused: it must be positive"),
    ("plant.nu[1]=fast", "'fast' is not a number"),
    ("plant.sensordata[1]=1", "sensordata[1] has no start value: it is a calculated output"),
    ("bus.nu[1]=1", "the system's components are plant and controller"),
    # A zero quaternion: no host can initialize the plant from it.
    ("plant.theta=0", "--set plant.theta=0: theta[4] to theta[7] (joint 'bus_free') would be a zero quaternion"),
])
def test_bad_values_are_refused_by_name_and_nothing_is_written(nudyn, fmu_library, tmp_path, value, message):
    out = tmp_path / "loop.ssp"
    done = subprocess.run([str(nudyn), "system", str(EXAMPLES / "servicer.xml"), "-o", str(out), "--set", value],
                          capture_output=True, text=True)
    assert done.returncode != 0
    assert message in done.stderr, done.stderr
    assert not out.exists()


def test_a_variable_set_twice_is_refused_and_nothing_is_written(nudyn, fmu_library, tmp_path):
    """The last of two values used to win silently."""
    out = tmp_path / "loop.ssp"
    for sets, message in [
        (["plant.nu[4]=0.5", "plant.nu[4]=0.7"], "--set plant.nu[4]=0.7: plant.nu[4] is already set by --set plant.nu[4]=0.5"),
        (["controller.c1=2", "controller.c1[3]=1"],
         "--set controller.c1[3]=1: controller.c1[3] is already set by --set controller.c1=2; set each variable once"),
    ]:
        options = [option for value in sets for option in ("--set", value)]
        done = subprocess.run([str(nudyn), "system", str(EXAMPLES / "bus_arm7.xml"), "-o", str(out), *options],
                              capture_output=True, text=True)
        assert done.returncode != 0 and message in done.stderr, done.stderr
        assert not out.exists()


def test_a_non_unit_quaternion_is_kept_and_the_plant_normalizes_it(nudyn, fmu_library, tmp_path):
    """As the plant FMU does with any non-unit quaternion start value (and
    MuJoCo with qpos0): (2, 0, 0, 0) starts as the identity."""
    system = write_system(nudyn, EXAMPLES / "bus_arm7.xml", tmp_path / "loop.ssp", "--stop", "0.1", "--step", "0.05",
                          "--set", "plant.theta[4]=2")
    assert system.values["plant"] == {"theta[4]": 2.0}
    run = ssp.run_loop(system, "gauss-seidel")
    assert list(run.theta[0][3:7]) == [1.0, 0.0, 0.0, 0.0]
