"""The spin-up of a beam on a hub (Kane, Ryan and Banerjee, "Dynamics of a
cantilever beam attached to a moving base", J. Guidance 10(2), 1987;
docs/flexible.md, "Spin-up"; issue 49).

A 10 m beam (EI = 1.4e4 N m², ρA = 1.2 kg/m) clamped to a hub that turns
about an axis normal to it, bending in the plane of the turn. The hub's rate
follows Ω(t) = (Ωs/Ts)(t − (Ts/2π) sin(2πt/Ts)) up to Ts, then Ωs. With Ωs
above the beam's first clamped frequency (3.80 rad/s), a linear modal model
diverges: it has the centrifugal softening of the turn and none of its
geometric stiffening. A chain of hinged rods has both, exactly.

Both sides are built as `lumped_chain` builds its boom: MuJoCo runs a
chain of n rods on hinge springs EI/ℓ; nudyn runs the same hub carrying one
flexible body whose modes are the chain's first constrained modes at rest.
The hub is a hinge with an inertia far above the beam's, driven by the
torque that gives a rigid hub Ω(t) at every communication point, held over
each step on both sides (nudyn through its FMU in FMPy, RK4 on both). The
quantity is the tip's deflection normal to the undeformed beam, in the
hub's frame. A third model, outside nudyn, shows what geometric stiffening
would add (`run_stiffened`).

    python -m nudyn_validation.spinup OUTDIR [--nudyn NUDYN] [--final-rate 6]

writes the models into OUTDIR, a plot spinup.png and the figures in
spinup.json.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import dataclass
from pathlib import Path

import fmpy
import matplotlib
import mujoco
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the backend)

from nudyn_driver.cli import Nudyn  # noqa: E402
from nudyn_driver.locations import nudyn_binary  # noqa: E402

from .lumped_chain import Boom  # noqa: E402

LENGTH = 10.0  # m
BENDING_STIFFNESS = 7e10 * 2e-7  # E I, N m²
MASS_PER_LENGTH = 3000 * 4e-4  # ρ A, kg/m
# The hub's moment of inertia, against the beam's 400 kg m² about the axis:
# the chain's bending moves the hub's rate by 5e-9 rad/s (measured).
HUB_INERTIA = 1e9


@dataclass(frozen=True)
class SpinUp:
    """Ω(t): a smooth ramp from rest to `final_rate` (Ωs, rad/s) over
    `ramp` (Ts, s), then constant."""

    final_rate: float = 6.0
    ramp: float = 15.0

    def rate(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        ramping = self.final_rate / self.ramp * (t - self.ramp / (2 * math.pi) * np.sin(2 * math.pi * t / self.ramp))
        return np.where(t < self.ramp, ramping, self.final_rate)


def beam_as_chain(links: int) -> Boom:
    """The beam as `links` rods on hinge springs EI/ℓ, the first hinge on
    the hub's axis, the hub a hinge about z with a motor."""
    length = LENGTH / links
    hub = (
        '<joint name="hub" type="hinge" axis="0 0 1"/>'
        f'<inertial pos="0 0 0" mass="1" diaginertia="{HUB_INERTIA} {HUB_INERTIA} {HUB_INERTIA}"/>'
    )
    return Boom(links=links, length=length, mass=MASS_PER_LENGTH * length, stiffness=BENDING_STIFFNESS / length,
                carrier=hub, root=0.0, actuators='<motor joint="hub" gear="1"/>')


def tip_lever(boom: Boom) -> np.ndarray:
    """The tip's deflection per hinge angle, to first order: the distance
    from each hinge to the tip."""
    return boom.length * (boom.links - np.arange(boom.links))


def hub_torques(chain: mujoco.MjModel, spin_up: SpinUp, step: float, stop: float) -> np.ndarray:
    """The torque held over each step that takes the rigid vehicle (hub and
    straight beam) from Ω(t_k) to Ω(t_k+1)."""
    data = mujoco.MjData(chain)
    mujoco.mj_forward(chain, data)
    full = np.zeros((chain.nv, chain.nv))
    mujoco.mj_fullM(chain, data, full)
    turning = full[0, 0]  # the hub's: the hub and the straight beam turning as one
    rates = spin_up.rate(np.arange(round(stop / step) + 1) * step)
    return turning * np.diff(rates) / step


