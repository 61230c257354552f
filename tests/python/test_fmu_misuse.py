"""The FMU never takes its host down: every misuse case of
`fmu_misuse.py` in a process of its own (a crash is a signal, a hang a
timeout), 8 instances on 8 threads bit-identical to sequential runs, and
the table of cases, statuses and crashes in docs/fmi.md ("The misuse
cases, counted") kept current."""

from __future__ import annotations

import ctypes as C
import json
import os
import subprocess
import sys
import threading
import zipfile

import pytest

import fmi3_misuse
import fmu_misuse
from conftest import ROOT
from nudyn_driver.package import FmuPackage

CASE_TIMEOUT = 120
RESULTS: dict[str, dict] = {}


@pytest.fixture(scope="session")
def unzipped(exported_fmu, tmp_path_factory):
    """servicer (bus_arm7's sizes, with actuators) with every optional output, and fixed_rig
    (the "other" FMU), unzipped."""
    directory = tmp_path_factory.mktemp("misuse")
    bus = exported_fmu(ROOT / "examples/servicer.xml", outputs=("qvel", "kinetic_energy", "power", "momentum"))
    rig = exported_fmu(ROOT / "examples/fixed_rig.xml")
    return FmuPackage.unzip(bus, directory / "bus"), FmuPackage.unzip(rig, directory / "rig")


@pytest.fixture(scope="session")
def unzipped_fmi3(exported_fmu, tmp_path_factory):
    """servicer's FMI 3.0 plant (with the momentum output) and controller,
    unzipped. The plant provides partial derivatives, the controller none
    (fmi3_misuse's refusals of wrong counts, and before any argument)."""
    directory = tmp_path_factory.mktemp("misuse3")
    made = []
    for name, controller in (("plant", False), ("controller", True)):
        options = dict(controller=True) if controller else dict(outputs=("momentum",))
        fmu = exported_fmu(ROOT / "examples/servicer.xml", fmi_version=3, **options)
        with zipfile.ZipFile(fmu) as archive:
            archive.extractall(directory / name)
        made.append(directory / name)
    return made


def run_case(name: str, cmd: list[str], env: dict) -> None:
    """One case in a process of its own: no signal, no hang, exit 0, and
    nothing on stderr (a panic's message goes to the logger, never to the host's stderr)."""
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=CASE_TIMEOUT, env=env)
    except subprocess.TimeoutExpired:
        pytest.fail(f"{name} hung (no answer in {CASE_TIMEOUT} s)")
    assert proc.returncode >= 0, f"{name} crashed with signal {-proc.returncode}:\n{proc.stderr[-4000:]}"
    assert proc.returncode == 0, f"{name} failed:\n{proc.stderr[-4000:]}"
    assert proc.stderr == "", f"{name} wrote to stderr:\n{proc.stderr[-4000:]}"
    RESULTS[name] = json.loads(proc.stdout)


@pytest.mark.parametrize("name", list(fmu_misuse.CASES))
def test_misuse_case(name, unzipped, tmp_path):
    bus, rig = unzipped
    cmd = [sys.executable, fmu_misuse.__file__, "run", name, str(bus.directory), str(rig.directory)]
    run_case(name, cmd, {**os.environ, "MISUSE_SCRATCH": str(tmp_path)})


@pytest.mark.parametrize("name", list(fmi3_misuse.CASES))
def test_fmi3_misuse_case(name, unzipped_fmi3):
    plant, controller = unzipped_fmi3
    run_case(name, [sys.executable, fmi3_misuse.__file__, "run", name, str(plant), str(controller)], dict(os.environ))


def test_misuse_table_in_docs_is_current():
    """docs/fmi.md's misuse table. Runs after the cases (file order);
    skipped when only some ran."""
    cases = [*fmu_misuse.CASES, *fmi3_misuse.CASES]
    if set(RESULTS) != set(cases):
        pytest.skip("not every misuse case ran in this session")
    table = fmu_misuse.table([RESULTS[name] for name in cases])
    doc = (ROOT / "docs" / "fmi.md").read_text()
    assert table in doc, f"docs/fmi.md's misuse table is out of date; it should read:\n\n{table}\n"


def run_instance(fmu: FmuPackage, lib: C.CDLL, seed: int, steps: int) -> bytes:
    """One instance from a start that depends on `seed`: the bytes of every
    Real value after every step."""
    callbacks = fmu_misuse.Callbacks(fmu_misuse.LOGGER(), fmu_misuse.ALLOCATE(), fmu_misuse.FREE(),
                                     fmu_misuse.STEP_FINISHED(), None)
    c = lib.fmi2Instantiate(f"thread{seed}".encode(), 1, fmu.guid.encode(), fmu_misuse.resource_uri(fmu).encode(),
                            C.pointer(callbacks), 0, 0)
    assert c
    assert lib.fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) == 0
    assert lib.fmi2EnterInitializationMode(c) == 0
    start = {"nu[4]": 0.1 * seed, "nu[8]": -0.05 * seed, "eps[9]": 0.2, "eps[13]": 0.01 * seed}
    vrs = (C.c_uint * len(start))(*[fmu.vr[n] for n in start])
    assert lib.fmi2SetReal(c, vrs, len(start), (C.c_double * len(start))(*start.values())) == 0
    assert lib.fmi2ExitInitializationMode(c) == 0
    all_vrs = (C.c_uint * len(fmu.reals))(*[fmu.vr[n] for n in fmu.reals])
    values = (C.c_double * len(fmu.reals))()
    trajectory = bytearray()
    for k in range(steps):
        assert lib.fmi2DoStep(c, k * fmu_misuse.STEP, fmu_misuse.STEP, 1) == 0
        assert lib.fmi2GetReal(c, all_vrs, len(fmu.reals), values) == 0
        trajectory += bytes(values)
    lib.fmi2FreeInstance(c)
    return bytes(trajectory)


def test_eight_threads_match_sequential_runs_bit_for_bit(unzipped):
    """ctypes releases the GIL during each call, so the 8 instances really
    step at the same time."""
    fmu = unzipped[0]
    lib = fmu_misuse.Harness(fmu).lib
    steps = 100
    sequential = [run_instance(fmu, lib, seed, steps) for seed in range(8)]
    assert len(set(sequential)) == 8, "the seeds give different runs"
    concurrent: list[bytes | None] = [None] * 8
    errors: list[BaseException] = []

    def worker(seed):
        try:
            concurrent[seed] = run_instance(fmu, lib, seed, steps)
        except BaseException as error:  # reported below, in the main thread
            errors.append(error)

    threads = [threading.Thread(target=worker, args=(seed,)) for seed in range(8)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert not errors, errors
    for seed in range(8):
        assert concurrent[seed] == sequential[seed], f"thread {seed} differs from its sequential run"
