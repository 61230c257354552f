"""The flexible example vehicle (examples/flexible_spacecraft/, issue 49,
item 6): a bus with two solar arrays, each on a drive hinge, and a boom,
the three appendages flexible, their modal files made by CalculiX and the
converter from meshes this module writes.

    python -m nudyn_validation.flexible_example OUT_FOLDER --nudyn NUDYN

writes OUT_FOLDER/flexible_spacecraft.xml, array.json and boom.json (the
files in examples/ are its output; tests/python/test_flexible_example.py
makes them again and compares). The arrays are aluminium-like plates of
2 m × 1 m × 5 mm at 1000 kg/m³ (10 kg, first mode about 1 Hz), the boom a
3 m bar of 30 mm × 20 mm (1.8 kg, first modes about 3 and 4.5 Hz), each clamped at
its root, 4 modes kept, 0.5 % damping. The same file loads in MuJoCo as
the rigid vehicle.

`lumped_equivalent` writes the vehicle MuJoCo compares in cost: each
appendage a chain of as many hinged links as it has modes, so that both
have the same number of degrees of freedom.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from .calculix_decks import run_ccx, write_box_deck

YOUNG, POISSON, DENSITY = 70e9, 0.3, 1000.0
MODES, DAMPING = 4, 0.005


@dataclass(frozen=True)
class Appendage:
    name: str
    size: tuple[float, float, float]
    divisions: tuple[int, int, int]
    # The body frame in FE coordinates: origin at the middle of the clamped
    # face, axes (body x, y, z) as FE vectors.
    origin: tuple[float, float, float]
    axes: tuple[float, ...]


# The array's length along body y (out from the bus), its width along body
# x, its normal along body −z; the boom's length along body x.
ARRAY = Appendage("array", (2.0, 1.0, 0.005), (12, 6, 1), (0.0, 0.5, 0.0025), (0, 1, 0, 1, 0, 0, 0, 0, -1))
# The boom's section is not square, so that no two of its modes share a
# frequency (a repeated frequency's mode shapes are any basis of their plane).
BOOM = Appendage("boom", (3.0, 0.03, 0.02), (24, 1, 1), (0.0, 0.015, 0.01), (1, 0, 0, 0, 1, 0, 0, 0, 1))

BUS = '<inertial pos="0 0 0" mass="800" diaginertia="180 200 220"/>'


def modal_file(appendage: Appendage, folder: Path, ccx: str) -> Path:
    """Meshes, solves and converts one appendage; returns its modal file in `folder`."""
    with tempfile.TemporaryDirectory() as work:
        deck = Path(work) / f"{appendage.name}.inp"
        write_box_deck(deck, appendage.size, appendage.divisions, young=YOUNG, poisson=POISSON, density=DENSITY,
                       modes=2 * MODES)
        frd = run_ccx(ccx, deck, timeout=300)
        output = folder / f"{appendage.name}.json"
        command = [sys.executable, "-m", "nudyn_validation.calculix", str(frd), "-o",
                   str(output), "--inp", str(deck), "--density", str(DENSITY), "--modes", str(MODES),
                   "--damping", str(DAMPING), "--origin", ",".join(map(str, appendage.origin)),
                   "--axes", ",".join(map(str, appendage.axes))]
        proc = subprocess.run(command, capture_output=True, text=True, timeout=300)
        if proc.returncode != 0:
            raise RuntimeError(f"the converter failed on {deck.name}: {proc.stderr}")
    return output


def inertial(nudyn: Path, path: Path) -> str:
    """The `<inertial>` that `nudyn modal` gives for a modal file."""
    table = subprocess.run([str(nudyn), "modal", str(path)], capture_output=True, text=True, check=True).stdout
    return next(line.strip() for line in table.splitlines() if line.strip().startswith("<inertial "))


def mjcf(array_inertial: str, boom_inertial: str) -> str:
    return f"""<mujoco model="flexible_spacecraft">
  <!-- A bus with two flexible solar arrays on drive hinges and a flexible
       boom (docs/flexible.md). Written by python -m
       nudyn_validation.flexible_example; the modal files by CalculiX and
       python -m nudyn_validation.calculix. MuJoCo ignores the <text>
       elements and loads the rigid vehicle. -->
  <option gravity="0 0 0" timestep="0.001"/>
  <custom>
    <text name="nudyn:modal:array_left" data="array.json"/>
    <text name="nudyn:modal:array_right" data="array.json"/>
    <text name="nudyn:modal:boom" data="boom.json"/>
  </custom>
  <worldbody>
    <body name="bus">
      <freejoint name="bus"/>
      {BUS}
      <body name="array_left" pos="0 0.6 0">
        <joint name="drive_left" type="hinge" axis="0 1 0"/>
        {array_inertial}
      </body>
      <body name="array_right" pos="0 -0.6 0" quat="0 0 0 1">
        <joint name="drive_right" type="hinge" axis="0 1 0"/>
        {array_inertial}
      </body>
      <body name="boom" pos="0.6 0 0">
        {boom_inertial}
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="drive_left" joint="drive_left"/>
    <motor name="drive_right" joint="drive_right"/>
  </actuator>
