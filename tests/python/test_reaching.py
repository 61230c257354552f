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


@pytest.fixture(scope="module")
def servicer(nudyn, tmp_path_factory):
    """examples/servicer.xml's FMU, unpacked, and a start off its arm
    servos' targets (ctrl 0), as tests/all/reaching.rs starts it."""
    from nudyn_driver.cli import Nudyn
    from nudyn_driver.package import FmuPackage

    path = ROOT / "examples" / "servicer.xml"
    work = tmp_path_factory.mktemp("servicer")
    package = FmuPackage.unzip(Nudyn(nudyn).export(path, work / "servicer.fmu"), work / "servicer")
    # The free bus (7 coordinates, 6 dofs), then three wheels and four arm joints.
    qpos = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0] + [0.4 * np.sin(1.3 * k) for k in range(6, 13)])
    qvel = np.array([0.02, -0.01, 0.01, 0.05, -0.03, 0.04] + [0.2 * np.cos(0.7 * k) for k in range(6, 13)])
    nu = Nudyn(nudyn).eval(path, {"theta": list(qpos), "qvel": list(qvel)})["nu"]
    return package, qpos, nu


def test_a_state_saved_while_steps_end_at_the_points_continues_bit_for_bit(servicer):
    """The servicer's interpolants stray on its servos' fast modes: steps past
    the points are refused, and the steps then end at the points for a
    while (docs/integration.md). That pause (the refusals counted and the
    time it ends) is part of the FMU state: a state saved during it
    continues bit for bit, as the run that saved it, into a fresh instance."""
    from nudyn_driver.instance import Instance

    package, qpos, nu = servicer

    def started():
        return Instance(package, start={"method": "dop853", "tolerance": 1e-8}, theta=qpos, nu=nu, logging_on=True)

    with started() as running, started() as fresh:
        # To the doStep that refuses an interpolant (the 15th, today), so that the pause follows.
        for _ in range(40):
            held(running, 1)
            if running.log.step_statistics()[-1]["refused_interpolants"] > 0:
                break
        else:
            pytest.fail("no interpolant refused in 40 doSteps")
        assert_restores_bit_for_bit(running, fresh, held, 30)


def test_a_state_saved_past_a_constraint_switch_continues_bit_for_bit(nudyn, tmp_path):
    """A step cut to end just past a constraint switch, reaching past the
    communication point, is held like any other: the run goes on from its
    end in the mode past the switch. The solver's working set there is part
    of the FMU state (its rows' entries lengthen the blob), and a state
    saved then continues bit for bit, in the instance and in a fresh one."""
    from nudyn_driver.cli import Nudyn
    from nudyn_driver.instance import Instance
    from nudyn_driver.package import FmuPackage

    path = ROOT / "tests" / "fixtures" / "constraints" / "docked_servicer.xml"
    package = FmuPackage.unzip(Nudyn(nudyn).export(path, tmp_path / "docked.fmu"), tmp_path / "docked")
    interval = 0.05

    def started():
        instance = Instance(package, start={"method": "dop853", "tolerance": 1e-6}, logging_on=True)
        instance.set_array("eps", [0.3 * np.sin(k) for k in range(len(instance.array("nu")))])
        return instance

    def advance(instance, steps):
        start = round(instance.time / interval)
        for k in range(start, start + steps):
            instance.step(interval, k * interval)

    with started() as running, started() as fresh:
        sizes = []
        for _ in range(40):
            advance(running, 1)
            sizes.append(blob_size(running))
            # Without a step held, with one, and with one past a switch (longer by its rows).
            if len(set(sizes)) == 3 and sizes[-1] == max(sizes):
                break
        else:
            pytest.fail(f"no step held past a switch in 40 doSteps: blob sizes {sorted(set(sizes))}")
        assert_restores_bit_for_bit(running, fresh, advance, 20)
