"""`nudyn modal` and the CalculiX converter (docs/flexible.md, "From a
structural solver"; issue 49, item 5).

The CLI's summary is checked against values worked by hand on the fixture
tests/fixtures/flex/bench.json. The converter is shown on a cantilever
beam and a cantilever plate that the tests mesh themselves (structured
grids of 8-node hexahedra, C3D8I, and for the beam also of 20-node
hexahedra and 10-node tetrahedra, written as a CalculiX deck) and run through ccx
in a temporary folder: the frequencies against Euler–Bernoulli and
Leissa's Kirchhoff-plate values, the converted file through `nudyn modal`
(every check of nudyn's reader, the mass, the effective masses)."""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from conftest import ROOT
from nudyn_validation import calculix
from nudyn_validation.calculix_decks import run_ccx, write_box_deck

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
    assert '<inertial pos="0.375 0 0" mass="4" fullinertia="0.01 0.7075 0.7075 0 0 0"/>' in table.stdout
    assert table.stdout.splitlines()[-1].split() == ["sum", "0.00", "25.00", "25.00", "100.00", "19.69", "78.74"]


def test_modal_refuses_a_bad_file_naming_the_file_and_the_field(nudyn, tmp_path):
    data = json.loads(BENCH.read_text())
    data["modes"][1]["shape"][1] = [0, 0, 0.5, 10, 0, 0]  # now not orthogonal to mode 1
    bad = tmp_path / "coupled.json"
    bad.write_text(json.dumps(data))
    proc = modal(nudyn, bad)
    assert proc.returncode == 1 and proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and str(bad) in lines[0], proc.stderr
    assert "modes[0] and modes[1] are not orthogonal" in lines[0], proc.stderr

    missing = modal(nudyn, tmp_path / "absent.json")
    assert missing.returncode == 1, missing.stderr
    assert "cannot read the modal file" in missing.stderr and "absent.json" in missing.stderr


# --- the converter, on meshes made here ----------------------------------------


def test_lumped_masses_of_distorted_elements():
    """Row sums on elements that are not parallelepipeds: a hexahedron whose
    cross-section is a trapezoid (parallel sides 2 and 1, height 1, depth 1)
    has volume 1.5 = Σ ∫ Nᵢ dV, and its nodes on the long side carry more;
    a tetrahedron's nodes carry a quarter each; an inverted element is refused."""
    # Bottom face z = 0 has the long side (x from 0 to 2), top face z = 1 the short one.
    corners = [(0, 0, 0), (2, 0, 0), (2, 1, 0), (0, 1, 0), (0.5, 0, 1), (1.5, 0, 1), (1.5, 1, 1), (0.5, 1, 1)]
    nodes = {k + 1: c for k, c in enumerate(corners)}
    masses = calculix.lumped_masses(nodes, {1: (calculix.HEXAHEDRON, list(range(1, 9)))}, density=2.0)
    assert sum(masses.values()) == pytest.approx(2.0 * 1.5, rel=1e-14)
    bottom, top = [masses[k] for k in (1, 2, 3, 4)], [masses[k] for k in (5, 6, 7, 8)]
    assert bottom == pytest.approx([bottom[0]] * 4) and top == pytest.approx([top[0]] * 4)
    # ∫ Nᵢ dV for a bottom node: the width 2 − z falls linearly; the shares are
    # ∫₀¹ (1 − z)(2 − z) dz / 4 · ρ = (5/6)/4 · 2 and ∫₀¹ z(2 − z) dz / 4 · ρ = (2/3)/4 · 2.
    assert bottom[0] == pytest.approx(2.0 * 5 / 24, rel=1e-14) and top[0] == pytest.approx(2.0 * 1 / 6, rel=1e-14)

    tetrahedron = {1: (0, 0, 0), 2: (3, 0, 0), 3: (0, 2, 0), 4: (0, 0, 1)}
    masses = calculix.lumped_masses(tetrahedron, {7: (calculix.TETRAHEDRON, [1, 2, 3, 4])}, density=1.0)
    assert list(masses.values()) == pytest.approx([0.25] * 4, rel=1e-14)  # volume 3·2·1/6 = 1

    with pytest.raises(calculix.ConversionError, match="element 7 is inverted"):
        calculix.lumped_masses(tetrahedron, {7: (calculix.TETRAHEDRON, [1, 3, 2, 4])}, density=1.0)
    with pytest.raises(calculix.ConversionError, match=r"element 9 \(6-node wedge\)"):
        calculix.lumped_masses(nodes, {9: (2, [1, 2, 3, 4, 5, 6])}, density=1.0)


