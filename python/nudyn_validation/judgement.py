"""Whether a trajectory comparison agrees, judged against MuJoCo's own
sensitivity.

Two RK4 runs that start 1e-13 apart separate as fast as the motion
amplifies a perturbation at that step.  nudyn and MuJoCo round differently
from the first step on, so on a chaotic or stiff-for-the-step model they
separate like MuJoCo's "twin": the same run with every qvel component
moved by TWIN_NUDGE.  One nudge may happen to lie where the motion
amplifies little (the divergence of a chaotic humanoid's twin varied 6×
between draws), so there are TWINS of them, with the nudge's signs
drawn differently, and the twin divergence is the largest.  The verdict:

  agrees               error ≤ tolerance;
  chaotic at this step tolerance < error ≤ TWIN_FACTOR × twin divergence:
                       MuJoCo cannot hold its own run to the tolerance either,
                       and nudyn stays as close to it as a 1e-13 nudge does
                       (within a factor TWIN_FACTOR);
  disagrees            otherwise.

A pass is max(tolerance, TWIN_FACTOR × twin) ≥ error, issue 33's bar; the
verdict tells the two kinds of pass apart.  A smaller step (or a shorter
run) turns a chaotic model into one that agrees; a disagreeing one stays.
"""

from __future__ import annotations

import numpy as np

# How far MuJoCo's twin starts from the run compared: every qvel component
# moved by this much (m/s or rad/s).
TWIN_NUDGE = 1e-13
# How many twins: the first moves every component up, the second down, the
# others by signs drawn at random.
TWINS = 3
# How much farther than the twin nudyn may end and still count as chaotic.
TWIN_FACTOR = 10.0

AGREES = "agrees"
CHAOTIC = "chaotic at this step"
DISAGREES = "disagrees"
VERDICTS = (AGREES, CHAOTIC, DISAGREES)


def judge(error: float, twin_divergence: float, tolerance: float) -> str:
    """The verdict on a trajectory whose largest error is `error`, where
    MuJoCo's twin diverged by `twin_divergence` (same norm, same run)."""
    if error <= tolerance:
        return AGREES
    if error <= TWIN_FACTOR * twin_divergence:
        return CHAOTIC
    return DISAGREES


def twin_nudges(nv: int, seed: int, count: int = TWINS) -> list[np.ndarray]:
    """The qvel offsets of `count` twins (see TWINS)."""
    rng = np.random.default_rng([seed, 13])
    signs = [np.ones(nv), -np.ones(nv)] + [rng.choice([-1.0, 1.0], nv) for _ in range(count - 2)]
    return [TWIN_NUDGE * s for s in signs[:count]]


def passes(verdict: str) -> bool:
    """Whether a verdict is within issue 33's bar, max(tolerance, 10 × twin)."""
    return verdict in (AGREES, CHAOTIC)
