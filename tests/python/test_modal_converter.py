"""`nudyn modal` and the CalculiX converter (docs/flexible.md, "From a
structural solver"; issue 49, item 5).

The CLI's summary is checked against values worked by hand on the fixture
tests/fixtures/flex/bench.json. The converter is shown on a cantilever
beam and a cantilever plate that the tests mesh themselves (structured
8-node hexahedra, C3D8I, written as a CalculiX deck) and run through ccx
in a temporary folder: the frequencies against Euler–Bernoulli and
Leissa's Kirchhoff-plate values, the converted file through `nudyn modal`
(every check of nudyn's reader, the mass, the effective masses)."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT
from nudyn_validation import calculix

BENCH = ROOT / "tests" / "fixtures" / "flex" / "bench.json"


def modal(nudyn, path, *args):
    return subprocess.run([str(nudyn), "modal", str(path), *args], capture_output=True, text=True, timeout=60)


def test_modal_summary_of_the_bench_fixture(nudyn):
    """Worked by hand: mode 1 moves the middle node (1 kg, at x = 0.5) by 1
    along z: L_z = 1, and for the rotation about y through the origin that
    node moves by e_y × r = (0, 0, −0.5): L_ry = −0.5. Mode 2 turns the middle
    node by 10 rad about x against Ixx = 0.01: L_rx = 0.1. Mode 3 moves the
    tip (1 kg, at x = 1) by 1 along y: L_y = 1, L_rz = 1 (its rotation
    meets no rotary inertia)."""
    proc = modal(nudyn, BENCH, "--json")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert summary["nodes"] == 3 and summary["fixed_nodes"] == 1 and summary["fixed_mass"] == 2.0
    assert summary["mass"] == pytest.approx(4.0) and summary["com"] == pytest.approx([0.375, 0, 0])
    # About the origin: Iyy = Izz = 1·0.5² + 1·1² + 0.02 (the middle node's own), Ixx = 0.01.
    assert np.diag(summary["inertia_about_origin"]) == pytest.approx([0.01, 1.27, 1.27])
    expected = [
        ([0, 0, 1], [0, -0.5, 0]),
        ([0, 0, 0], [0.1, 0, 0]),
        ([0, 1, 0], [0, 0, 1]),
    ]
    for mode, (translation, rotation) in zip(summary["modes"], expected):
        assert mode["participation"]["translation"] == pytest.approx(translation, abs=1e-12)
        assert mode["participation"]["rotation"] == pytest.approx(rotation, abs=1e-12)
        assert mode["effective_mass"]["rotation"] == pytest.approx(np.square(rotation), abs=1e-12)
    assert [m["frequency"] for m in summary["modes"]] == pytest.approx([1.5, 4.0, 9.0])
    assert summary["effective_mass_fraction"]["translation"] == pytest.approx([0, 0.25, 0.25], abs=1e-12)
    assert summary["effective_mass_fraction"]["rotation"] == pytest.approx([1.0, 0.25 / 1.27, 1 / 1.27])

    table = modal(nudyn, BENCH)
    assert table.returncode == 0, table.stderr
    assert "3 nodes (1 that no mode moves, 2 kg), 3 modes" in table.stdout
    assert table.stdout.splitlines()[-1].split() == ["sum", "0.00", "25.00", "25.00", "100.00", "19.69", "78.74"]


def test_modal_refuses_a_bad_file_naming_the_file_and_the_field(nudyn, tmp_path):
    data = json.loads(BENCH.read_text())
    data["modes"][1]["shape"][1] = [0, 0, 0.5, 10, 0, 0]  # now not orthogonal to mode 1
    bad = tmp_path / "coupled.json"
    bad.write_text(json.dumps(data))
    proc = modal(nudyn, bad)
    assert proc.returncode == 1 and proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and str(bad) in lines[0] and "modes[0] and modes[1] are not orthogonal" in lines[0], proc.stderr

    missing = modal(nudyn, tmp_path / "absent.json")
    assert missing.returncode == 1 and "cannot read the modal file" in missing.stderr and "absent.json" in missing.stderr