def test_ritz_step_with_every_mode_is_the_lumped_eigenproblem(nudyn, tmp_path):
    """Two unit cubes side by side (12 nodes), clamped on x = 0 (4 nodes): 24
    free degrees of freedom. Modes made here of a random stiffness K and a
    random "consistent" mass M_c, all 24 of them, handed to the converter
    as if CalculiX had written them: in their full span the Ritz step must
    give exactly the eigenproblem (K, M_lumped), solved here apart, and the
    effective masses must sum to the mass of the nodes that move."""
    rng = np.random.default_rng(49)
    points = [(i, j, k) for k in (0, 1) for j in (0, 1) for i in (0, 1, 2)]
    nodes = {n + 1: tuple(map(float, p)) for n, p in enumerate(points)}

    def number(i, j, k):
        return 1 + points.index((i, j, k))

    elements = {e + 1: (calculix.HEXAHEDRON, [number(e + di, dj, dk) for dk in (0, 1)
                                               for dj, di in ((0, 0), (0, 1), (1, 1), (1, 0))])
                for e in (0, 1)}
    free = [n for n in nodes if nodes[n][0] > 0]  # 8 nodes
    density = 3.0
    # Each cube's 3 kg in eighths: nodes at x = 1 are in both cubes.
    lumped = {n: density / 8 * (2 if nodes[n][0] == 1 else 1) for n in nodes}
    m_lumped = np.repeat([lumped[n] for n in free], 3)
    a = rng.standard_normal((24, 24))
    stiffness = a @ a.T + 24 * np.eye(24)
    b = rng.standard_normal((24, 24))
    consistent = np.diag(m_lumped) + 0.05 * b @ b.T
    # Modes in the consistent mass, unit generalized mass (CalculiX's normalization).
    chol = np.linalg.cholesky(consistent)
    inverse = np.linalg.inv(chol)
    eigenvalues, vectors = np.linalg.eigh(inverse @ stiffness @ inverse.T)
    shapes = (inverse.T @ vectors).T  # 24 modes × 24 free degrees of freedom
    modes = []
    for k, (value, shape) in enumerate(zip(eigenvalues, shapes)):
        by_node = {n: (0.0, 0.0, 0.0) for n in nodes}
        by_node.update({n: tuple(shape[3 * f:3 * f + 3]) for f, n in enumerate(free)})
        modes.append(calculix.FrdMode(number=k + 1, frequency=math.sqrt(value) / (2 * math.pi), shape=by_node))
    conversion = calculix.convert(calculix.FrdResults(nodes, elements, modes), density)
    assert conversion.modal_file["nodes"][0]["mass"] == pytest.approx(lumped[1], rel=1e-14)

    # The lumped eigenproblem, directly.
    scaled = stiffness / np.sqrt(np.outer(m_lumped, m_lumped))
    expected = np.sqrt(np.linalg.eigvalsh(scaled)) / (2 * math.pi)
    assert conversion.frequencies == pytest.approx(expected, rel=1e-10)

    path = tmp_path / "complete.json"
    path.write_text(calculix.layout(conversion.modal_file))
    proc = modal(nudyn, path, "--json")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    # 6 kg, of which the 4 clamped nodes carry 4 × 3/8: 3/4 of the mass moves.
    assert summary["mass"] == pytest.approx(6.0) and summary["fixed_nodes"] == 4
    assert summary["fixed_mass"] == pytest.approx(1.5)
    assert summary["effective_mass_fraction"]["translation"] == pytest.approx([0.75] * 3, rel=1e-10)
    # Rotations about the origin: the moving nodes' share of the inertia about it, axis by axis.

    def inertia_about_origin(numbers):
        return sum(lumped[n] * (np.dot(nodes[n], nodes[n]) - np.square(nodes[n])) for n in numbers)

    shares = inertia_about_origin(free) / inertia_about_origin(nodes)
    assert summary["effective_mass_fraction"]["rotation"] == pytest.approx(shares, rel=1e-10)


