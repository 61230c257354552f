"""From CalculiX frequency results to nudyn's modal data file (version 1,
docs/flexible.md, "From a structural solver").

Input: the `.frd` of a `*FREQUENCY` step with the displacements written
(`*NODE FILE` with `U`): it holds the nodes, the elements, each mode's
frequency and generalized mass, and each mode's shape; optionally the
`.inp` deck, whose `*NODE` coordinates are read at full precision (the
`.frd` keeps six digits). The density is given on the command line.

nudyn holds the modes orthogonal in the nodes' lumped masses, where a
finite-element model has a consistent mass matrix. So the converter lumps
the mass at the nodes (a linear element's ∫ρ Nᵢ dV, the row sums of its
consistent mass; a quadratic element's mass in proportion to the diagonal
∫ρ Nᵢ² dV, HRZ), then solves the eigenproblem again in the span Φ of the
chosen finite-element modes (a Ritz step):

    K_r = Φᵀ K Φ = diag(ω²ᵢ gᵢ)     (the FE modes' own orthogonality; gᵢ
                                      their generalized mass, 1 in CalculiX)
    M_r = Φᵀ M_lumped Φ
    K_r q = ω̃² M_r q,   shapes Φ q

whose modes are exactly orthogonal in the lumped masses, with unit modal
mass. It reports the frequency each mode moves by, and warns of FE modes
whose modal mass in the lumped masses is far from their own.

Solid elements carry translations only: every node's rotations and rotary
inertia are 0. Nodes that the finite-element model clamps (the interface
to the parent body) have zero shape and keep their mass: they are part of
the body.

Run as `python -m nudyn_validation.calculix RESULTS.frd --density RHO -o OUT.json`.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

FORMAT = "nudyn-modal"
VERSION = 1

# CalculiX's element types in the .frd (its manual, "Result (.frd) file"),
# the ones whose mass the converter lumps: hexahedra of 8 nodes (C3D8,
# C3D8R, C3D8I) and 20 (C3D20, C3D20R), tetrahedra of 4 (C3D4) and 10 (C3D10).
HEXAHEDRON = 1
TETRAHEDRON = 3
HEXAHEDRON20 = 4
TETRAHEDRON10 = 6
FRD_TYPE_NAMES = {1: "8-node hexahedron", 2: "6-node wedge", 3: "4-node tetrahedron",
                  4: "20-node hexahedron", 5: "15-node wedge", 6: "10-node tetrahedron",
                  7: "3-node triangle", 8: "6-node triangle", 9: "4-node quadrilateral",
                  10: "8-node quadrilateral", 11: "2-node beam", 12: "3-node beam"}
NODES_PER_TYPE = {1: 8, 2: 6, 3: 4, 4: 20, 5: 15, 6: 10, 7: 3, 8: 6, 9: 4, 10: 8, 11: 2, 12: 3}


class ConversionError(Exception):
    """A result or an option the converter cannot use; the message names it."""


@dataclass
class FrdMode:
    """One mode of the .frd: its frequency (Hz), generalized mass and shape."""

    number: int
    frequency: float
    generalized_mass: float = 1.0
    shape: dict[int, tuple[float, float, float]] = field(default_factory=dict)


@dataclass
class FrdResults:
    """What the converter reads from a .frd: nodes, elements and modes."""

    nodes: dict[int, tuple[float, float, float]]
    elements: dict[int, tuple[int, list[int]]]  # number: (frd type, node numbers)
    modes: list[FrdMode]


def _fixed_float(text: str, start: int, width: int = 12) -> float:
    return float(text[start:start + width])


def read_frd(path: Path) -> FrdResults:
    """Reads the nodes (2C), elements (3C) and every DISP block of a
    frequency step from CalculiX's ASCII .frd (fixed columns, as ccx writes
    them: numbers may touch, `2.5E-02-1.2E-03`)."""
    lines = path.read_text().splitlines()
    nodes: dict[int, tuple[float, float, float]] = {}
    elements: dict[int, tuple[int, list[int]]] = {}
    modes: list[FrdMode] = []
    generalized_mass = 1.0
    mode_number: int | None = None
    i = 0

    def where(k: int) -> str:
        return f"{path}:{k + 1}"

    try:
        while i < len(lines):
            line = lines[i]
            key = line[:6].strip()
            if key == "2C":
                i += 1
                while lines[i].startswith(" -1"):
                    row = lines[i]
                    nodes[int(row[3:13])] = (_fixed_float(row, 13), _fixed_float(row, 25), _fixed_float(row, 37))
                    i += 1
                continue
            if key == "3C":
                i += 1
                while lines[i].startswith(" -1"):
                    head = lines[i].split()
                    number, kind = int(head[1]), int(head[2])
                    members: list[int] = []
                    i += 1
                    while lines[i].startswith(" -2"):
                        members += [int(x) for x in lines[i][3:].split()]
                        i += 1
                    if kind in NODES_PER_TYPE and len(members) != NODES_PER_TYPE[kind]:
                        raise ConversionError(f"{where(i)}: element {number} has {len(members)} nodes; "
                                              f"a {FRD_TYPE_NAMES[kind]} has {NODES_PER_TYPE[kind]}")
                    elements[number] = (kind, members)
                continue
            if line.startswith("    1PGM"):
                generalized_mass = float(line[8:].split()[0])
            elif line.startswith("    1PMODE"):
                mode_number = int(line[10:].split()[0])
            elif line.startswith("  100CL"):
                # The header of a result block: its value is the frequency
                # (cycles per time unit) in a frequency step, whose blocks follow a 1PMODE line.
                frequency = float(line[12:24])
                block = lines[i + 1].split()
                if mode_number is not None and len(block) >= 2 and block[0] == "-4" and block[1] == "DISP":
                    if mode_number != len(modes) + 1:
                        raise ConversionError(f"{where(i)}: mode {mode_number} follows mode {len(modes)}: "
                                              "convert the results of one *FREQUENCY step")
                    mode = FrdMode(number=mode_number, frequency=frequency, generalized_mass=generalized_mass)
                    i += 2
                    while lines[i].startswith(" -5"):
                        i += 1
                    while lines[i].startswith(" -1"):
                        row = lines[i]
                        mode.shape[int(row[3:13])] = (_fixed_float(row, 13), _fixed_float(row, 25),
                                                      _fixed_float(row, 37))
                        i += 1
                    modes.append(mode)
                    generalized_mass, mode_number = 1.0, None
                    continue
            i += 1
    except IndexError:
        raise ConversionError(f"{path} ends inside a block: is the file whole?") from None
    except ValueError as error:
        raise ConversionError(f"{where(i)}: {error}: not a line CalculiX writes") from None
    if not nodes:
        raise ConversionError(f"{path}: no nodes (no 2C block): is this a CalculiX .frd?")
    if not elements:
        raise ConversionError(f"{path}: no elements (no 3C block)")
    if not modes:
        raise ConversionError(f"{path}: no displacement results: the *FREQUENCY step needs *NODE FILE with U")
    return FrdResults(nodes, elements, modes)


def read_inp_nodes(path: Path) -> dict[int, tuple[float, float, float]]:
    """The *NODE coordinates of a CalculiX deck (and of the files it
    *INCLUDEs), at the precision written there."""
    nodes: dict[int, tuple[float, float, float]] = {}
    in_nodes = False
    for raw in path.read_text().splitlines():
        line = raw.strip()
        if not line or line.startswith("**"):
            continue
        if line.startswith("*"):
            keyword = line.split(",")[0].strip().upper()
            in_nodes = keyword == "*NODE"
            if keyword == "*INCLUDE":
                for part in line.split(",")[1:]:
                    name, _, value = part.partition("=")
                    if name.strip().upper() == "INPUT":
                        nodes.update(read_inp_nodes(path.parent / value.strip()))
            continue
        if in_nodes:
            values = [v for v in line.split(",") if v.strip()]
            coordinates = [float(v) for v in values[1:4]] + [0.0] * (4 - len(values))
            nodes[int(values[0])] = (coordinates[0], coordinates[1], coordinates[2])
    return nodes


_HEX_CORNERS = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                         [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=float)
# The 20-node hexahedron's mid-edge nodes in the .frd's order, which is the
# deck's (C3D20, C3D20R) with its nodes 17–20 (the edges from the bottom face
# to the top) before 13–16 (the top face's edges).
_HEX20_MIDDLES = np.array([[0, -1, -1], [1, 0, -1], [0, 1, -1], [-1, 0, -1],
                           [-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0],
                           [0, -1, 1], [1, 0, 1], [0, 1, 1], [-1, 0, 1]], dtype=float)


def _gauss(points: int):
    """Gauss–Legendre points and weights on [−1, 1]³."""
    x, w = np.polynomial.legendre.leggauss(points)
    return [(np.array([a, b, c]), w[i] * w[j] * w[k])
            for i, a in enumerate(x) for j, b in enumerate(x) for k, c in enumerate(x)]


def _corner_jacobian(corners: np.ndarray, p: np.ndarray) -> float:
    """det ∂x/∂ξ of the trilinear map through the 8 corners (straight edges)."""
    dn = np.empty((8, 3))
    for a in range(3):
        others = [b for b in range(3) if b != a]
        dn[:, a] = _HEX_CORNERS[:, a] * np.prod(1.0 + _HEX_CORNERS[:, others] * p[others], axis=1) / 8.0
    return float(np.linalg.det(dn.T @ corners))


def _hexahedron_shares(x: np.ndarray) -> np.ndarray:
    """Row sums ∫ Nᵢ dV over an 8-node hexahedron: Nᵢ det J is of degree at
    most 3 in each coordinate, which 2 Gauss points integrate exactly."""
    shares = np.zeros(8)
    for p, weight in _gauss(2):
        n = np.prod(1.0 + _HEX_CORNERS * p, axis=1) / 8.0
        shares += weight * n * _corner_jacobian(x, p)
    return shares


def _hexahedron20_shares(x: np.ndarray) -> np.ndarray:
    """A 20-node hexahedron's volume shared in proportion to ∫ Nᵢ² dV, the
    diagonal of its consistent mass (HRZ lumping: its row sums give the
    corners negative mass). Geometry from the corners (straight edges);
    3 Gauss points, exact for a parallelepiped."""
    diagonal = np.zeros(20)
    volume = 0.0
    for p, weight in _gauss(3):
        c = _HEX_CORNERS
        corner = np.prod(1.0 + c * p, axis=1) / 8.0 * (c @ p - 2.0)
        m = _HEX20_MIDDLES
        # 1 − ξ² along the edge's own direction (its zero coordinate), linear across.
        middle = np.prod(np.where(m == 0, 1.0 - p ** 2, 1.0 + m * p), axis=1) / 4.0
        n = np.concatenate([corner, middle])
        jacobian = _corner_jacobian(x[:8], p)
        diagonal += weight * n ** 2 * jacobian
        volume += weight * jacobian
    return volume * diagonal / diagonal.sum()


def _tetrahedron_shares(x: np.ndarray) -> np.ndarray:
    volume = np.linalg.det(x[1:4] - x[0]) / 6.0
    return np.full(4, volume / 4.0)


def _tetrahedron10_shares(x: np.ndarray) -> np.ndarray:
    """HRZ lumping of a straight-edged 10-node tetrahedron: with ∫ L⁴ = V/35,
    ∫ L³ = V/20, ∫ L² = V/10 and ∫ L₁²L₂² = V/210, a corner's ∫ Nᵢ² dV is
    V/70 and a mid-edge node's 8V/105; shared in that proportion, each
    corner gets V/36 and each mid-edge node 4V/27."""
    volume = np.linalg.det(x[1:4] - x[0]) / 6.0
    return volume * np.array([1 / 36] * 4 + [4 / 27] * 6)


# How each element type's volume is shared among its nodes (the .frd's types).
_SHARES = {HEXAHEDRON: _hexahedron_shares, TETRAHEDRON: _tetrahedron_shares,
           HEXAHEDRON20: _hexahedron20_shares, TETRAHEDRON10: _tetrahedron10_shares}


def lumped_masses(nodes: dict[int, tuple[float, float, float]], elements: dict[int, tuple[int, list[int]]],
                  density: float) -> dict[int, float]:
    """Each node's share of the mass, summed over the elements around it:
    for linear elements the row sums ρ ∫ Nᵢ dV of their consistent mass
    matrices, for quadratic ones their diagonals scaled to the element's
    mass (HRZ)."""
    mass: dict[int, float] = {}
    for number, (kind, members) in elements.items():
        if kind not in _SHARES:
            name = FRD_TYPE_NAMES.get(kind, f"type {kind}")
            raise ConversionError(f"element {number} ({name}): the converter lumps the mass of solid "
                                  "hexahedra (C3D8, C3D8R, C3D8I, C3D20, C3D20R) and tetrahedra (C3D4, C3D10) only "
                                  "(shells and beams: write them as ccx expands them, *NODE FILE without OUTPUT=2D)")
        shares = _SHARES[kind](np.array([nodes[n] for n in members]))
        if np.any(shares <= 0.0):
            raise ConversionError(f"element {number} is inverted or degenerate (a node's share of its volume "
                                  f"is {shares.min():.3e})")
        for n, share in zip(members, shares):
            mass[n] = mass.get(n, 0.0) + density * share
    return mass


@dataclass
class Conversion:
    """The modal file and what the Ritz step changed."""

    modal_file: dict
    fe_frequencies: np.ndarray  # Hz, of the chosen FE modes
    frequencies: np.ndarray  # Hz, in the lumped mass
    # Each FE mode's modal mass in the lumped masses over its own (generalized) mass.
    modal_mass_ratios: np.ndarray

    def report(self) -> str:
        rows = ["mode  FE (Hz)        lumped (Hz)    shift       FE mode's modal mass, lumped/FE"]
        for k, (fe, lumped, ratio) in enumerate(zip(self.fe_frequencies, self.frequencies, self.modal_mass_ratios)):
            rows.append(f"{k + 1:<5} {fe:<14.6g} {lumped:<14.6g} {100 * (lumped / fe - 1):+7.3f} %   {ratio:.4g}")
        return "\n".join(rows)

    def warnings(self) -> list[str]:
        """FE modes that the lumped masses weigh far from their own modal
        mass: node-to-node oscillations of a mesh too coarse (or of spurious
        modes) that a consistent mass hides."""
        return [f"FE mode {k + 1} has {ratio:.3g} times its modal mass in the lumped masses: the mesh is too "
                "coarse for lumped masses, or the mode is spurious (refine the mesh)"
                for k, ratio in enumerate(self.modal_mass_ratios) if not 0.5 <= ratio <= 2.0]


def body_frame(origin: list[float] | None, axes: list[float] | None) -> tuple[np.ndarray, np.ndarray]:
    """The FE coordinates' origin of the body frame and the rotation A whose
    rows are the body axes in FE coordinates: r_body = A (r_FE − origin)."""
    o = np.zeros(3) if origin is None else np.asarray(origin, dtype=float)
    a = np.eye(3) if axes is None else np.asarray(axes, dtype=float).reshape(3, 3)
    if np.abs(a @ a.T - np.eye(3)).max() > 1e-9 or np.linalg.det(a) < 0:
        raise ConversionError(f"--axes {axes} are not three orthonormal right-handed axes (to 1e-9)")
    return o, a


def convert(results: FrdResults, density: float, *, coordinates: dict[int, tuple[float, float, float]] | None = None,
            modes: int | None = None, max_frequency: float | None = None, damping: list[float] | None = None,
            origin: list[float] | None = None, axes: list[float] | None = None,
            units: tuple[str, str] = ("m", "kg")) -> Conversion:
    """The modal file of the FE modes chosen by count and/or frequency."""
    if not density > 0:
        raise ConversionError(f"--density is {density}; it must be positive")
    chosen = results.modes
    if max_frequency is not None:
        chosen = [m for m in chosen if m.frequency <= max_frequency]
    if modes is not None:
        if modes > len(chosen):
            raise ConversionError(f"--modes {modes}: the results hold {len(chosen)} such modes")
        chosen = chosen[:modes]
    if not chosen:
        raise ConversionError("no mode is chosen (--modes, --max-frequency)")
    damping = [0.0] if damping is None else damping
    if len(damping) == 1:
        damping = damping * len(chosen)
    if len(damping) != len(chosen):
        raise ConversionError(f"--damping has {len(damping)} values; give one, or one per mode ({len(chosen)})")
    if any(not z >= 0 for z in damping):
        raise ConversionError(f"--damping {damping}: damping ratios cannot be negative")

    xyz = dict(results.nodes)
    if coordinates is not None:
        # Nodes the deck lacks are ccx's own: those it adds to expand shells
        # and beams into solids, written to the .frd only.
        xyz.update({n: coordinates[n] for n in xyz if n in coordinates})
    mass_of = lumped_masses(xyz, results.elements, density)
    # The nodes that carry mass, in the FE's numbering (nodes of no element are left out).
    numbers = sorted(mass_of)
    mass = np.array([mass_of[n] for n in numbers])
    for mode in chosen:
        missing = [n for n in numbers if n not in mode.shape]
        if missing:
            raise ConversionError(f"mode {mode.number} has no displacement at node {missing[0]}")
    phi = np.array([[mode.shape[n] for n in numbers] for mode in chosen])  # modes × nodes × 3

    # The Ritz step: K_r = diag(ω² g), M_r = Φᵀ M_lumped Φ, solved as a
    # standard problem through M_r's Cholesky factor.
    omega2 = np.array([(2 * math.pi * m.frequency) ** 2 * m.generalized_mass for m in chosen])
    m_r = np.einsum("inc,n,jnc->ij", phi, mass, phi)
    chol = np.linalg.cholesky(m_r)
    chol_inv = np.linalg.inv(chol)
    eigenvalues, vectors = np.linalg.eigh(chol_inv @ np.diag(omega2) @ chol_inv.T)
    q = chol_inv.T @ vectors  # qᵀ M_r q = I
    shapes = np.einsum("ik,inc->knc", q, phi)
    # Each mode's sign: its largest displacement positive, so that a rerun gives the same file.
    for k in range(len(shapes)):
        flat = shapes[k].ravel()
        if flat[np.argmax(np.abs(flat))] < 0:
            shapes[k] = -shapes[k]

    o, a = body_frame(origin, axes)
    positions = (np.array([xyz[n] for n in numbers]) - o) @ a.T
    shapes = shapes @ a.T
    frequencies = np.sqrt(eigenvalues) / (2 * math.pi)
    modal_file = {
        "format": FORMAT,
        "version": VERSION,
        "units": {"length": units[0], "mass": units[1], "frequency": "Hz"},
        "mass_normalized": True,
        "nodes": [{"name": f"n{n}", "position": [float(v) for v in p], "mass": float(m)}
                  for n, p, m in zip(numbers, positions, mass)],
        "modes": [{"frequency": float(f), "damping_ratio": float(z),
                   "shape": [[float(s[0]), float(s[1]), float(s[2]), 0.0, 0.0, 0.0] for s in shape]}
                  for f, z, shape in zip(frequencies, damping, shapes)],
    }
    ratios = np.diag(m_r) / np.array([m.generalized_mass for m in chosen])
    return Conversion(modal_file, np.array([m.frequency for m in chosen]), frequencies, ratios)


def layout(modal_file: dict) -> str:
    """The file as JSON a person can read: a line per node, and per node of a
    mode's shape (numbers in full: nudyn checks orthogonality to 1e-6)."""
    head = {k: v for k, v in modal_file.items() if k not in ("nodes", "modes")}
    lines = ["{"] + [f" {json.dumps(k)}: {json.dumps(v)}," for k, v in head.items()]
    lines.append(' "nodes": [')
    lines += [f"  {json.dumps(node)}," for node in modal_file["nodes"]]
    lines[-1] = lines[-1].rstrip(",")
    lines.append(" ],")
    lines.append(' "modes": [')
    for mode in modal_file["modes"]:
        lines.append(f'  {{"frequency": {json.dumps(mode["frequency"])}, '
                     f'"damping_ratio": {json.dumps(mode["damping_ratio"])}, "shape": [')
        lines += [f"   {json.dumps(row)}," for row in mode["shape"]]
        lines[-1] = lines[-1].rstrip(",")
        lines.append("  ]},")
    lines[-1] = lines[-1].rstrip(",")
    lines.append(" ]")
    lines.append("}")
    return "\n".join(lines) + "\n"


