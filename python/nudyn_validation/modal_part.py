"""A vehicle with modal bodies against MuJoCo (docs/flexible.md; docs/validation.md,
"Vehicles with flexible bodies").

MuJoCo ignores the modal files, so its twin of such a vehicle is the rigid
vehicle. The comparison that applies is of the rigid part with the modes
frozen: a copy of the model whose modal files keep their nodes and lose
their modes, which is nudyn's rigid model exactly (docs/flexible.md). The
modal part is reported beside it: the FMU with its modes is given the same
held inputs from the same state (modes at rest), and the report lists each
mode's range, the largest strain energy, and how far the modes take the
joints' coordinates from MuJoCo's rigid run.
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from nudyn_driver.cli import Nudyn
from nudyn_driver.package import FmuPackage

MODAL_TEXT = "nudyn:modal:"
# The optional outputs of the FMU with modes.
MODAL_OUTPUTS = ("modal_strain_energy",)


class FreezeError(Exception):
    """A modal file the frozen copy cannot replace."""


def modal_files(model: mujoco.MjModel, model_path: Path) -> dict[str, Path]:
    """Each flexible body's modal file, by body name, as the MJCF's
    `<text name="nudyn:modal:BODY" data="FILE">` names it (relative to the
    MJCF's folder)."""
    files = {}
    for k in range(model.ntext):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TEXT, k) or ""
        if name.startswith(MODAL_TEXT):
            data = model.text_data[model.text_adr[k]:model.text_adr[k] + model.text_size[k]]
            files[name[len(MODAL_TEXT):]] = (model_path.parent / data.decode().rstrip("\0")).resolve()
    return files


def frozen_copy(model_path: Path, files: dict[str, Path], folder: Path) -> Path:
    """The model with its modes frozen, in `folder`: the MJCF's folder
    mirrored by symbolic links (its assets and includes found as before),
    every modal file written again with its nodes and no modes. Returns the
    MJCF's path in the mirror."""
    source = model_path.parent.resolve()
    for path in files.values():
        if not path.is_relative_to(source):
            raise FreezeError(f"cannot freeze the modes of {path}: it is outside the model's folder {source}")
        if not path.is_file():
            # nudyn also looks beside an <include>d file that names it; this copy does not.
            raise FreezeError(f"cannot freeze the modes of {path}: no such file beside the model")
    frozen = {path: json.loads(path.read_text()) for path in set(files.values())}
    for modal in frozen.values():
        modal["modes"] = []
    # The folders on the way to a modal file are made real; everything else is linked.
    real_folders = {source} | {parent for path in frozen for parent in path.parents if parent.is_relative_to(source)}

    def mirror(original: Path, copy: Path) -> None:
        copy.mkdir(parents=True, exist_ok=True)
        for entry in original.iterdir():
            if entry in frozen:
                (copy / entry.name).write_text(json.dumps(frozen[entry]))
            elif entry in real_folders:
                mirror(entry, copy / entry.name)
            else:
                os.symlink(entry, copy / entry.name)

    mirror(source, folder)
    return folder / model_path.name


def export_frozen(nudyn: Path, model_path: Path, files: dict[str, Path], fmu: Path, **export_options) -> Path:
    """The FMU of the model with its modes frozen."""
    with tempfile.TemporaryDirectory(prefix="nudyn-frozen-") as folder:
        return Nudyn(nudyn).export(frozen_copy(model_path, files, Path(folder)), fmu, **export_options)


@dataclass
class ModalPart:
    """The vehicle with its modes over one scenario's held inputs."""

    scenario: str
    modes: list[tuple[str, float]]  # each mode's name and frequency (Hz)
    eta_low: np.ndarray  # (modes,): each modal coordinate's least value
    eta_high: np.ndarray  # (modes,): and its greatest (√kg m)
    strain_energy: np.ndarray  # (n + 1,): ½ Σ ω²η² at each communication point (J)
    kinetic_energy: np.ndarray  # (n + 1,)
    joint_difference: np.ndarray  # (n + 1,): max |θ[:nq] − MuJoCo's rigid qpos| (quaternions up to sign)

    def summary(self) -> dict:
        moved_most = int(np.argmax(np.maximum(np.abs(self.eta_low), np.abs(self.eta_high))))
        return {
            "scenario": self.scenario,
            "modes": [
                {"name": name, "frequency_hz": frequency, "eta_range": [float(low), float(high)]}
                for (name, frequency), low, high in zip(self.modes, self.eta_low, self.eta_high)
            ],
            "mode_moved_most": self.modes[moved_most][0],
            "max_abs_eta": float(max(abs(self.eta_low[moved_most]), abs(self.eta_high[moved_most]))),
            "max_strain_energy": float(self.strain_energy.max()),
            "max_kinetic_energy": float(self.kinetic_energy.max()),
            "max_joint_difference_from_rigid_mujoco": float(self.joint_difference.max()),
        }


def run_modal_part(fmu_path: Path, nudyn: Path, model_path: Path, result, settings, open_fmu) -> ModalPart:
    """The FMU with modes (`fmu_path`, exported with MODAL_OUTPUTS) from the
    scenario's start with the modes at rest, given the inputs of `result`
    (a compare.ScenarioResult of the frozen FMU) held: its ε on the joints
    (0 on the modes), its ctrl and wrenches. A closed-loop scenario's ε is
    so replayed, not recomputed from this run's ν. `open_fmu` is compare's."""
    scenario, cli = result.scenario, Nudyn(nudyn)
    modes = [(m["name"], m["frequency"]) for m in json.loads(cli.run("describe", model_path, "--json"))["modes"]]
    at_rest = np.zeros(len(modes))
    theta = np.concatenate([scenario.qpos0, at_rest])
    nu = cli.eval(model_path, {"theta": list(theta), "qvel": list(np.concatenate([scenario.qvel0, at_rest]))})["nu"]
    h = settings.communication_step
    theta_rows, strain, kinetic = [], [], []
    with tempfile.TemporaryDirectory(prefix="nudyn-fmu-") as unzip_dir:
        plain = settings.fmi_version == 2 and settings.interface == "cs"
        package = FmuPackage.unzip(fmu_path, Path(unzip_dir) / "package") if plain else None
        fmu = open_fmu(package, fmu_path, settings, theta, nu, Path(unzip_dir) / "run")
        try:
            def sample():
                theta_rows.append(fmu.array("theta"))
                strain.append(fmu.real("modal_strain_energy"))
                kinetic.append(fmu.real("kinetic_energy"))

            sample()
            for k, eps in enumerate(result.eps):
                fmu.set_array("eps", np.concatenate([eps, at_rest]))
                if result.ctrl is not None:
                    fmu.set_array("ctrl", result.ctrl[k])
                if scenario.wrench_law is not None:
                    fmu.set_array("xfrc_applied", scenario.wrench_law(k).ravel())
                fmu.step(h, communication_point=k * h)
                sample()
        finally:
            fmu.close()
    theta_rows = np.array(theta_rows)
    nq = len(scenario.qpos0)
    joints = theta_rows[:, :nq].copy()
    for a in result.quaternion_starts:
        block = slice(a, a + 4)
        flip = np.sum(joints[:, block] * result.mujoco.theta[:, block], axis=1) < 0.0
        joints[flip, block] *= -1.0
    eta = theta_rows[:, nq:]
    return ModalPart(
        scenario=scenario.name, modes=modes, eta_low=eta.min(axis=0), eta_high=eta.max(axis=0),
        strain_energy=np.array(strain), kinetic_energy=np.array(kinetic),
        joint_difference=np.max(np.abs(joints - result.mujoco.theta), axis=1),
    )
