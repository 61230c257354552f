"""A flexible boom as a lumped chain and as a modal body (docs/flexible.md,
"Against a lumped chain"; issue 49).

The chain: n rigid rods in a row on a free bus, each on a hinge about z
with a torsion spring. Its constrained modes at rest come from MuJoCo's own
mass matrix (the hinges' block, the bus held) and the springs' stiffness;
the nodes are the rods (mass and rotary inertia at their centres), and a
mode's shape at a node is what the hinge angles of that mode do to the rod
to first order. The modal body written with all n modes is the same boom
for nudyn. Both are run from the same state: the bus turning, the boom
bent in its first mode; nudyn's modal model lacks only terms of second
order in the bending (and the geometric stiffening of the turn, first
order in the bending times the turn's rate squared).

    python -m nudyn_validation.lumped_chain NUDYN [--spin 0.01] [--stiffness 2000]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

BUS = '<inertial pos="0 0 0" mass="100" diaginertia="10 12 14"/>'
FREE_BUS = f"<freejoint/>{BUS}"


@dataclass(frozen=True)
class Boom:
    links: int = 4
    length: float = 0.5
    mass: float = 1.0
    stiffness: float = 2000.0
    # What carries the boom: the joint and inertial of the body named "bus",
    # and where along its x axis the first hinge sits.
    carrier: str = FREE_BUS
    root: float = 0.5
    # The content of an <actuator> element both models carry (none: "").
    actuators: str = ""

    @property
    def rod_inertia(self) -> list[float]:
        """A thin rod's principal moments about its centre (x along the rod)."""
        transverse = self.mass * self.length**2 / 12
        return [1e-3, transverse, transverse]

    @property
    def actuator_element(self) -> str:
        return f"<actuator>{self.actuators}</actuator>" if self.actuators else ""

    def chain_mjcf(self) -> str:
        i_xx, i_yy, i_zz = self.rod_inertia
        inner = ""
        for k in reversed(range(self.links)):
            pos = f"{self.root} 0 0" if k == 0 else f"{self.length} 0 0"
            inner = (
                f'<body name="link{k}" pos="{pos}">'
                f'<joint name="hinge{k}" type="hinge" axis="0 0 1" stiffness="{self.stiffness}"/>'
                f'<inertial pos="{self.length / 2} 0 0" mass="{self.mass}" diaginertia="{i_xx} {i_yy} {i_zz}"/>'
                f"{inner}</body>"
            )
        return (
            '<mujoco model="lumped_chain"><option gravity="0 0 0" integrator="RK4" timestep="1e-4"/>'
            f'<worldbody><body name="bus">{self.carrier}{inner}</body></worldbody>{self.actuator_element}</mujoco>'
        )

    def flexible_mjcf(self, modal_file: str) -> str:
        """The bus with the boom as one body, made flexible by `modal_file`;
        its inertial is the rods'."""
        i_xx, _, i_zz = self.rod_inertia
        mass, centre = self.links * self.mass, self.links * self.length / 2
        bending = sum(i_zz + self.mass * (self.length * (k + 0.5) - centre) ** 2 for k in range(self.links))
        return (
            '<mujoco model="modal_boom"><option gravity="0 0 0"/>'
            f'<custom><text name="nudyn:modal:boom" data="{modal_file}"/></custom>'
            f'<worldbody><body name="bus">{self.carrier}<body name="boom" pos="{self.root} 0 0">'
            f'<inertial pos="{centre} 0 0" mass="{mass}" fullinertia="{self.links * i_xx} {bending} {bending} 0 0 0"/>'
            f"</body></body></worldbody>{self.actuator_element}</mujoco>"
        )

    def modes(self, chain: mujoco.MjModel) -> np.ndarray:
        """The constrained modes in hinge angles, mass-normalized (columns),
        and their ω² — from MuJoCo's mass matrix at rest, the bus held (the
        hinges are the last `links` degrees of freedom)."""
        data = mujoco.MjData(chain)
        mujoco.mj_forward(chain, data)
        full = np.zeros((chain.nv, chain.nv))
        mujoco.mj_fullM(chain, data, full)
        factor_inverse = np.linalg.inv(np.linalg.cholesky(full[-self.links:, -self.links:]))
        squares, vectors = np.linalg.eigh(factor_inverse @ (self.stiffness * np.eye(self.links)) @ factor_inverse.T)
        return factor_inverse.T @ vectors, squares

    def modal_file(self, shapes: np.ndarray, squares: np.ndarray) -> dict:
        """The modal body: a node per rod, each mode (a column of `shapes`)
        at it to first order in the hinge angles (a turn Σθ about z, a
        displacement along y)."""
        centres = [self.length * (k + 0.5) for k in range(self.links)]
        hinges = [self.length * k for k in range(self.links)]
        nodes = [
            {"name": f"rod{k}", "position": [centres[k], 0, 0], "mass": self.mass,
             "rotary_inertia": self.rod_inertia + [0, 0, 0]}
            for k in range(self.links)
        ]
        modes = []
        for mode in range(shapes.shape[1]):
            shape = []
            for node in range(self.links):
                turn = sum(shapes[h, mode] for h in range(node + 1))
                along_y = sum(shapes[h, mode] * (centres[node] - hinges[h]) for h in range(node + 1))
                shape.append([0, along_y, 0, 0, 0, turn])
            modes.append({"frequency": float(np.sqrt(squares[mode])), "damping_ratio": 0.0, "shape": shape})
        return {"format": "nudyn-modal", "version": 1, "units": {"length": "m", "mass": "kg", "frequency": "rad/s"},
                "mass_normalized": True, "nodes": nodes, "modes": modes}


