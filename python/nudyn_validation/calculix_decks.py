"""CalculiX decks of boxes meshed on structured grids: the converter's
tests and the flexible example vehicle (python -m
nudyn_validation.flexible_example) mesh their beams and plates with it."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np

# Kuhn's six tetrahedra of a cube, as paths from corner (0, 0, 0) to (1, 1, 1)
# along the axes in each order: they meet face to face across a structured grid.
KUHN_PATHS = [(0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)]


def write_box_deck(path: Path, size, divisions, *, young, poisson, density, modes, element="C3D8I", scale=1.0):
    """A CalculiX deck of a box [0, size] meshed on a grid of divisions,
    clamped on its face x = 0, with a *FREQUENCY step writing the modes'
    displacements. Elements: C3D8I (8-node hexahedra with incompatible
    modes, good in bending with one element through the thickness), C3D20R
    (20-node hexahedra) or C3D10 (10-node tetrahedra, six per grid cell).
    Lengths are written times `scale` (1000 for a deck in mm)."""
    nx, ny, nz = divisions

    # Nodes on a grid of half cells, so that mid-edge nodes have indices too.
    def node(i, j, k):
        return 1 + i + (2 * nx + 1) * (j + (2 * ny + 1) * k)

    def middle(a, b):
        return node(*[(p + q) // 2 for p, q in zip(a, b)])

    elements = []
    for i, j, k in np.ndindex(nx, ny, nz):
        cube = [(2 * (i + di), 2 * (j + dj), 2 * (k + dk))
                for dk in (0, 1) for dj, di in ((0, 0), (0, 1), (1, 1), (1, 0))]  # CalculiX's corner order
        if element == "C3D8I":
            elements.append([node(*c) for c in cube])
        elif element == "C3D20R":
            edges = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7)]
            elements.append([node(*c) for c in cube] + [middle(cube[a], cube[b]) for a, b in edges])
        elif element == "C3D10":
            for axes in KUHN_PATHS:
                corner = [2 * i, 2 * j, 2 * k]
                corners = [tuple(corner)]
                for axis in axes:
                    corner[axis] += 2
                    corners.append(tuple(corner))
                if np.linalg.det(np.subtract(corners[1:], corners[0])) < 0:
                    corners[1], corners[2] = corners[2], corners[1]
                edges = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]
                elements.append([node(*c) for c in corners] + [middle(corners[a], corners[b]) for a, b in edges])
    used = sorted({n for members in elements for n in members})
    lines = ["*NODE, NSET=NALL"]
    for n in used:
        i, rest = (n - 1) % (2 * nx + 1), (n - 1) // (2 * nx + 1)
        j, k = rest % (2 * ny + 1), rest // (2 * ny + 1)
        x = [scale * size[0] * i / (2 * nx), scale * size[1] * j / (2 * ny), scale * size[2] * k / (2 * nz)]
        lines.append(f"{n}, {x[0]!r}, {x[1]!r}, {x[2]!r}")
    lines.append(f"*ELEMENT, TYPE={element}, ELSET=EALL")
    for number, members in enumerate(elements, start=1):
        # At most 16 numbers on a line of the deck; the rest continue on the next.
        lines.append(f"{number}, " + ", ".join(map(str, members[:15])) + ("," if len(members) > 15 else ""))
        if len(members) > 15:
            lines.append(", ".join(map(str, members[15:])))
    clamped = [n for n in used if (n - 1) % (2 * nx + 1) == 0]
    lines.append("*NSET, NSET=CLAMPED")
    lines += [f"{n}," for n in clamped]
    lines += ["*BOUNDARY", "CLAMPED, 1, 3",
              "*MATERIAL, NAME=MATERIAL", "*ELASTIC", f"{young!r}, {poisson!r}", "*DENSITY", f"{density!r}",
              "*SOLID SECTION, ELSET=EALL, MATERIAL=MATERIAL",
              "*STEP", "*FREQUENCY", str(modes), "*NODE FILE", "U", "*END STEP"]
    path.write_text("\n".join(lines) + "\n")


def run_ccx(ccx: str, deck: Path, timeout: float = 120) -> Path:
    """Runs CalculiX on `deck` in its folder; the .frd it writes. Raises
    RuntimeError with ccx's output when it fails."""
    proc = subprocess.run([ccx, deck.stem], cwd=deck.parent, capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0 or "ERROR" in proc.stdout:
        raise RuntimeError(f"ccx failed on {deck.name}: {proc.stdout[-2000:]}{proc.stderr}")
    return deck.with_suffix(".frd")
