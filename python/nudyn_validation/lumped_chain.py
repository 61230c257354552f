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
order in the bending times the turn's rate squared). With `--panel` both
carry a panel at the boom's tip, on a hinge or welded: the chain on its
last rod's end, the modal body at its node "tip" (docs/flexible.md, "Child
bodies at nodes", "Bodies welded at nodes").

    python -m nudyn_validation.lumped_chain NUDYN [--spin 0.01] [--stiffness 2000] [--panel hinge|weld]
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
    # A panel at the boom's tip (the chain's last rod's end, the modal
    # body's node "tip"): "" none, "hinge" on a hinge with a spring (started
    # at the amplitude of the bending), "weld" welded there.
    panel: str = ""

    @property
    def rod_inertia(self) -> list[float]:
        """A thin rod's principal moments about its centre (x along the rod)."""
        transverse = self.mass * self.length**2 / 12
        return [1e-3, transverse, transverse]

    def panel_body(self, pos: float) -> str:
        """The panel at `pos` along x of what carries it: 2 kg, its centre
        of mass off the boom's plane, on a hinge with a spring whose axis is
        off it too, or welded."""
        if not self.panel:
            return ""
        joint = '<joint name="fold" type="hinge" axis="0 0.6 0.8" stiffness="20"/>' if self.panel == "hinge" else ""
        return (
            f'<body name="panel" pos="{pos} 0 0">{joint}'
            '<inertial pos="0.2 0.05 0" mass="2" diaginertia="0.01 0.03 0.03"/></body>'
        )

    @property
    def actuator_element(self) -> str:
        return f"<actuator>{self.actuators}</actuator>" if self.actuators else ""

    def chain_mjcf(self, with_panel: bool = True) -> str:
        i_xx, i_yy, i_zz = self.rod_inertia
        inner = self.panel_body(self.length) if with_panel else ""
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
            f"{self.panel_body(self.links * self.length)}</body></body></worldbody>{self.actuator_element}</mujoco>"
        )

    def modes(self, chain: mujoco.MjModel) -> np.ndarray:
        """The constrained modes in hinge angles, mass-normalized (columns),
        and their ω² — from MuJoCo's mass matrix at rest, the bus held (the
        hinges are the `links` degrees of freedom after the bus's). `chain`
        is the boom alone: a panel at its tip is a child body of the modal
        body, not part of its modes."""
        data = mujoco.MjData(chain)
        mujoco.mj_forward(chain, data)
        full = np.zeros((chain.nv, chain.nv))
        mujoco.mj_fullM(chain, data, full)
        hinges = slice(chain.nv - self.links, chain.nv)
        factor_inverse = np.linalg.inv(np.linalg.cholesky(full[hinges, hinges]))
        squares, vectors = np.linalg.eigh(factor_inverse @ (self.stiffness * np.eye(self.links)) @ factor_inverse.T)
        return factor_inverse.T @ vectors, squares

    def modal_file(self, shapes: np.ndarray, squares: np.ndarray) -> dict:
        """The modal body: a node per rod, each mode (a column of `shapes`)
        at it to first order in the hinge angles (a turn Σθ about z, a
        displacement along y); with a panel, a massless node "tip" at the
        last rod's end, which the panel hangs from."""
        centres = [self.length * (k + 0.5) for k in range(self.links)]
        hinges = [self.length * k for k in range(self.links)]
        nodes = [
            {"name": f"rod{k}", "position": [centres[k], 0, 0], "mass": self.mass,
             "rotary_inertia": self.rod_inertia + [0, 0, 0]}
            for k in range(self.links)
        ]
        # Each node's position along the boom, and the hinges inboard of it.
        along = [(centres[k], k + 1) for k in range(self.links)]
        if self.panel:
            nodes.append({"name": "tip", "position": [self.links * self.length, 0, 0], "mass": 0.0})
            along.append((self.links * self.length, self.links))
        modes = []
        for mode in range(shapes.shape[1]):
            shape = []
            for x, inboard in along:
                turn = sum(shapes[h, mode] for h in range(inboard))
                along_y = sum(shapes[h, mode] * (x - hinges[h]) for h in range(inboard))
                shape.append([0, along_y, 0, 0, 0, turn])
            modes.append({"frequency": float(np.sqrt(squares[mode])), "damping_ratio": 0.0, "shape": shape})
        return {"format": "nudyn-modal", "version": 1, "units": {"length": "m", "mass": "kg", "frequency": "rad/s"},
                "mass_normalized": True, "nodes": nodes, "modes": modes}


