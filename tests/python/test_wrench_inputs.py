"""`nudyn export --wrench-inputs BODY[,BODY...]`: inputs xfrc_applied[1..6n],
a world-frame force and torque at each named body's centre of mass, checked
against MuJoCo's d.xfrc_applied (the validation's 'wrenched' scenario: a
fresh random wrench held over each communication step, 2 s, θ, ν and every
sensordata entry within the issue's 1e-6), through FMI 2 and 3,
co-simulation and model exchange; the ports' descriptions and dependencies;
and the refusals.
"""

from __future__ import annotations

import json
import subprocess
import xml.etree.ElementTree as ET
import zipfile

import numpy as np
import pytest
from fmpy import read_model_description

from fmpy.fmi1 import FMICallException

from conftest import ROOT
from nudyn_driver.instance import Instance
from nudyn_driver.package import FmuPackage
from nudyn_validation.compare import Settings, validate_model
from nudyn_validation.scenarios import FORCED_TOLERANCE

SERVICER = ROOT / "examples" / "servicer.xml"
EVERY_SENSOR = ROOT / "tests" / "fixtures" / "sensors" / "every_sensor.xml"


def check_wrenched(model_path, bodies, fmu_path, nudyn, **settings):
    # No MuJoCo twin: only the FMU's errors against MuJoCo are asserted
    # here; the twins feed the verdict, which test_corpus.py tests.
    settings = Settings(wrench_bodies=tuple(bodies), twins=0, **settings)
    result = validate_model(model_path, fmu_path, nudyn, ["wrenched"], settings).results[0]
    x = result.summary()
    report = json.dumps(x, indent=1)
    assert x["max_theta_error"] <= FORCED_TOLERANCE and x["max_nu_error"] <= FORCED_TOLERANCE, report
    assert x["max_sensordata_error"] <= FORCED_TOLERANCE, report
    return result


@pytest.mark.parametrize(
    "model_path, bodies",
    [(SERVICER, ["bus", "hand"]), (EVERY_SENSOR, ["tool", "boom", "bus"])],
    ids=["servicer", "every_sensor"],
)
def test_wrenches_move_the_vehicle_as_mujocos_xfrc_applied(model_path, bodies, nudyn, tmp_path):
    wrenched = check_wrenched(model_path, bodies, tmp_path / "w.fmu", nudyn)
    # The same start without wrenches ends elsewhere: the wrenches shape the motion compared.
    free = validate_model(model_path, tmp_path / "f.fmu", nudyn, ["tumble"], Settings(twins=0)).results[0]
    assert np.max(np.abs(wrenched.fmu.nu[-1] - free.fmu.nu[-1])) > 1e-2


@pytest.mark.parametrize("fmi_version, interface", [(3, "cs"), (2, "me")])
def test_wrenches_through_the_other_interfaces(fmi_version, interface, nudyn, tmp_path):
    check_wrenched(EVERY_SENSOR, ["tool", "bus"], tmp_path / "w.fmu", nudyn, fmi_version=fmi_version,
                   interface=interface)


