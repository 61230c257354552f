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

from nudyn_driver.cli import Nudyn
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


def chain_model(links: int) -> mujoco.MjModel:
    """The vehicle of `write_chain(links)` built for MuJoCo with its model
    editor: MuJoCo's XML reader refuses bodies nested more than about 500
    deep, nudyn's does not. Same numbers as scripts/gen_chain.py
    (`test_bench.py` checks that both give the same model)."""
    spec = mujoco.MjSpec()
    spec.modelname = f"chain{links}"
    spec.option.gravity = [0.0, 0.0, 0.0]
    base = spec.worldbody.add_body(name="base")
    base.add_freejoint()
    base.explicitinertial = True
    base.mass = 200.0
    base.ipos = [0.02, 0.0, 0.01]
    base.fullinertia = [30.0, 35.0, 28.0, 0.5, -0.8, 0.3]
    base.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.5, 0.5, 0.5])
    axes = [[0, 1, 0], [0, 0, 1], [0, 0.6, 0.8]]
    length = 0.25
    # zaxis="1 0 0": the capsule's axis along x, a quarter turn about y.
    along_x = [np.sqrt(0.5), 0.0, np.sqrt(0.5), 0.0]
    parent = base
    for k in range(links):
        mass = 6.0 - 4.5 * k / (links - 1)
        radius = round(0.04 - 0.015 * k / (links - 1), 4)
        body = parent.add_body(name=f"link{k + 1}", pos=[length if k else 0.55, 0.0, 0.0])
        joint = body.add_joint(name=f"j{k + 1}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=axes[k % 3])
        if k % 3 == 0:
            joint.armature = 0.02
            joint.damping = [0.05, 0.0, 0.0]  # MuJoCo 4: damping and its polynomial terms
        body.add_geom(
            type=mujoco.mjtGeom.mjGEOM_CAPSULE,
            size=[radius, round(length / 2 - radius, 4), 0.0],
            pos=[length / 2, 0.01 if k % 4 == 1 else 0.0, 0.0],
            quat=along_x,
            mass=round(mass, 4),
        )
        parent = body
    model = spec.compile()
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT) | int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    return model


@dataclass
class Vehicle:
    """One benchmarked vehicle: nudyn's MJCF file, MuJoCo's model of it
    (contacts and constraints off, as for the validation; also saved as a
    binary model for the Rust side) unless MuJoCo cannot have it, and a
    moving start."""

    name: str
    path: Path
    model: mujoco.MjModel | None
    mujoco_path: Path | None
    state_path: Path
    qpos: np.ndarray
    qvel: np.ndarray
    nu: np.ndarray


def prepare(
    name: str, path: Path, work: Path, model: mujoco.MjModel | None = None, seed: int = 1, rate_scale: float = 1.0
) -> Vehicle:
    """Writes MuJoCo's binary model and the state (the validation's
    "tumble" start: random pose offsets and rates, the rates times
    `rate_scale`) under `work`; `model` defaults to MuJoCo's reading of `path`."""
    model = load_model(path) if model is None else model
    scenario = make_scenario("tumble", model, seed)
    data = mujoco.MjData(model)
    data.qpos[:] = scenario.qpos0
    data.qvel[:] = rate_scale * scenario.qvel0
    mujoco.mj_forward(model, data)
    nu = MujocoFactor(model).nu(data, data.qvel)
    state_path = work / f"{name}.state.json"
    state_path.write_text(
        json.dumps({"theta": list(map(float, data.qpos)), "nu": list(map(float, nu)), "qvel": list(map(float, data.qvel))})
    )
    mujoco_path = work / f"{name}.mjb"
    mujoco.mj_saveModel(model, str(mujoco_path), None)
    return Vehicle(name, path, model, mujoco_path, state_path, data.qpos.copy(), data.qvel.copy(), np.asarray(nu, float))


def prepare_chain_without_mujoco(links: int, path: Path, nudyn: Path, work: Path, seed: int = 1) -> Vehicle:
    """A chain MuJoCo 4.0 cannot compile (its body tree is limited to about
    1000 levels): the same kind of start, with ν from `nudyn eval` of the
    rates, and no MuJoCo model."""
    rng = np.random.default_rng(seed)
    quat = rng.normal(size=4)
    qpos = np.concatenate([rng.uniform(-0.5, 0.5, 3), quat / np.linalg.norm(quat), rng.uniform(-0.5, 0.5, links)])
    qvel = rng.normal(0.0, np.concatenate([[0.05] * 3, [0.1] * 3, [0.2] * links]))
    nu = np.array(Nudyn(nudyn).eval(path, {"theta": list(qpos), "qvel": list(qvel)})["nu"])
    state_path = work / f"chain{links}.state.json"
    state_path.write_text(json.dumps({"theta": list(qpos), "nu": list(nu), "qvel": list(qvel)}))
    return Vehicle(f"chain{links}", path, None, None, state_path, qpos, qvel, nu)
