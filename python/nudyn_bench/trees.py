"""Random six-body trees as MJCF, drawn as the tolerance tests draw theirs
(`random_vehicle` in tests/all/common.rs with a free base, springs,
dampers and gravity): each body on a random earlier one, 0 to 3 joints
(hinge, slide, a ball only last), random placements, box-like inertias of
0.2–5 kg turned at random, armature on half the joints, stiffness 0–5
(none on ball and free joints, whose spring torque jumps where the
rotation passes π) and damping 0–1. numpy draws them, so they are trees of
the same kind, not the tests' very trees."""

from __future__ import annotations

from pathlib import Path

import numpy as np

BODIES = 6


def _unit_quat(rng: np.random.Generator) -> np.ndarray:
    q = rng.uniform(-1.0, 1.0, 4)
    return q / np.linalg.norm(q)


def _unit_vec(rng: np.random.Generator) -> np.ndarray:
    while True:
        v = rng.uniform(-1.0, 1.0, 3)
        if np.linalg.norm(v) > 0.2:
            return v / np.linalg.norm(v)


def _rotation(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def _numbers(values) -> str:
    return " ".join(repr(float(v)) for v in values)


def _inertial(rng: np.random.Generator) -> str:
    mass = rng.uniform(0.2, 5.0)
    a, b, c = rng.uniform(0.02, 0.3, 3)
    diag = np.diag([b * b + c * c, a * a + c * c, a * a + b * b]) * mass / 3.0
    r = _rotation(_unit_quat(rng))
    inertia = r @ diag @ r.T
    full = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]
    return f'<inertial pos="{_numbers(rng.uniform(-0.3, 0.3, 3))}" mass="{mass!r}" fullinertia="{_numbers(full)}"/>'


def _joints(rng: np.random.Generator, b: int) -> list[str]:
    if b == 0:
        return [f'<joint name="j0_free" type="free" damping="{rng.uniform(0.0, 1.0)!r}"/>']
    count = [0, 1, 1, 1, 2, 3][rng.integers(6)]
    joints = []
    for k in range(count):
        kind = ["hinge", "hinge", "slide", "ball", "ball"][rng.integers(5)]
        if kind == "ball" and k + 1 != count:
            kind = "hinge"
        stiffness = 0.0 if kind == "ball" else rng.uniform(0.0, 5.0)
        armature = rng.uniform(0.0, 0.5) if rng.integers(2) == 0 else 0.0
        axis = "" if kind == "ball" else f' axis="{_numbers(_unit_vec(rng))}"'
        joints.append(
            f'<joint name="j{b}_{k}" type="{kind}" pos="{_numbers(rng.uniform(-0.2, 0.2, 3))}"{axis} '
            f'springref="{rng.uniform(-0.5, 0.5)!r}" stiffness="{stiffness!r}" damping="{rng.uniform(0.0, 1.0)!r}" '
            f'armature="{armature!r}"/>'
        )
    return joints


def write_tree(seed: int, path: Path) -> Path:
    """The random tree of `seed` as an MJCF file at `path`."""
    rng = np.random.default_rng(seed)
    parents = [None] + [int(rng.integers(b)) for b in range(1, BODIES)]
    bodies = []
    for b in range(BODIES):
        pos = _numbers(rng.uniform(-0.5, 0.5, 3)) if b else "0 0 0"
        bodies.append((f'<body name="b{b}" pos="{pos}" quat="{_numbers(_unit_quat(rng))}">',
                       [_inertial(rng), *_joints(rng, b)]))

    def nested(b: int, depth: int) -> list[str]:
        indent = "  " * depth
        opening, children = bodies[b]
        lines = [indent + opening] + [indent + "  " + c for c in children]
        for child in (c for c in range(BODIES) if parents[c] == b):
            lines += nested(child, depth + 1)
        return lines + [indent + "</body>"]

    text = "\n".join([
        f'<mujoco model="tree{seed}">',
        '  <option gravity="0.3 -0.2 -9.81"/>',
        "  <worldbody>",
        *nested(0, 2),
        "  </worldbody>",
        "</mujoco>",
        "",
    ])
    path.write_text(text)
    return path