def test_wrench_ports_are_described_and_feed_nu_dot(cli, tmp_path):
    fmu = cli.export(SERVICER, tmp_path / "w.fmu", wrench_inputs=["hand", "bus"])
    description = read_model_description(str(fmu))
    variables = description.modelVariables
    by_name = {v.name: v for v in variables}
    wrenches = [v for v in variables if v.name.startswith("xfrc_applied[")]
    assert [v.name for v in wrenches] == [f"xfrc_applied[{k}]" for k in range(1, 13)]
    for k, variable in enumerate(wrenches):
        assert (variable.causality, variable.variability, float(variable.start)) == ("input", "continuous", 0.0)
        body = ["hand", "bus"][k // 6]
        component = ["force x (N)", "force y (N)", "force z (N)", "torque x (N*m)", "torque y (N*m)", "torque z (N*m)"][k % 6]
        assert f"body '{body}'" in variable.description and variable.description.endswith(component), variable.description
    # They follow ctrl, and theta follows them.
    assert by_name["xfrc_applied[1]"].valueReference == by_name["ctrl[15]"].valueReference + 1
    assert by_name["theta[1]"].valueReference == by_name["xfrc_applied[12]"].valueReference + 1
    names = [v.name for v in variables]
    wrench_indices = {names.index(v.name) + 1 for v in wrenches}
    with zipfile.ZipFile(fmu) as archive:
        structure = ET.fromstring(archive.read("modelDescription.xml")).find("ModelStructure")
    for unknown in [*structure.find("Derivatives"), *structure.find("Outputs")]:
        variable = variables[int(unknown.get("index")) - 1]
        dependencies = set(map(int, (unknown.get("dependencies") or "").split()))
        if variable.name.startswith("der(nu[") or "'specific_force'" in (variable.description or ""):
            assert wrench_indices <= dependencies, variable.name
        else:
            assert not wrench_indices & dependencies, variable.name


def test_without_the_option_there_are_no_wrench_inputs(cli, tmp_path):
    fmu = cli.export(SERVICER, tmp_path / "plain.fmu")
    assert not [v for v in read_model_description(str(fmu)).modelVariables if v.name.startswith("xfrc_applied")]


@pytest.mark.parametrize(
    "arguments, expected",
    [
        (["--wrench-inputs", "nope"], "no body 'nope' in the vehicle (its bodies: bus, wheel_x"),
        (["--wrench-inputs", "bus,nope"], "no body 'nope'"),
        # Two wrenches on one body used to be two sets of inputs, added.
        (["--wrench-inputs", "bus,wheel_x,bus"], "--wrench-inputs: body 'bus' is named twice"),
        (["--wrench-inputs", "bus", "--wrench-inputs", "bus"], "--wrench-inputs: body 'bus' is named twice"),
        (["--wrench-inputs", "bus", "--controller"], "cannot be used with"),
    ],
)
def test_bad_wrench_bodies_are_clear_errors(nudyn, tmp_path, arguments, expected):
    proc = subprocess.run([str(nudyn), "export", str(SERVICER), "-o", str(tmp_path / "x.fmu"), *arguments],
                          capture_output=True, text=True)
    assert proc.returncode != 0 and expected in proc.stderr, proc.stderr
    assert not (tmp_path / "x.fmu").exists()


def test_a_body_fixed_to_the_world_is_refused(nudyn, tmp_path):
    proc = subprocess.run([str(nudyn), "export", str(EVERY_SENSOR), "-o", str(tmp_path / "x.fmu"),
                           "--wrench-inputs", "post"], capture_output=True, text=True)
    assert proc.returncode != 0 and "body 'post' is fixed to the world" in proc.stderr, proc.stderr


def test_a_non_finite_wrench_is_discarded_and_nothing_changes(cli, tmp_path):
    fmu = cli.export(SERVICER, tmp_path / "w.fmu", wrench_inputs=["bus"])
    package = FmuPackage.unzip(fmu, tmp_path / "unzipped")
    with Instance(package, name="nan", start={"method": "rk4", "max_step": 1e-3}) as slave:
        slave.set({"xfrc_applied[4]": 2.0})
        slave.step(0.01, communication_point=0.0)
        before = slave.all_reals()
        for value in (float("nan"), float("-inf")):
            with pytest.raises(FMICallException) as discarded:
                slave.set({"xfrc_applied[2]": value})
            assert discarded.value.status == 2 and "xfrc_applied[2] =" in slave.log.text()
            assert np.array_equal(slave.all_reals(), before)
        # The torque held about x turned the bus: its body rate about x grew.
        slave.step(0.01, communication_point=0.01)
        assert slave.array("nu")[3] > before[list(package.reals).index("nu[4]")]