def compare(nudyn: Path, boom: Boom, amplitudes, spin: float, stop: float = 10.0) -> list[dict]:
    """Per amplitude (the largest hinge angle of the first mode at the
    start, and the panel's angle if it has one): the largest difference at
    `stop` in the bus's qpos, in the hinge angles and in the panel's,
    MuJoCo's chain against nudyn's modal body (RK4 at 1e-4 s on both
    sides, the bus turning at `spin` rad/s about z)."""
    chain = mujoco.MjModel.from_xml_string(boom.chain_mjcf())
    shapes, squares = boom.modes(mujoco.MjModel.from_xml_string(boom.chain_mjcf(with_panel=False)))
    mass = np.linalg.inv(shapes @ shapes.T)  # the hinges' mass matrix, Φ⁻ᵀΦ⁻¹
    hinges = slice(7, 7 + boom.links)
    panel = [7 + boom.links] if boom.panel == "hinge" else []
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        (folder / "boom.json").write_text(json.dumps(boom.modal_file(shapes, squares)))
        (folder / "boom.xml").write_text(boom.flexible_mjcf("boom.json"))
        for amplitude in amplitudes:
            bend = amplitude * shapes[:, 0] / np.abs(shapes[:, 0]).max()
            data = mujoco.MjData(chain)
            data.qpos[hinges], data.qpos[panel], data.qvel[5] = bend, amplitude, spin
            for _ in range(round(stop / chain.opt.timestep)):
                mujoco.mj_step(chain, data)
            # nudyn's θ: MuJoCo's qpos of the modal vehicle (the bus, the panel), then η.
            theta = [0, 0, 0, 1, 0, 0, 0] + [amplitude] * len(panel) + list(shapes.T @ mass @ bend)
            qvel = [0, 0, 0, 0, 0, spin] + [0] * (len(panel) + boom.links)

            def run(*arguments, request):
                out = subprocess.run([str(nudyn), *arguments], input=json.dumps(request), capture_output=True,
                                     text=True, check=True)
                return json.loads(out.stdout)

            nu = run("eval", folder / "boom.xml", request={"theta": theta, "qvel": qvel})["nu"]
            end = run("simulate", folder / "boom.xml", "--step", str(stop), "--stop", str(stop), "--method", "rk4",
                      "--max-step", "1e-4", request={"theta": theta, "nu": nu})["theta"][-1]
            eta = np.array(end[7 + len(panel):])
            row = {
                "amplitude": amplitude,
                "bus": float(np.abs(np.array(end[:7]) - data.qpos[:7]).max()),
                "hinges": float(np.abs(shapes @ eta - data.qpos[hinges]).max()),
            }
            if panel:
                row["panel"] = float(abs(end[7] - data.qpos[panel[0]]))
            rows.append(row)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("nudyn", type=Path)
    parser.add_argument("--spin", type=float, default=0.01)
    parser.add_argument("--stiffness", type=float, default=Boom.stiffness)
    parser.add_argument("--panel", choices=["hinge", "weld"], default="", help="a panel at the boom's tip")
    args = parser.parse_args()
    rows = compare(args.nudyn, Boom(stiffness=args.stiffness, panel=args.panel), [1e-2, 1e-3, 1e-4], args.spin)
    hinged = args.panel == "hinge"
    panel = " panel angle difference |" if hinged else ""
    print(f"| amplitude (rad) | bus qpos difference | hinge angle difference |{panel}")
    print("|---|---|---|" + ("---|" if hinged else ""))
    for row in rows:
        panel = f" {row['panel']:.2e} |" if hinged else ""
        print(f"| {row['amplitude']:.0e} | {row['bus']:.2e} | {row['hinges']:.2e} |{panel}")


if __name__ == "__main__":
    main()