def test_lumped_masses_of_a_20_node_hexahedron():
    """HRZ on a box 2 × 1 × 1: the diagonal of the consistent mass, ∫ Nᵢ² dV,
    is in the ratio 7 : 16 between a corner and a mid-edge node (worked by
    hand on the cube [−1, 1]³: 0.20741 and 64/135), so the corners get 7/248
    of the mass each and the mid-edge nodes 16/248."""
    corners = np.array([(0, 0, 0), (2, 0, 0), (2, 1, 0), (0, 1, 0), (0, 0, 1), (2, 0, 1), (2, 1, 1), (0, 1, 1)], float)
    # The .frd's order: the bottom face's edges, the vertical edges, the top face's edges.
    edges = [(0, 1), (1, 2), (2, 3), (3, 0), (0, 4), (1, 5), (2, 6), (3, 7), (4, 5), (5, 6), (6, 7), (7, 4)]
    points = list(corners) + [(corners[a] + corners[b]) / 2 for a, b in edges]
    nodes = {k + 1: tuple(p) for k, p in enumerate(points)}
    masses = calculix.lumped_masses(nodes, {1: (calculix.HEXAHEDRON20, list(range(1, 21)))}, density=3.0)
    shares = np.array([masses[k] for k in range(1, 21)]) / (3.0 * 2.0)
    assert shares == pytest.approx([7 / 248] * 8 + [16 / 248] * 12, rel=1e-12)


@pytest.fixture(scope="module")
def ccx():
    """CalculiX's solver; fails (never skips) when it is missing: scripts/setup-test.sh installs calculix-ccx."""
    path = shutil.which("ccx")
    if path is None:
        pytest.fail("ccx not found: install the Debian package calculix-ccx (scripts/setup-test.sh does)",
                    pytrace=False)
    return path


def dat_frequencies(dat: Path):
    """The frequencies (cycles/time) of ccx's eigenvalue table in the .dat,
    written apart from the .frd's."""
    rows = []
    lines = dat.read_text().splitlines()
    start = next(k for k, line in enumerate(lines) if "E I G E N V A L U E   O U T P U T" in line)
    for line in lines[start + 1:]:
        parts = line.split()
        if len(parts) == 5 and parts[0].isdigit():
            rows.append(float(parts[3]))
        elif rows and not parts:
            break
    return np.array(rows)


def convert(frd: Path, output: Path, *args):
    command = [sys.executable, "-m", "nudyn_validation.calculix", str(frd), "-o", str(output), *args]
    environment = {**os.environ, "PYTHONPATH": str(ROOT / "python")}
    return subprocess.run(command, capture_output=True, text=True, timeout=120, env=environment)


def shape_fractions(modal_file, axis):
    """Per mode, the share of its (unit) modal mass that moves along `axis` (0, 1, 2)."""
    masses = np.array([n["mass"] for n in modal_file["nodes"]])
    return [float(np.sum(masses * np.square(np.array(m["shape"])[:, axis]))) for m in modal_file["modes"]]


# Steel cantilever, 1 m × 50 mm × 20 mm, bending about y (vibrating along z) first.
BEAM = {"size": (1.0, 0.05, 0.02), "young": 210e9, "poisson": 0.3, "density": 7800.0}
BEAM_MESH = (40, 2, 1)
# Euler–Bernoulli, clamped–free: the roots λₙL of cos λ cosh λ = −1.
EULER_BERNOULLI = [1.87510407, 4.69409113, 7.85475744]


def euler_bernoulli_mass_share(lam):
    """The share of a cantilever's mass that mode n moves (its effective mass
    over the mass): 4σₙ²/λₙ², σₙ = (sinh λₙ − sin λₙ)/(cosh λₙ + cos λₙ)."""
    sigma = (math.sinh(lam) - math.sin(lam)) / (math.cosh(lam) + math.cos(lam))
    return 4 * sigma ** 2 / lam ** 2


def euler_bernoulli_frequency(lam, size, young, density, **_):
    length, _, height = size
    # EI / (ρA) = E h² / (12 ρ) for bending across the height.
    return lam ** 2 / (2 * math.pi * length ** 2) * math.sqrt(young * height ** 2 / (12 * density))