def run_chain(boom: Boom, chain: mujoco.MjModel, torques: np.ndarray, step: float, substeps: int) -> dict:
    """MuJoCo's chain (RK4, `substeps` steps per held torque): at every
    communication point the hub's rate and the tip's deflection normal to
    the undeformed beam in the hub's frame (exact: Σ ℓ sin of the rods' angles)."""
    chain.opt.timestep = step / substeps
    data = mujoco.MjData(chain)
    rates, tips = [0.0], [0.0]
    for torque in torques:
        data.ctrl[0] = torque
        for _ in range(substeps):
            mujoco.mj_step(chain, data)
        rates.append(data.qvel[0])
        tips.append(boom.length * np.sin(np.cumsum(data.qpos[1:])).sum())
    return {"hub_rate": np.array(rates), "tip": np.array(tips)}


def run_stiffened(boom: Boom, chain: mujoco.MjModel, shapes: np.ndarray, torques: np.ndarray, step: float,
                  substeps: int) -> dict:
    """What a modal body with geometric stiffening would do, outside nudyn:
    the chain's own equations linearized about the straight beam turning
    at Ω (MuJoCo's hinge accelerations by central differences: the
    stiffness at rest, its part in Ω², the Coriolis part in Ω and the
    response to Ω̇), projected on the same modes, RK4 in Python with the hub
    rate the held torques give a rigid hub (piecewise linear). This is the
    first-order model of Kane, Ryan and Banerjee: the linear modal model
    plus the second-order foreshortening's work, which docs/flexible.md
    describes as the option not built."""
    data, hinges = mujoco.MjData(chain), boom.links

    def hinge_acceleration(angles, rates, hub_rate, hub_torque=0.0):
        data.qpos[:], data.qvel[:] = 0.0, 0.0
        data.qpos[1:], data.qvel[1:], data.qvel[0], data.ctrl[0] = angles, rates, hub_rate, hub_torque
        mujoco.mj_forward(chain, data)
        return data.qacc[1:].copy(), data.qacc[0]

    def jacobians(hub_rate, delta=1e-6):
        unit = np.eye(hinges) * delta
        by_angle = [hinge_acceleration(u, 0, hub_rate)[0] - hinge_acceleration(-u, 0, hub_rate)[0] for u in unit]
        by_rate = [hinge_acceleration(0, u, hub_rate)[0] - hinge_acceleration(0, -u, hub_rate)[0] for u in unit]
        return np.column_stack(by_angle) / (2 * delta), np.column_stack(by_rate) / (2 * delta)

    at_rest, _ = jacobians(0.0)
    turning, coriolis = jacobians(1.0)  # at Ω = 1: the Ω² and Ω parts are the differences from rest
    accelerations, hub = hinge_acceleration(np.zeros(hinges), np.zeros(hinges), 0.0, hub_torque=HUB_INERTIA)
    full = np.zeros((chain.nv, chain.nv))
    mujoco.mj_fullM(chain, data, full)
    project = shapes.T @ full[1:, 1:]  # η of the hinge angles, for mass-normalized modes
    # η̈ per η at rest (−ω² on the diagonal), and the parts of it in Ω² and Ω, and per Ω̇.
    restoring, per_rate_squared = project @ at_rest @ shapes, project @ (turning - at_rest) @ shapes
    per_rate, per_acceleration = project @ coriolis @ shapes, project @ accelerations / hub
    modes, h = shapes.shape[1], step / substeps

    def derivative(state, rate, acceleration):
        eta, eta_dot = state[:modes], state[modes:]
        eta_ddot = ((restoring + rate**2 * per_rate_squared) @ eta + rate * per_rate @ eta_dot
                    + per_acceleration * acceleration)
        return np.concatenate([eta_dot, eta_ddot])

    state, rate, lever = np.zeros(2 * modes), 0.0, shapes.T @ tip_lever(boom)
    turning_inertia = full[0, 0]
    tips = [0.0]
    for torque in torques:
        acceleration = torque / turning_inertia
        for _ in range(substeps):
            k1 = derivative(state, rate, acceleration)
            k2 = derivative(state + h / 2 * k1, rate + h / 2 * acceleration, acceleration)
            k3 = derivative(state + h / 2 * k2, rate + h / 2 * acceleration, acceleration)
            k4 = derivative(state + h * k3, rate + h * acceleration, acceleration)
            state, rate = state + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), rate + h * acceleration
        tips.append(float(lever @ state[:modes]))
    return {"tip": np.array(tips)}


