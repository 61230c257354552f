"""A vehicle nested thousands of bodies deep: every command and the FMU's
loader handle it with a small stack (the CLI under a 1 MiB stack limit, the
FMU instantiated on a thread with a 512 KiB stack), and the FMU steps it to
the same numbers as `nudyn simulate` with the FMU's default method."""

from __future__ import annotations

import json
import resource
import subprocess
import threading
import xml.etree.ElementTree as ET
import zipfile

import numpy as np
import pytest

from nudyn_driver.instance import Instance
from nudyn_driver.package import FmuPackage

DEPTH = 4000
STACK_LIMIT = 1024 * 1024


def deep_chain() -> str:
    bodies = "".join(
        f'<body name="b{i}" pos="0 0 0.1"><joint axis="1 0 0"/><geom size="0.05"/>\n' for i in range(1, DEPTH)
    )
    return (
        '<mujoco model="deep"><worldbody><body name="b0"><freejoint/><geom size="0.1"/>\n'
        + bodies
        + "</body>" * DEPTH
        + "</worldbody></mujoco>"
    )


def small_stack():
    resource.setrlimit(resource.RLIMIT_STACK, (STACK_LIMIT, STACK_LIMIT))


def run(nudyn, fmu_library, *arguments, stdin=""):
    env = {"NUDYN_FMU_LIB": str(fmu_library), "PATH": "/usr/bin:/bin"}
    proc = subprocess.run([str(nudyn), *map(str, arguments)], input=stdin, capture_output=True, text=True,
                          preexec_fn=small_stack, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout


@pytest.fixture(scope="module")
def deep_model(tmp_path_factory):
    path = tmp_path_factory.mktemp("deep") / "deep.xml"
    path.write_text(deep_chain())
    return path


@pytest.fixture(scope="module")
def deep_fmu(nudyn, fmu_library, deep_model):
    """The deep chain exported under the small stack, once for both tests."""
    fmu = deep_model.parent / "deep.fmu"
    run(nudyn, fmu_library, "export", deep_model, "-o", fmu)
    return fmu


def test_every_command_reads_a_deep_chain_on_a_small_stack(nudyn, fmu_library, deep_model, deep_fmu):
    described = json.loads(run(nudyn, fmu_library, "describe", deep_model, "--json"))
    assert (described["nq"], described["nv"]) == (7 + DEPTH - 1, 6 + DEPTH - 1)
    state = {"theta": [0, 0, 0, 1, 0, 0, 0] + [0.0] * (DEPTH - 1), "nu": [1e-3] * (6 + DEPTH - 1)}
    evaluated = json.loads(run(nudyn, fmu_library, "eval", deep_model, stdin=json.dumps(state)))
    assert np.all(np.isfinite(evaluated["nu_dot"]))
    # Past 1000 knowns an unknown is listed as depending on all of them: the
    # exact lists of this chain took 588 MB of modelDescription.xml (6 MB now).
    description = zipfile.ZipFile(deep_fmu).read("modelDescription.xml")
    assert len(description) < 20e6, len(description)
    structure = ET.fromstring(description).find("ModelStructure")
    unknowns = list(structure.iter("Unknown"))
    assert any(u.get("dependencies") is None for u in unknowns)
    assert max(len(u.get("dependencies", "").split()) for u in unknowns) <= 1000


def test_the_fmu_loads_a_deep_chain_on_a_small_stack(nudyn, fmu_library, deep_model, deep_fmu, tmp_path):
    package = FmuPackage.unzip(deep_fmu, tmp_path / "unzipped")
    nu = [1e-3] * (6 + DEPTH - 1)
    results = {}

    def step_once():
        with Instance(package, nu=nu) as instance:
            instance.step(0.01)
            results["theta"] = instance.array("theta")
            results["nu"] = instance.array("nu")

    previous = threading.stack_size(512 * 1024)
    try:
        worker = threading.Thread(target=step_once)
        worker.start()
        worker.join()
    finally:
        threading.stack_size(previous)
    assert "nu" in results, "the FMU did not step on the small-stack thread"

    simulated = json.loads(run(nudyn, fmu_library, "simulate", deep_model, "--step", "0.01", "--stop", "0.01",
                               "--method", "dop853", "--tolerance", "1e-8", "--max-step", "0.01",
                               stdin=json.dumps({"nu": nu})))
    np.testing.assert_array_equal(results["theta"], simulated["theta"][-1])
    np.testing.assert_array_equal(results["nu"], simulated["nu"][-1])