@pytest.mark.parametrize("element, mesh", [("C3D8I", BEAM_MESH), ("C3D20R", (20, 2, 1)), ("C3D10", (20, 2, 1))])
def test_cantilever_beam_against_euler_bernoulli(ccx, nudyn, tmp_path, element, mesh):
    deck = tmp_path / "beam.inp"
    write_box_deck(deck, BEAM["size"], mesh, young=BEAM["young"], poisson=BEAM["poisson"],
                   density=BEAM["density"], modes=8, element=element)
    frd = run_ccx(ccx, deck)
    output = tmp_path / "beam.json"
    proc = convert(frd, output, "--inp", str(deck), "--density", "7800", "--damping", "0.005")
    assert proc.returncode == 0 and "warning" not in proc.stderr, proc.stderr
    assert "shift" in proc.stdout, proc.stdout

    # The converter's FE frequencies are the .frd's; the .dat lists the same modes apart from it.
    results = calculix.read_frd(frd)
    assert [m.frequency for m in results.modes] == pytest.approx(dat_frequencies(deck.with_suffix(".dat")), rel=1e-6)

    modal_file = json.loads(output.read_text())
    summary_proc = modal(nudyn, output, "--json")
    assert summary_proc.returncode == 0, summary_proc.stderr  # nudyn's checks: orthogonal, unit modal masses
    summary = json.loads(summary_proc.stdout)
    length, width, height = BEAM["size"]
    assert summary["mass"] == pytest.approx(BEAM["density"] * length * width * height, rel=1e-12)
    assert summary["com"] == pytest.approx([length / 2, width / 2, height / 2], rel=1e-12)
    assert summary["fixed_nodes"] == sum(1 for node in modal_file["nodes"] if node["position"][0] == 0)
    assert all(m["damping_ratio"] == 0.005 for m in summary["modes"])
    for node in modal_file["nodes"]:
        assert node.get("rotary_inertia") is None
    assert all(s[3:] == [0, 0, 0] for m in modal_file["modes"] for s in m["shape"])

    # The bending modes across the height: the modes that move mostly along z.
    vertical = [k for k, share in enumerate(shape_fractions(modal_file, 2)) if share > 0.9]
    assert len(vertical) >= 3, shape_fractions(modal_file, 2)
    for lam, k in zip(EULER_BERNOULLI, vertical):
        mass_share = euler_bernoulli_mass_share(lam)
        expected = euler_bernoulli_frequency(lam, **BEAM)
        frequency = summary["modes"][k]["frequency"]
        assert frequency == pytest.approx(expected, rel=0.01), (k, frequency, expected)
        share = summary["modes"][k]["effective_mass_fraction"]["translation"][2]
        assert share == pytest.approx(mass_share, rel=0.02), (k, share, mass_share)
    # The sum over the modes kept: at least the three bending modes' 86.6 %, at most
    # what the nodes that move carry.
    total_z = summary["effective_mass_fraction"]["translation"][2]
    moving = 1 - summary["fixed_mass"] / summary["mass"]
    assert 0.86 < total_z <= moving, (total_z, moving)


def test_the_same_beam_in_millimetres_and_tonnes(ccx, nudyn, tmp_path):
    """A deck in mm, t, s (E in MPa, ρ in t/mm³) gives the same body in SI."""
    deck = tmp_path / "beam_mm.inp"
    write_box_deck(deck, BEAM["size"], BEAM_MESH, young=BEAM["young"] * 1e-6, poisson=BEAM["poisson"],
                   density=BEAM["density"] * 1e-12, modes=3, scale=1000.0)
    frd = run_ccx(ccx, deck)
    output = tmp_path / "beam_mm.json"
    proc = convert(frd, output, "--inp", str(deck), "--density", "7.8e-9", "--length-unit", "mm",
                   "--mass-unit", "t")
    assert proc.returncode == 0, proc.stderr
    assert json.loads(output.read_text())["units"] == {"length": "mm", "mass": "t", "frequency": "Hz"}
    summary = json.loads(modal(nudyn, output, "--json").stdout)
    length, width, height = BEAM["size"]
    assert summary["mass"] == pytest.approx(BEAM["density"] * length * width * height, rel=1e-12)
    first_frequency = euler_bernoulli_frequency(EULER_BERNOULLI[0], **BEAM)
    assert summary["modes"][0]["frequency"] == pytest.approx(first_frequency, rel=0.01)
    first_share = euler_bernoulli_mass_share(EULER_BERNOULLI[0])
    assert summary["modes"][0]["effective_mass_fraction"]["translation"][2] == pytest.approx(first_share, rel=0.02)