def compare(nudyn: Path, boom: Boom, amplitudes, spin: float, stop: float = 10.0) -> list[dict]:
    """Per amplitude (the largest hinge angle of the first mode at the
    start): the largest difference at `stop` in the bus's qpos and in the
    hinge angles, MuJoCo's chain against nudyn's modal body (RK4 at 1e-4 s
    on both sides, the bus turning at `spin` rad/s about z)."""
    chain = mujoco.MjModel.from_xml_string(boom.chain_mjcf())
    shapes, squares = boom.modes(chain)
    mass = np.linalg.inv(shapes @ shapes.T)  # the hinges' mass matrix, Φ⁻ᵀΦ⁻¹
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        (folder / "boom.json").write_text(json.dumps(boom.modal_file(shapes, squares)))
        (folder / "boom.xml").write_text(boom.flexible_mjcf("boom.json"))
        for amplitude in amplitudes:
            bend = amplitude * shapes[:, 0] / np.abs(shapes[:, 0]).max()
            data = mujoco.MjData(chain)
            data.qpos[7:], data.qvel[5] = bend, spin
            for _ in range(round(stop / chain.opt.timestep)):
                mujoco.mj_step(chain, data)
            theta = [0, 0, 0, 1, 0, 0, 0] + list(shapes.T @ mass @ bend)
            qvel = [0, 0, 0, 0, 0, spin] + [0] * boom.links

            def run(*arguments, request):
                out = subprocess.run([str(nudyn), *arguments], input=json.dumps(request), capture_output=True,
                                     text=True, check=True)
                return json.loads(out.stdout)

            nu = run("eval", folder / "boom.xml", request={"theta": theta, "qvel": qvel})["nu"]
            end = run("simulate", folder / "boom.xml", "--step", str(stop), "--stop", str(stop), "--method", "rk4",
                      "--max-step", "1e-4", request={"theta": theta, "nu": nu})["theta"][-1]
            rows.append({
                "amplitude": amplitude,
                "bus": float(np.abs(np.array(end[:7]) - data.qpos[:7]).max()),
                "hinges": float(np.abs(shapes @ np.array(end[7:]) - data.qpos[7:]).max()),
            })
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("nudyn", type=Path)
    parser.add_argument("--spin", type=float, default=0.01)
    parser.add_argument("--stiffness", type=float, default=Boom.stiffness)
    args = parser.parse_args()
    rows = compare(args.nudyn, Boom(stiffness=args.stiffness), [1e-2, 1e-3, 1e-4], args.spin)
    print("| amplitude (rad) | bus qpos difference | hinge angle difference |")
    print("|---|---|---|")
    for row in rows:
        print(f"| {row['amplitude']:.0e} | {row['bus']:.2e} | {row['hinges']:.2e} |")


if __name__ == "__main__":
    main()
