"""The native master that times FMUs for the benchmarks
(bench/native/fmu_host.c): what it reads is what FMPy reads from the same
FMU with the same settings, to the bit, for a new method and the default
(its timings are the benchmark's business, not a test's)."""

from __future__ import annotations

import numpy as np
import pytest

from nudyn_bench import native_host
from nudyn_bench.vehicles import ROOT, prepare
from nudyn_driver.instance import Instance
from nudyn_driver.package import FmuPackage


@pytest.mark.parametrize("method", ["tsit5", "dop853"])
def test_native_host_reads_what_fmpy_reads(method, cli, tmp_path):
    model = ROOT / "examples" / "bus_arm7.xml"
    vehicle = prepare("bus_arm7", model, tmp_path)
    package = FmuPackage.unzip(cli.export(model, tmp_path / "bus_arm7.fmu"), tmp_path / "bus_arm7")
    host = native_host.build(tmp_path)
    settings = {"method": method, "tolerance": 1e-6}
    native = native_host.run(host, package, vehicle, settings, 0.1, 10, repetitions=2)
    assert len(native["seconds"]) == 2 and all(s > 0 for s in native["seconds"])
    with Instance(package, start=settings, theta=vehicle.qpos, nu=vehicle.nu) as fmu:
        theta, nu = [], []
        for n in range(10):
            fmu.step(0.1, communication_point=n * 0.1)
            theta.append(fmu.array("theta"))
            nu.append(fmu.array("nu"))
    assert np.array_equal(np.array(native["theta"]), np.array(theta))
    assert np.array_equal(np.array(native["nu"]), np.array(nu))
