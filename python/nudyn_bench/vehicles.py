"""The vehicles benchmarked and their states: the MJCF file for MuJoCo
(contacts and constraints off, as for the validation), generated chains,
and a moving start given both as MuJoCo's (qpos, qvel) and nudyn's (θ, ν)."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from nudyn_validation.mujoco_reference import MujocoFactor, load_model
from nudyn_validation.scenarios import make_scenario

ROOT = Path(__file__).resolve().parents[2]


def mujoco_library() -> Path:
    """The libmujoco.so of the installed mujoco package (the benchmark's
    Rust side loads it to call mj_forward natively)."""
    package = Path(mujoco.__file__).parent
    found = sorted(package.glob("libmujoco.so*"))
    if not found:
        raise FileNotFoundError(f"no libmujoco.so in {package}")
    return found[0]


def write_mujoco_xml(source: Path, target: Path) -> Path:
    """The same vehicle with contacts and constraints disabled in <option>,
    so that the C library, which reads only the file, runs what the Python
    side (`load_model`) runs."""
    spec = mujoco.MjSpec.from_file(str(source))
    spec.option.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT) | int(
        mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    )
    target.write_text(spec.to_xml())
    return target


def write_chain(links: int, target: Path) -> Path:
    """examples/chain60.xml's vehicle with `links` links (scripts/gen_chain.py)."""
    text = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "gen_chain.py"), str(links)],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    target.write_text(text)
    return target


@dataclass
class Vehicle:
    """One benchmarked vehicle: its files and a moving start."""

    name: str
    path: Path
    mujoco_path: Path
    state_path: Path
    qpos: np.ndarray
    qvel: np.ndarray
    nu: np.ndarray

    @property
    def model(self) -> mujoco.MjModel:
        return load_model(self.path)


def prepare(name: str, path: Path, work: Path, seed: int = 1) -> Vehicle:
    """Writes the MuJoCo file and the state (the validation's "tumble"
    start: random pose offsets and rates) under `work`."""
    model = load_model(path)
    scenario = make_scenario("tumble", model, seed)
    data = mujoco.MjData(model)
    data.qpos[:] = scenario.qpos0
    data.qvel[:] = scenario.qvel0
    mujoco.mj_forward(model, data)
    nu = MujocoFactor(model).nu(data, data.qvel)
    state_path = work / f"{name}.state.json"
    state_path.write_text(
        json.dumps({"theta": list(map(float, data.qpos)), "nu": list(map(float, nu)), "qvel": list(map(float, data.qvel))})
    )
    return Vehicle(
        name,
        path,
        write_mujoco_xml(path, work / f"{name}.mujoco.xml"),
        state_path,
        data.qpos.copy(),
        data.qvel.copy(),
        np.asarray(nu, float),
    )
