"""scripts/validate.py on a vehicle with modal bodies (issue 49: "the
validation scripts compare the rigid part with MuJoCo and report the modal
part"; docs/validation.md, "Vehicles with flexible bodies"), on
examples/flexible_spacecraft/: MuJoCo's twin is the rigid vehicle, so the
judged comparison is of the FMU with its modes frozen, and the FMU with its
modes is reported beside it."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import ROOT

from nudyn_validation.compare import Settings, validate_model
from nudyn_validation.modal_part import FreezeError, frozen_copy, modal_files
from nudyn_validation.mujoco_reference import load_model
from nudyn_validation.report import write

EXAMPLE = ROOT / "examples" / "flexible_spacecraft" / "flexible_spacecraft.xml"
MODES = [f"{body}:mode{k}" for body in ("array_left", "array_right", "boom") for k in range(1, 5)]


@pytest.fixture(scope="module")
def validation(nudyn, tmp_path_factory):
    folder = tmp_path_factory.mktemp("validate_flexible")
    validation = validate_model(EXAMPLE, folder / "flexible_spacecraft.fmu", nudyn, None, Settings(duration=0.5, twins=0))
    return validation, write(validation, folder / "report")


def test_the_rigid_part_agrees_with_mujoco(validation):
    validation, _ = validation
    assert validation.rigid_fmu_path.is_file() and validation.fmu_path.is_file()
    assert [r.scenario.name for r in validation.results] == ["tumble", "sine", "damping", "actuated"]
    for result in validation.results:
        summary = result.summary()
        assert summary["max_theta_error"] < 1e-9 and summary["max_nu_error"] < 1e-9, summary
    assert validation.passed


def test_the_modal_part_is_reported_for_every_scenario(validation):
    validation, paths = validation
    parts = {part.scenario: part.summary() for part in validation.modal}
    assert list(parts) == ["tumble", "sine", "damping", "actuated"]
    for summary in parts.values():
        assert [mode["name"] for mode in summary["modes"]] == MODES
    # The sine's ε on the joints and the drives' torques bend the appendages,
    # and so move the joints away from MuJoCo's rigid run.
    for name in ("sine", "actuated"):
        assert parts[name]["max_strain_energy"] > 1e-4, parts[name]
        assert parts[name]["max_joint_difference_from_rigid_mujoco"] > 1e-4, parts[name]
    table = paths["table"].read_text()
    assert "## The modal part" in table and all(f"`{mode}`" in table for mode in MODES)
    numbers = json.loads(paths["json"].read_text())
    assert [part["scenario"] for part in numbers["modal"]] == list(parts)


def test_the_frozen_copy_keeps_the_nodes_and_drops_the_modes(tmp_path):
    files = modal_files(load_model(EXAMPLE), EXAMPLE)
    assert sorted(files) == ["array_left", "array_right", "boom"]
    copy = frozen_copy(EXAMPLE, files, tmp_path / "frozen")
    for name in ("array.json", "boom.json"):
        original, frozen = (json.loads((folder / name).read_text()) for folder in (EXAMPLE.parent, copy.parent))
        assert original["modes"] and frozen["modes"] == []
        assert np.array_equal([n["mass"] for n in frozen["nodes"]], [n["mass"] for n in original["nodes"]])
    assert copy.read_text() == EXAMPLE.read_text()


def test_a_modal_file_outside_the_model_folder_is_refused(tmp_path):
    (tmp_path / "outside.json").write_text(json.dumps({"modes": []}))
    model = tmp_path / "model" / "vehicle.xml"
    model.parent.mkdir()
    with pytest.raises(FreezeError, match="outside the model's folder"):
        frozen_copy(model, {"panel": tmp_path / "outside.json"}, tmp_path / "frozen")