# Aluminium cantilever plate 0.5 m square, 5 mm thick, clamped along x = 0.
PLATE = {"size": (0.5, 0.5, 0.005), "young": 70e9, "poisson": 0.3, "density": 2700.0}
PLATE_MESH = (20, 20, 1)
# ω a² √(ρh/D) of the first six modes of a square cantilever plate, ν = 0.3
# (Barton 1951, in Leissa's "Vibration of Plates", 1969).
LEISSA_CANTILEVER_SQUARE = [3.492, 8.525, 21.43, 27.33, 31.11, 54.44]


def test_cantilever_plate_against_kirchhoff(ccx, nudyn, tmp_path):
    deck = tmp_path / "plate.inp"
    write_box_deck(deck, PLATE["size"], PLATE_MESH, young=PLATE["young"], poisson=PLATE["poisson"],
                   density=PLATE["density"], modes=6)
    frd = run_ccx(ccx, deck)
    # The body frame: origin at the middle of the clamped edge; body x along the
    # plate's normal (FE z), body y along FE x, body z along FE y.
    output = tmp_path / "plate.json"
    proc = convert(frd, output, "--inp", str(deck), "--density", "2700", "--origin", "0,0.25,0",
                   "--axes", "0,0,1,1,0,0,0,1,0", "--damping", "0.01,0.01,0.02,0.02,0.03,0.03")
    assert proc.returncode == 0, proc.stderr
    summary_proc = modal(nudyn, output, "--json")
    assert summary_proc.returncode == 0, summary_proc.stderr
    summary = json.loads(summary_proc.stdout)

    a, _, h = PLATE["size"]
    assert summary["mass"] == pytest.approx(PLATE["density"] * a * a * h, rel=1e-12)
    # The centre (a/2, a/2, h/2) in FE coordinates, less the origin, in body axes.
    assert summary["com"] == pytest.approx([h / 2, a / 2, 0.0], abs=1e-12)
    rigidity = PLATE["young"] * h ** 3 / (12 * (1 - PLATE["poisson"] ** 2))
    scale = math.sqrt(rigidity / (PLATE["density"] * h)) / (2 * math.pi * a * a)
    frequencies = [m["frequency"] for m in summary["modes"]]
    assert frequencies == pytest.approx([lam * scale for lam in LEISSA_CANTILEVER_SQUARE], rel=0.015)
    assert [m["damping_ratio"] for m in summary["modes"]] == [0.01, 0.01, 0.02, 0.02, 0.03, 0.03]
    # The first mode bends the plate along its normal, body x: about as much
    # mass as a cantilever beam's first mode, and nothing in the plane.
    first = summary["modes"][0]["effective_mass_fraction"]["translation"]
    assert first[0] == pytest.approx(euler_bernoulli_mass_share(EULER_BERNOULLI[0]), rel=0.03), first
    assert max(first[1:]) < 1e-6, first
    total = summary["effective_mass_fraction"]["translation"][0]
    assert total <= 1 - summary["fixed_mass"] / summary["mass"]

    # The <inertial> that `nudyn modal` prints for the MJCF body, as MuJoCo reads it.
    table = modal(nudyn, output).stdout
    inertial = next(line.strip() for line in table.splitlines() if line.strip().startswith("<inertial "))
    model = mujoco.MjModel.from_xml_string(
        f'<mujoco><worldbody><body name="panel"><freejoint/>{inertial}</body></worldbody></mujoco>')
    body = model.body("panel")
    assert body.mass[0] == pytest.approx(summary["mass"], rel=1e-12)
    assert body.ipos == pytest.approx(summary["com"], abs=1e-12)
    axes = np.zeros(9)
    mujoco.mju_quat2Mat(axes, body.iquat)
    axes = axes.reshape(3, 3)
    inertia = axes @ np.diag(body.inertia) @ axes.T
    assert np.abs(inertia - np.array(summary["inertia"])).max() <= 1e-9 * np.abs(inertia).max()