def export_modal(cli: Nudyn, folder: Path, boom: Boom, shapes: np.ndarray, squares: np.ndarray) -> Path:
    """The hub carrying the beam as one flexible body with the modes given
    (columns of `shapes`, in hinge angles): its files in `folder`, its FMU
    (RK4, θ̇ as an output)."""
    (folder / "beam.json").write_text(json.dumps(boom.modal_file(shapes, squares)))
    (folder / "modal_beam.xml").write_text(boom.flexible_mjcf("beam.json"))
    return cli.export(folder / "modal_beam.xml", folder / "modal_beam.fmu", method="rk4", outputs=["qvel"])


def run_modal(fmu: Path, boom: Boom, shapes: np.ndarray, torques: np.ndarray, step: float, substeps: int) -> dict:
    """nudyn's modal body through its FMU in FMPy, the same torques held over
    each communication step (RK4 inside, `substeps` steps each): the hub's
    rate and the tip's deflection, Σ over hinges of (Φη) × the lever."""
    modes = shapes.shape[1]
    # ε (the hub's and the modes') is 0: given, so that FMPy does not warn of it.
    epsilons = [f"eps[{k}]" for k in range(1, modes + 2)]
    signal = np.zeros(len(torques), dtype=[("time", float), ("ctrl[1]", float)] + [(e, float) for e in epsilons])
    signal["time"], signal["ctrl[1]"] = np.arange(len(torques)) * step, torques
    # θ: the hub's angle, then the modes.
    names = ["qvel[1]"] + [f"theta[{k + 2}]" for k in range(modes)]
    result = fmpy.simulate_fmu(fmu, stop_time=len(torques) * step, output_interval=step, input=signal, output=names,
                               start_values={"max_step": step / substeps})
    eta = np.column_stack([result[name] for name in names[1:]])
    return {"hub_rate": result["qvel[1]"], "tip": eta @ shapes.T @ tip_lever(boom)}


def spin_up(cli: Nudyn, folder: Path, links: int, modes: int, final_rates, stop: float, step: float = 0.01,
            substeps: int = 10) -> dict:
    """Both sides for each Ωs of `final_rates` (Ts = 15 s), `stop` seconds
    sampled every `step`: the times, each side's tip deflection and hub
    rate, and Ω(t). The chain's first frequencies are in `frequencies`."""
    boom = beam_as_chain(links)
    chain = mujoco.MjModel.from_xml_string(boom.chain_mjcf())
    shapes, squares = boom.modes(chain)
    fmu = export_modal(cli, folder, boom, shapes[:, :modes], squares[:modes])
    (folder / "chain.xml").write_text(boom.chain_mjcf())
    times = np.arange(round(stop / step) + 1) * step
    runs = {}
    for final_rate in final_rates:
        manoeuvre = SpinUp(final_rate=final_rate)
        torques = hub_torques(chain, manoeuvre, step, stop)
        runs[final_rate] = {
            "rate": manoeuvre.rate(times),
            "chain": run_chain(boom, chain, torques, step, substeps),
            "modal": run_modal(fmu, boom, shapes[:, :modes], torques, step, substeps),
            "stiffened": run_stiffened(boom, chain, shapes[:, :modes], torques, step, substeps),
        }
    return {"times": times, "frequencies": np.sqrt(squares), "runs": runs, "ramp": SpinUp.ramp}


