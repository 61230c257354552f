"""Steps past the communication point, through the FMU (docs/integration.md,
"Steps past the communication point"): with the inputs held, a slow
vehicle takes fewer internal steps than doSteps, and an FMU state saved
while the last step reaches past the communication point (its
interpolant and its end are in the state) continues bit for bit, into
the instance that ran on and, serialized, into a fresh one, whether the
inputs then stay or change."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import ROOT, assert_restores_bit_for_bit

FIXTURE = ROOT / "tests" / "fixtures" / "slow_station.xml"
STEP = 0.1


@pytest.fixture(scope="module")
def station(nudyn, tmp_path_factory):
    """The slow station's FMU, unpacked, and a slow start: the base turning
    at about 0.01 rad/s, the arm joints at up to 0.05 rad/s (as
    tests/all/reaching.rs starts it)."""
    from nudyn_driver.cli import Nudyn
    from nudyn_driver.package import FmuPackage

    work = tmp_path_factory.mktemp("station")
    package = FmuPackage.unzip(Nudyn(nudyn).export(FIXTURE, work / "station.fmu"), work / "station")
    qpos = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0] + [0.3 * np.sin(k) for k in range(6, 20)])
    qvel = np.array([0.01, -0.004, 0.006, 0.006, -0.004, 0.008] + [0.05 * np.cos(1.7 * k) for k in range(6, 20)])
    nu = Nudyn(nudyn).eval(FIXTURE, {"theta": list(qpos), "qvel": list(qvel)})["nu"]
    return package, qpos, nu


def blob_size(instance) -> int:
    state = instance.fmu.getFMUstate()
    size = len(instance.fmu.serializeFMUstate(state))
    instance.fmu.freeFMUstate(state)
    return size


def held(instance, steps):
    start = round(instance.time / STEP)
    for k in range(start, start + steps):
        instance.step(STEP, k * STEP)


def pushed(instance, steps):
    """Like `held`, with ε changed after the first of the steps."""
    held(instance, 1)
    instance.set_array("eps", [0.05] * 20)
    held(instance, steps - 1)


@pytest.mark.parametrize("method", ["dop853", "dopri5", "tsit5", "bs3"])
@pytest.mark.parametrize("advance", [held, pushed])
def test_a_state_saved_inside_a_step_continues_bit_for_bit(method, advance, station):
    from nudyn_driver.instance import Instance

    package, qpos, nu = station

    def started():
        return Instance(package, start={"method": method, "tolerance": 1e-4}, theta=qpos, nu=nu, logging_on=True)

    with started() as running, started() as fresh:
        held(running, 30)
        taken, _ = running.log.internal_steps()
        assert taken < 30, f"{taken} internal steps for 30 doSteps"
        # The state holds the step reaching past t = 3 s: its blob is longer than a fresh one's.
        assert blob_size(running) > blob_size(fresh)
        assert_restores_bit_for_bit(running, fresh, advance, 30)
