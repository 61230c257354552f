"""scripts/thruster-demo.sh's flight (python/nudyn_servicer/demo.py),
shortened to 6 s: the servicer's FMU driven through ctrl in FMPy does what
each phase of the manoeuvre should, read from its own sensordata, and agrees
with MuJoCo's d.sensordata entry by entry."""

from __future__ import annotations

import json

import numpy as np
import pytest

from nudyn_servicer import demo


@pytest.fixture(scope="module")
def flown(nudyn, tmp_path_factory):
    out = tmp_path_factory.mktemp("thruster-demo")
    flight, result = demo.run(nudyn, out, duration=6.0)
    return flight, result, out


def sample(flight, name, time):
    return flight.sensor(name)[int(round(time / demo.COMMUNICATION_STEP))]


def test_the_demo_writes_its_plot_and_numbers(flown):
    _, result, out = flown
    assert (out / "servicer.png").stat().st_size > 20_000
    assert json.loads((out / "results.json").read_text()) == result


def test_the_fmu_agrees_with_mujoco(flown):
    flight, result, _ = flown
    assert flight.fmu.shape == flight.mujoco.shape == (601, 30)
    assert result["max_sensordata_disagreement_with_mujoco"] <= demo.AGREEMENT


def test_the_aft_burn_pushes_the_bus_forward(flown):
    flight, _, _ = flown
    start, after = sample(flight, "bus_position", 0.0), sample(flight, "bus_position", 2.0)
    # 88 N on about 640 kg for 2 s: about 0.27 m along x, hardly sideways.
    assert 0.2 < after[0] - start[0] < 0.35
    assert np.all(np.abs(after[1:] - start[1:]) < 0.02)
    # The accelerometer felt the thrust along the bus x axis (the IMU is turned 0.1 rad about z).
    assert sample(flight, "specific_force", 1.0)[0] > 0.1


def test_the_yaw_couple_spins_the_bus_and_the_wheel_takes_it_back(flown):
    flight, _, _ = flown
    yaw = lambda t: sample(flight, "body_rates", t)[2]  # noqa: E731
    assert yaw(3.5) - yaw(2.9) > 0.03
    # The wheel, driven from 4 s, spins up about +z; the bus's yaw rate falls.
    assert sample(flight, "wheel_z_speed", 6.0)[0] > 5.0
    assert yaw(6.0) < yaw(4.0) - 1e-3


def test_the_arm_reaches_its_servo_pose(flown):
    flight, _, _ = flown
    for name, angle in demo.ARM_POSE.items():
        assert sample(flight, f"{name}_angle", 6.0)[0] == pytest.approx(angle, abs=0.05), name