def figures(result: dict) -> dict:
    """What the docs quote, per Ωs: each side's largest |tip deflection|
    (over the run, and after Ts for the chain), the first time the modal
    tip passes 10 times the chain's largest (and its hub's rate 1e-3 rad/s
    from Ω(t)), the largest difference between the sides, and how far each
    hub strayed from Ω(t)."""
    times = result["times"]

    def first_time(condition: np.ndarray) -> float | None:
        return float(times[np.argmax(condition)]) if condition.any() else None

    after_ramp = times >= result["ramp"]
    table = {"chain_frequencies_rad_s": [float(w) for w in result["frequencies"][:4]], "runs": []}
    for final_rate, run in result["runs"].items():
        chain, modal = run["chain"]["tip"], run["modal"]["tip"]
        chain_largest = float(np.abs(chain).max())
        table["runs"].append({
            "final_rate": final_rate,
            "chain_largest_tip": chain_largest,
            "chain_largest_tip_after_ramp": float(np.abs(chain[after_ramp]).max()) if after_ramp.any() else None,
            "modal_largest_tip": float(np.abs(modal).max()),
            "modal_beyond_10x_chain_at": first_time(np.abs(modal) > 10 * chain_largest),
            "modal_hub_strays_at": first_time(np.abs(run["modal"]["hub_rate"] - run["rate"]) > 1e-3),
            "largest_difference": float(np.abs(chain - modal).max()),
            "stiffened_largest_difference": float(np.abs(chain - run["stiffened"]["tip"]).max()),
            "chain_hub_rate_error": float(np.abs(run["chain"]["hub_rate"] - run["rate"]).max()),
            "modal_hub_rate_error": float(np.abs(run["modal"]["hub_rate"] - run["rate"]).max()),
        })
    return table


def plot(result: dict, final_rate: float, path: Path) -> None:
    """Tip deflection against time, the chain and the modal body, on a
    linear scale (where the chain's motion shows) and as |deflection| on a
    logarithmic one (where the modal body's divergence shows)."""
    times, run = result["times"], result["runs"][final_rate]
    fig, (near, far) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    sides = (("lumped chain (MuJoCo)", "chain", "-"), ("linear modal body (nudyn)", "modal", "--"),
             ("modal with geometric stiffening (not in nudyn)", "stiffened", ":"))
    for label, side, style in sides:
        near.plot(times, run[side]["tip"], style, label=label)
        far.semilogy(times, np.abs(run[side]["tip"]) + 1e-6, style, label=label)
    limit = 2 * np.abs(run["chain"]["tip"]).max()
    near.set_ylim(-limit, limit)
    near.set_ylabel("tip deflection (m)")
    far.set_ylabel("|tip deflection| (m)")
    far.set_xlabel("time (s)")
    for axes in (near, far):
        axes.axvline(result["ramp"], color="grey", linewidth=0.8)
        axes.grid(True, linewidth=0.3)
    near.legend(loc="lower right")
    near.set_title(f"Spin-up of a 10 m beam to {final_rate:g} rad/s over {result['ramp']:g} s")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("outdir", type=Path)
    parser.add_argument("--nudyn", type=Path, default=nudyn_binary(),
                        help="the nudyn binary (default $NUDYN_BIN or target/release/nudyn)")
    parser.add_argument("--links", type=int, default=20, help="rods of the chain (default 20)")
    parser.add_argument("--modes", type=int, default=4, help="modes of the modal body (default 4)")
    parser.add_argument("--final-rate", type=float, default=6.0, help="Ωs of the plotted run (rad/s, default 6)")
    parser.add_argument("--slow-rate", type=float, default=0.5, help="Ωs of the control run (rad/s, default 0.5)")
    parser.add_argument("--stop", type=float, default=30.0, help="seconds simulated (default 30)")
    args = parser.parse_args()
    args.outdir.mkdir(parents=True, exist_ok=True)
    # The chain's highest frequency is about 7 links² rad/s; RK4 is stable
    # for ω h < 2.8, kept here below 1.5.
    substeps = max(10, math.ceil(0.05 * args.links**2))
    result = spin_up(Nudyn(args.nudyn), args.outdir, args.links, args.modes, [args.final_rate, args.slow_rate],
                     args.stop, substeps=substeps)
    table = {"links": args.links, "modes": args.modes, "internal_step": 0.01 / substeps, **figures(result)}
    (args.outdir / "spinup.json").write_text(json.dumps(table, indent=2) + "\n")
    plot(result, args.final_rate, args.outdir / "spinup.png")
    print(json.dumps(table, indent=2))


if __name__ == "__main__":
    main()