def write_shell_plate_deck(path: Path, side, thickness, divisions, *, young, poisson, density, modes):
    """A square plate of 8-node shells (S8R) in the plane z = 0, clamped
    (translations and rotations) along x = 0."""
    def node(i, j):
        return 1 + i + (2 * divisions + 1) * j

    elements = []
    for i, j in np.ndindex(divisions, divisions):
        i0, j0 = 2 * i, 2 * j
        corners = [(i0, j0), (i0 + 2, j0), (i0 + 2, j0 + 2), (i0, j0 + 2)]
        middles = [(i0 + 1, j0), (i0 + 2, j0 + 1), (i0 + 1, j0 + 2), (i0, j0 + 1)]
        elements.append([node(*p) for p in corners + middles])
    used = sorted({n for members in elements for n in members})
    step = side / (2 * divisions)
    lines = ["*NODE, NSET=NALL"]
    lines += [f"{n}, {step * ((n - 1) % (2 * divisions + 1))!r}, {step * ((n - 1) // (2 * divisions + 1))!r}, 0.0"
              for n in used]
    lines.append("*ELEMENT, TYPE=S8R, ELSET=EALL")
    lines += [f"{number}, " + ", ".join(map(str, members)) for number, members in enumerate(elements, start=1)]
    lines.append("*NSET, NSET=CLAMPED")
    lines += [f"{n}," for n in used if (n - 1) % (2 * divisions + 1) == 0]
    lines += ["*BOUNDARY", "CLAMPED, 1, 6",
              "*MATERIAL, NAME=MATERIAL", "*ELASTIC", f"{young!r}, {poisson!r}", "*DENSITY", f"{density!r}",
              "*SHELL SECTION, ELSET=EALL, MATERIAL=MATERIAL", f"{thickness!r}",
              "*STEP", "*FREQUENCY", str(modes), "*NODE FILE", "U", "*END STEP"]
    path.write_text("\n".join(lines) + "\n")


def test_a_shell_plate_as_calculix_expands_it(ccx, nudyn, tmp_path):
    """Shells (S8R) reach the .frd expanded into 20-node hexahedra through
    the thickness, with nodes of ccx's own beside the deck's: the converter
    takes those, and the plate matches Leissa's values as the solid one does."""
    a, _, h = PLATE["size"]
    deck = tmp_path / "shell.inp"
    write_shell_plate_deck(deck, a, h, 10, young=PLATE["young"], poisson=PLATE["poisson"],
                           density=PLATE["density"], modes=6)
    frd = run_ccx(ccx, deck)
    output = tmp_path / "shell.json"
    proc = convert(frd, output, "--inp", str(deck), "--density", "2700")
    assert proc.returncode == 0 and "warning" not in proc.stderr, proc.stderr
    summary_proc = modal(nudyn, output, "--json")
    assert summary_proc.returncode == 0, summary_proc.stderr
    summary = json.loads(summary_proc.stdout)
    assert summary["mass"] == pytest.approx(PLATE["density"] * a * a * h, rel=1e-9)
    rigidity = PLATE["young"] * h ** 3 / (12 * (1 - PLATE["poisson"] ** 2))
    scale = math.sqrt(rigidity / (PLATE["density"] * h)) / (2 * math.pi * a * a)
    frequencies = [m["frequency"] for m in summary["modes"]]
    assert frequencies == pytest.approx([lam * scale for lam in LEISSA_CANTILEVER_SQUARE], rel=0.03)

    # Written as shells (OUTPUT=2D), the results carry no volume to lump.
    deck.write_text(deck.read_text().replace("*NODE FILE", "*NODE FILE, OUTPUT=2D"))
    proc = convert(run_ccx(ccx, deck), output, "--inp", str(deck), "--density", "2700")
    assert proc.returncode == 2 and "(8-node quadrilateral): the converter lumps" in proc.stderr, proc.stderr
    assert "*NODE FILE without OUTPUT=2D" in proc.stderr


