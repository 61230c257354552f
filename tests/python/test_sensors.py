"""Sensors in `nudyn eval` against MuJoCo 4.0.

The fixtures in tests/fixtures/sensors/ and the examples with sensors cover
every sensor type nudyn computes (jointpos, jointvel, ballquat, ballangvel,
framepos, framequat, framexaxis/yaxis/zaxis, framelinvel, frameangvel,
framelinacc, frameangacc, subtreecom, subtreelinvel, subtreeangmom, gyro,
velocimeter, accelerometer, force, torque, magnetometer, actuatorfrc, jointactuatorfrc,
actuatorpos, actuatorvel, clock) on every kind of frame (objtype body, xbody and site;
moving, welded and world bodies; with and without a reference frame), with
cutoffs, gravity on and off, actuators and applied forces. For random
states, ctrl and joint forces, nudyn's sensordata must be MuJoCo's
d.sensordata after mj_forward (same layout, same order), and its qacc
MuJoCo's d.qacc, which the acceleration sensors are built on.
"""

from __future__ import annotations

import json
import zlib

import mujoco
import numpy as np
import pytest

from conftest import EXAMPLES, ROOT, run_eval
from nudyn_validation.mujoco_reference import Reference, load_model

FIXTURES = sorted((ROOT / "tests" / "fixtures" / "sensors").glob("*.xml"))
WITH_SENSORS = FIXTURES + [p for p in EXAMPLES if "<sensor" in p.read_text()]
N_STATES = 8
TIME = 1.25


def scaled_err(a: np.ndarray, b: np.ndarray) -> float:
    """Largest difference, relative where the value exceeds 1."""
    return float(np.max(np.abs(a - b) / np.maximum(1.0, np.abs(b)), initial=0.0))


class SensedRun:
    """Random states, ctrl and joint forces for one file, MuJoCo's sensors
    there, and one `nudyn eval` call with all of them."""

    def __init__(self, path, nudyn):
        self.path = path
        self.model = load_model(path)
        reference = Reference.from_file(path)
        data = mujoco.MjData(self.model)
        rng = np.random.default_rng(zlib.crc32(path.stem.encode()))
        self.cases = []
        for _ in range(N_STATES):
            qpos, qvel, torque = reference.random_state(rng)
            ctrl = rng.normal(0.0, 5.0, self.model.nu)
            mujoco.mj_resetData(self.model, data)
            data.qpos[:], data.qvel[:], data.qfrc_applied[:], data.ctrl[:] = qpos, qvel, torque, ctrl
            data.time = TIME
            mujoco.mj_forward(self.model, data)
            self.cases.append(
                dict(qpos=qpos, qvel=qvel, torque=torque, ctrl=ctrl, sensordata=data.sensordata.copy(), qacc=data.qacc.copy())
            )
        requests = [
            {"theta": c["qpos"].tolist(), "qvel": c["qvel"].tolist(), "torque": c["torque"].tolist(), "ctrl": c["ctrl"].tolist(), "time": TIME}
            for c in self.cases
        ]
        result = run_eval(nudyn, path, json.dumps(requests))
        assert result.returncode == 0, result.stderr
        # Every numeric field; the constraint rows are records (test_constraints.py checks them).
        self.outputs = [{k: np.asarray(v, float) for k, v in o.items() if k != "constraint_rows"} for o in result.json()]

    def sensor_slices(self):
        for i in range(self.model.nsensor):
            adr, dim = self.model.sensor_adr[i], self.model.sensor_dim[i]
            name = mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_SENSOR, i) or str(i)
            kind = mujoco.mjtSensor(self.model.sensor_type[i]).name.removeprefix("mjSENS_").lower()
            yield f"{kind} {name}", slice(adr, adr + dim)


@pytest.fixture(params=WITH_SENSORS, ids=[p.stem for p in WITH_SENSORS])
def run(request, nudyn, once):
    return once(SensedRun, request.param, nudyn)


def test_the_fixtures_cover_every_sensor_type_and_frame_kind():
    types, objtypes, reftypes = set(), set(), set()
    for path in FIXTURES:
        model = load_model(path)
        types |= {mujoco.mjtSensor(t).name for t in model.sensor_type}
        objtypes |= {mujoco.mjtObj(t).name for t in model.sensor_objtype}
        reftypes |= {mujoco.mjtObj(t).name for t in model.sensor_reftype}
    expected = {
        "JOINTPOS", "JOINTVEL", "BALLQUAT", "BALLANGVEL", "FRAMEPOS", "FRAMEQUAT", "FRAMEXAXIS", "FRAMEYAXIS",
        "FRAMEZAXIS", "FRAMELINVEL", "FRAMEANGVEL", "FRAMELINACC", "FRAMEANGACC", "SUBTREECOM", "SUBTREELINVEL",
        "SUBTREEANGMOM", "GYRO", "VELOCIMETER", "ACCELEROMETER", "FORCE", "TORQUE", "MAGNETOMETER", "ACTUATORFRC", "JOINTACTFRC", "ACTUATORPOS",
        "ACTUATORVEL", "CLOCK",
    }
    assert {f"mjSENS_{t}" for t in expected} <= types
    assert {"mjOBJ_BODY", "mjOBJ_XBODY", "mjOBJ_SITE"} <= objtypes
    assert {"mjOBJ_BODY", "mjOBJ_XBODY", "mjOBJ_SITE"} <= reftypes


def test_sensordata_has_mujocos_layout(run):
    for out in run.outputs:
        assert out["sensordata"].shape == (run.model.nsensordata,)


def test_every_sensor_reads_what_mujoco_reads(run):
    for i, (case, out) in enumerate(zip(run.cases, run.outputs)):
        for label, where in run.sensor_slices():
            err = scaled_err(out["sensordata"][where], case["sensordata"][where])
            assert err <= 1e-9, (
                f"{run.path.stem} state {i}: {label} reads {out['sensordata'][where]}, MuJoCo "
                f"{case['sensordata'][where]} (off by {err:.2e})"
            )


def test_qacc_is_mujocos(run):
    for i, (case, out) in enumerate(zip(run.cases, run.outputs)):
        err = scaled_err(out["qacc"], case["qacc"])
        assert err <= 1e-8, f"{run.path.stem} state {i}: qacc off by {err:.2e}"


def test_a_cutoff_clamps(nudyn, once):
    """The fixtures' cutoffs are small enough to clamp in some state: the
    clamping is exercised, not only allowed."""
    every = ROOT / "tests" / "fixtures" / "sensors" / "every_sensor.xml"
    run = once(SensedRun, every, nudyn)
    clamped = 0
    for i in range(run.model.nsensor):
        cutoff = run.model.sensor_cutoff[i]
        if cutoff > 0:
            adr, dim = run.model.sensor_adr[i], run.model.sensor_dim[i]
            clamped += sum(np.any(np.abs(c["sensordata"][adr : adr + dim]) == cutoff) for c in run.cases)
    assert clamped > 0