</mujoco>
"""


def write_example(folder: Path, nudyn: Path, ccx: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    array, boom = modal_file(ARRAY, folder, ccx), modal_file(BOOM, folder, ccx)
    path = folder / "flexible_spacecraft.xml"
    path.write_text(mjcf(inertial(nudyn, array), inertial(nudyn, boom)))
    return path


def _chain(name: str, links: int, length: float, mass: float, axis: str, inner_pos: str) -> str:
    """A chain of `links` rods of total `length` and `mass` along body x, hinged about `axis`."""
    piece, piece_mass = length / links, mass / links
    transverse = piece_mass * piece**2 / 12
    inner = ""
    for k in reversed(range(links)):
        pos = inner_pos if k == 0 else f"{piece} 0 0"
        inner = (f'<body name="{name}{k}" pos="{pos}"><joint name="{name}_bend{k}" axis="{axis}" stiffness="1000"/>'
                 f'<inertial pos="{piece / 2} 0 0" mass="{piece_mass}" diaginertia="1e-3 {transverse} {transverse}"/>'
                 f"{inner}</body>")
    return inner


def lumped_equivalent(example: dict[str, int]) -> str:
    """The example's degrees of freedom as rigid links for MuJoCo: each
    appendage a chain of `example[name]` hinged rods (for the cost
    comparison only: not the same dynamics)."""
    arrays = "".join(
        f'<body name="array_{side}" pos="0 {y} 0" euler="0 0 {turn}"><joint name="drive_{side}" axis="1 0 0"/>'
        f'<inertial pos="0.1 0 0" mass="0.1" diaginertia="1e-3 1e-3 1e-3"/>'
        f'{_chain(f"array_{side}_", example["array_" + side], 2.0, 10.0, "0 0 1", "0.1 0 0")}</body>'
        for side, y, turn in (("left", 0.6, 1.5707963267948966), ("right", -0.6, -1.5707963267948966)))
    boom = _chain("boom", example["boom"], 3.0, 1.8, "0 1 0", "0.6 0 0")
    return (f'<mujoco model="flexible_spacecraft_lumped"><option gravity="0 0 0"/><worldbody><body name="bus">'
            f"<freejoint/>{BUS}{arrays}{boom}</body></worldbody></mujoco>")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m nudyn_validation.flexible_example", description=__doc__)
    parser.add_argument("folder", type=Path, help="where to write the MJCF and the modal files")
    parser.add_argument("--nudyn", type=Path, required=True, help="the nudyn executable (for `nudyn modal`)")
    args = parser.parse_args(argv)
    ccx = shutil.which("ccx")
    if ccx is None:
        print("nudyn_validation.flexible_example: error: ccx not found (Debian package calculix-ccx)",
              file=sys.stderr)
        return 2
    path = write_example(args.folder, args.nudyn, ccx)
    print(json.dumps({"mjcf": str(path)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