def test_the_finite_element_modes_as_they_come_are_refused(ccx, nudyn, tmp_path):
    """Why the converter solves again: CalculiX's modes, orthogonal in its
    consistent mass, are not in the nodes' lumped masses, and nudyn says so."""
    deck = tmp_path / "beam.inp"
    write_box_deck(deck, BEAM["size"], (10, 1, 1), young=BEAM["young"], poisson=BEAM["poisson"],
                   density=BEAM["density"], modes=3)
    results = calculix.read_frd(run_ccx(ccx, deck))
    masses = calculix.lumped_masses(results.nodes, results.elements, BEAM["density"])
    numbers = sorted(masses)
    raw = {"format": "nudyn-modal", "version": 1, "mass_normalized": False,
           "nodes": [{"name": f"n{n}", "position": list(results.nodes[n]), "mass": masses[n]} for n in numbers],
           "modes": [{"frequency": m.frequency, "damping_ratio": 0.0,
                      "shape": [[*m.shape[n], 0, 0, 0] for n in numbers]} for m in results.modes]}
    path = tmp_path / "raw.json"
    path.write_text(json.dumps(raw))
    proc = modal(nudyn, path)
    assert proc.returncode == 1 and "are not orthogonal in the nodes' mass" in proc.stderr, proc.stderr

    output = tmp_path / "converted.json"
    assert convert(deck.with_suffix(".frd"), output, "--density", "7800").returncode == 0
    assert modal(nudyn, output).returncode == 0


def test_a_mesh_too_coarse_for_lumped_masses_is_warned_of(ccx, tmp_path):
    """20-node hexahedra one across the section: CalculiX's modes carry
    node-to-node oscillations that its consistent mass hides and the lumped
    masses weigh tens to hundreds of times over."""
    deck = tmp_path / "beam.inp"
    write_box_deck(deck, BEAM["size"], (10, 1, 1), young=BEAM["young"], poisson=BEAM["poisson"],
                   density=BEAM["density"], modes=3, element="C3D20R")
    proc = convert(run_ccx(ccx, deck), tmp_path / "coarse.json", "--density", "7800")
    assert proc.returncode == 0, proc.stderr
    assert "warning: FE mode 1 has" in proc.stderr and "the mesh is too coarse for lumped masses" in proc.stderr


def test_converter_refuses_what_it_cannot_use(ccx, tmp_path):
    deck = tmp_path / "beam.inp"
    write_box_deck(deck, BEAM["size"], (10, 1, 1), young=BEAM["young"], poisson=BEAM["poisson"],
                   density=BEAM["density"], modes=3)
    frd = run_ccx(ccx, deck)
    output = tmp_path / "out.json"
    cases = [
        (["--density", "7800", "--modes", "4"], "--modes 4: the results hold 3 such modes"),
        (["--density", "7800", "--damping", "0.01,0.02"], "--damping has 2 values; give one, or one per mode (3)"),
        (["--density", "7800", "--axes", "1,0,0,0,1,0,0,0,2"], "are not three orthonormal right-handed axes"),
        (["--density", "0"], "--density is 0.0; it must be positive"),
        (["--density", "7800", "--max-frequency", "1"], "no mode is chosen"),
    ]
    for args, message in cases:
        proc = convert(frd, output, *args)
        assert proc.returncode == 2 and message in proc.stderr, (args, proc.stderr)
        assert not output.exists()

    text = frd.read_text()
    cut = tmp_path / "cut.frd"
    cut.write_text(text[:text.index("\n", 5000) + 1])  # a whole line, then nothing
    proc = convert(cut, output, "--density", "7800")
    assert proc.returncode == 2 and "cut.frd ends inside a block" in proc.stderr, proc.stderr
    lines = text.splitlines()
    broken = next(k for k, line in enumerate(lines) if line.startswith(" -1") and k > 100)
    lines[broken] = lines[broken][:20]  # a coordinate cut short
    cut.write_text("\n".join(lines) + "\n")
    proc = convert(cut, output, "--density", "7800")
    assert proc.returncode == 2 and f"cut.frd:{broken + 1}: " in proc.stderr, proc.stderr


def test_mujoco_loads_the_flexible_vehicle_as_the_rigid_one():
    """The nudyn:modal: text that makes a body flexible is one MuJoCo keeps
    and ignores: the same MJCF file is the rigid vehicle there, with the
    inertial the modal file's nodes were held to at nudyn's import."""
    model = mujoco.MjModel.from_xml_path(str(ROOT / "tests/fixtures/flex/bench_vehicle.xml"))
    assert model.ntext == 1 and bytes(model.text_data).startswith(b"bench.json")
    bench = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "bench")
    assert model.body_mass[bench] == 4.0
    assert np.allclose(model.body_inertia[bench], [0.01, 0.7075, 0.7075], rtol=1e-12)