def _numbers(text: str) -> list[float]:
    return [float(v) for v in text.replace(",", " ").split()]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m nudyn_validation.calculix",
        description="Convert a CalculiX *FREQUENCY step's results (.frd) to nudyn's modal data file "
                    "(docs/flexible.md): masses lumped at the nodes, the modes solved again in that mass.")
    parser.add_argument("frd", type=Path, help="the .frd of the *FREQUENCY step (with *NODE FILE U)")
    parser.add_argument("-o", "--output", type=Path, required=True, help="the modal file to write (JSON)")
    parser.add_argument("--density", type=float, required=True,
                        help="the material's density, in the deck's units (one material)")
    parser.add_argument("--inp", type=Path,
                        help="the deck, whose *NODE coordinates are read at full precision (the .frd's for the "
                             "nodes ccx adds)")
    parser.add_argument("--modes", type=int, help="keep the first N modes (after --max-frequency)")
    parser.add_argument("--max-frequency", type=float, help="keep the modes up to this frequency (Hz)")
    parser.add_argument("--damping", type=_numbers, default=[0.0],
                        help="damping ratio: one value, or one per kept mode (comma-separated); default 0")
    parser.add_argument("--origin", type=_numbers, help="the body frame's origin in FE coordinates (x,y,z)")
    parser.add_argument("--axes", type=_numbers,
                        help="the body frame's x, y and z axes in FE coordinates (9 values, axis by axis)")
    parser.add_argument("--length-unit", default="m", choices=["m", "cm", "mm"], help="the deck's length unit")
    parser.add_argument("--mass-unit", default="kg", choices=["kg", "g", "t"], help="the deck's mass unit")
    args = parser.parse_args(argv)
    try:
        if args.origin is not None and len(args.origin) != 3:
            raise ConversionError(f"--origin has {len(args.origin)} values; it takes 3")
        if args.axes is not None and len(args.axes) != 9:
            raise ConversionError(f"--axes has {len(args.axes)} values; it takes 9")
        results = read_frd(args.frd)
        coordinates = read_inp_nodes(args.inp) if args.inp else None
        conversion = convert(results, args.density, coordinates=coordinates, modes=args.modes,
                             max_frequency=args.max_frequency, damping=args.damping, origin=args.origin,
                             axes=args.axes, units=(args.length_unit, args.mass_unit))
    except (ConversionError, OSError, ValueError) as error:
        print(f"nudyn_validation.calculix: error: {error}", file=sys.stderr)
        return 2
    args.output.write_text(layout(conversion.modal_file))
    total = sum(n["mass"] for n in conversion.modal_file["nodes"])
    print(f"{args.output}: {len(conversion.modal_file['nodes'])} nodes, {total:.6g} {args.mass_unit}, "
          f"{len(conversion.frequencies)} modes (frequencies in the lumped mass against the FE's):")
    print(conversion.report())
    for warning in conversion.warnings():
        print(f"nudyn_validation.calculix: warning: {warning}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
