"""The seven stress cases.  Each runs the FMU through FMPy in a few
set-ups, measures against references that do not come from the set-up
under test (the invariants K and momentum, exact for ε = 0 in zero gravity;
an exact solution; a run at a far tighter tolerance; MuJoCo), writes its
figure and returns its table rows and a verdict.

Every case has a short length (CI) and a long one (`--long`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nudyn_driver.cli import Nudyn
from nudyn_driver.errors import DriverError
from nudyn_driver.instance import STATUS_NAMES, status_of
from nudyn_driver.package import FmuPackage
from nudyn_driver.structure import VehicleStructure

from . import plots, vehicles
from .measures import (
    energy_residual,
    evaluation_cost,
    kinetic_energy_drift,
    momentum_drift,
    nu_of,
    scaled_error,
    sqrt_d,
    steps_per_second,
)
from .runs import OUTPUTS, Run, Setup, simulate, start_instance

# The run every accuracy is measured against, where there is no exact
# solution: DOP853 four orders of magnitude tighter than the default (at
# 1e-13 the mass-ratio vehicle's reference is discarded: round-off).
REFERENCE = Setup("dop853", tolerance=1e-12, max_step=1e-3)
DEFAULT_TOLERANCE = 1e-8  # the FMU's default, stated here for the thresholds

# Energy projection keeps K to round-off: each projected step may move K
# by a few units of round-off (the sum ½|ν|², a square root, the scaling),
# so the drift allowed is this, or this many ε per internal step on runs
# with more steps than that covers.
PROJECTED_K_DRIFT = 1e-12
ROUNDOFF_PER_STEP = 4 * np.finfo(float).eps


def projected_k_bound(row: "Row", duration: float) -> float:
    return max(PROJECTED_K_DRIFT, ROUNDOFF_PER_STEP * row.steps_per_second * duration)


@dataclass
class Row:
    """One set-up of one case."""

    setup: str
    outcome: str  # "completed" or what stopped it
    error: float | None = None  # max scaled error against the reference
    k_drift: float | None = None  # max |K − K₀|/K₀ (only where K is conserved)
    momentum_drift: float | None = None
    residual: float | None = None  # max |energy residual| / K₀
    steps_per_second: float | None = None  # internal steps per simulated second (FMU-reported)
    wall: float | None = None  # seconds in fmi2DoStep
    note: str = ""


@dataclass
class CaseResult:
    key: str
    title: str
    checked: str
    rows: list[Row]
    verdict: str
    passed: bool
    figure: Path
    numbers: dict = field(default_factory=dict)  # case-specific values for the JSON and the tests


@dataclass
class Context:
    nudyn: Path
    out_dir: Path
    long: bool
    seed: int = 1
    _packages: dict = field(default_factory=dict)
    _structures: dict = field(default_factory=dict)

    @property
    def cli(self) -> Nudyn:
        # The FMU binary built with this nudyn, whatever NUDYN_FMU_LIB says.
        library = self.nudyn.parent / "libnudyn_fmu.so"
        return Nudyn(self.nudyn, library if library.is_file() else None)

    def package(self, model: Path) -> FmuPackage:
        """The model exported (and unzipped) once, under out_dir/fmus."""
        if model not in self._packages:
            fmu = self.cli.export(model, self.out_dir / "fmus" / f"{model.stem}.fmu", outputs=OUTPUTS)
            self._packages[model] = FmuPackage.unzip(fmu, self.out_dir / "fmus" / model.stem)
        return self._packages[model]

    def structure(self, model: Path) -> VehicleStructure:
        """The model's joints and their θ/ν addresses (`nudyn describe`)."""
        if model not in self._structures:
            self._structures[model] = self.cli.describe(model)
        return self._structures[model]

    @property
    def vehicles_dir(self) -> Path:
        return self.out_dir / "vehicles"

    def figure(self, key: str) -> Path:
        return self.out_dir / f"{key}.png"

    def rng(self) -> np.random.Generator:
        return np.random.default_rng(self.seed)


def start_pose(structure: VehicleStructure, rng: np.random.Generator, hinge_offset: float = 0.5) -> np.ndarray:
    """The model's pose with hinges offset by up to ±hinge_offset rad and
    random orientations of ball and free joints (free positions kept)."""
    theta = np.array(structure.qpos0)
    for joint in structure.joints:
        if joint.quaternion_adr is not None:
            q = rng.normal(size=4)
            theta[joint.quaternion_adr : joint.quaternion_adr + 4] = q / np.linalg.norm(q)
        elif joint.kind == "hinge":
            theta[joint.qpos_adr] += rng.uniform(-hinge_offset, hinge_offset)
    return theta


def random_qvel(structure: VehicleStructure, rng: np.random.Generator, angular: float, linear: float) -> np.ndarray:
    """N(0, angular) rad/s per rotational dof, N(0, linear) m/s per
    translational one."""
    translational = set(structure.translational_dofs)
    return rng.normal(0.0, [linear if k in translational else angular for k in range(structure.nv)])


def _outcome(run: Run) -> str:
    if run.completed:
        return "completed"
    return f"{STATUS_NAMES[run.status]} at t = {run.time[-1]:.4g} s"


def _relaxed(run: Run) -> str:
    if run.held_tolerance is None:
        return ""
    return f"round-off: tolerance relaxed to {run.held_tolerance:.1e} per second (fmi2Warning)"


def _row(run: Run, *, reference: Run | None = None, quaternion_starts=(), conserved=True,
         momentum_conserved=True, note="") -> Row:
    """conserved: K is (ε = 0, no springs or dampers); momentum_conserved:
    the momentum is (no ε on the free base)."""
    return Row(
        setup=run.setup.label(),
        outcome=_outcome(run),
        error=float(np.max(scaled_error(run, reference, list(quaternion_starts)))) if reference else None,
        k_drift=float(np.max(kinetic_energy_drift(run))) if conserved else None,
        momentum_drift=float(np.max(momentum_drift(run))) if momentum_conserved else None,
        residual=float(np.max(energy_residual(run))),
        steps_per_second=steps_per_second(run),
        wall=run.wall_time,
        note="; ".join(filter(None, [note, _relaxed(run), run.message.removeprefix("fmi2DoStep: ")])),
    )


# ---------------------------------------------------------------- case 1


def long_tumbling(ctx: Context) -> CaseResult:
    """bus_arm7 tumbling freely: drift of K and momentum over 10³ s (10⁴ s
    long) for both adaptive methods at a loose and a tight tolerance, with
    and without energy projection, and the FMU's defaults."""
    model = vehicles.BUS_ARM7
    package = ctx.package(model)
    structure = ctx.structure(model)
    rng = ctx.rng()
    theta0 = start_pose(structure, rng)
    nu0 = nu_of(ctx.nudyn, model, theta0, random_qvel(structure, rng, angular=0.1, linear=0.05))
    duration = 1e4 if ctx.long else 1e3
    comm_step = 10.0
    # max_step = the communication step: the tolerance alone sets the steps.
    setups = [
        Setup(method, tolerance, comm_step, projection)
        for method in ("dop853", "dopri5")
        for tolerance in (1e-6, 1e-10)
        for projection in (False, True)
    ]
    setups.append(Setup("dop853"))  # the FMU's defaults: tolerance 1e-8, no max_step
    runs = [simulate(package, s, theta0, nu0, duration, comm_step) for s in setups]
    rows = [_row(r) for r in runs]

    failures = []
    for run, row in zip(runs, rows):
        tolerance = run.setup.tolerance or DEFAULT_TOLERANCE
        budget = tolerance * duration  # the tolerance is error per second
        if not run.completed:
            failures.append(f"{row.setup}: {row.outcome}")
        if run.setup.energy_projection and row.k_drift >= projected_k_bound(row, duration):
            failures.append(f"{row.setup}: projected K drift {row.k_drift:.1e}")
        if row.k_drift > budget or row.momentum_drift > budget:
            failures.append(f"{row.setup}: drift above tolerance × time = {budget:.0e}")
    plots.drift_figure(ctx.figure("tumbling"), runs, f"bus_arm7 tumbling freely for {duration:g} s (ε = 0)")
    verdict = (
        "all within tolerance × time; projected K kept to round-off"
        if not failures
        else "; ".join(failures)
    )
    return CaseResult(
        "tumbling",
        f"Free tumbling, {duration:g} s",
        "bus_arm7, ε = 0: relative drift of K and momentum (exact invariants); "
        "threshold tolerance × simulated time (the tolerance is per second); "
        f"projected K: < {PROJECTED_K_DRIFT:.0e} or 4ε per internal step, whichever is larger",
        rows,
        verdict,
        not failures,
        ctx.figure("tumbling"),
        {"duration": duration},
    )


# ---------------------------------------------------------------- case 2


def sine_law(amplitude: np.ndarray, rng: np.random.Generator):
    """ε_k(t) = a_k sin(2π f_k t + φ_k), f between 0.1 and 0.5 Hz."""
    frequency = rng.uniform(0.1, 0.5, len(amplitude))
    phase = rng.uniform(0, 2 * np.pi, len(amplitude))
    return lambda t: amplitude * np.sin(2 * np.pi * frequency * t + phase)


def _accuracy_case(ctx, model, key, title, checked, theta0, nu0, eps_law, duration, comm_step, extra_setups=(),
                   mujoco_check=True, reference_setup=REFERENCE, round_off_probe=None, mujoco_limit=1e-6,
                   mujoco_method="dop853"):
    """Runs the usual set-ups against `reference_setup`, with and without ε.

    round_off_probe: for a vehicle whose accuracy round-off limits, a second
    reference whose distance from the first (the spread) shows how far the
    motion grows round-off; adaptive runs must then say which tolerance they
    held (fmi2Warning) and keep K and momentum to it, and their errors are
    reported, not judged."""
    package = ctx.package(model)
    structure = ctx.structure(model)
    setups = [Setup("rk4"), Setup("dopri5"), Setup("dop853"), *extra_setups]
    rows, error_series, failures = [], {}, []
    numbers = {"spread": {}}
    for label, law in (("ε = 0", None), ("sine ε", eps_law)):
        reference = simulate(package, reference_setup, theta0, nu0, duration, comm_step, law)
        spread = 0.0
        if round_off_probe is not None:
            probe = simulate(package, round_off_probe, theta0, nu0, duration, comm_step, law)
            probe_error = scaled_error(probe, reference, structure.quaternion_starts)
            error_series[f"{round_off_probe.label()} (the spread), {label}"] = (np.array(probe.time[: len(probe_error)]),
                                                                               probe_error)
            spread = float(np.max(probe_error))
            numbers["spread"][label] = spread
            rows.append(_row(probe, reference=reference, quaternion_starts=structure.quaternion_starts,
                             conserved=law is None, momentum_conserved=law is None,
                             note=f"{label}; round-off probe: its distance from the reference is the spread"))
        for setup in setups:
            run = simulate(package, setup, theta0, nu0, duration, comm_step, law)
            row = _row(run, reference=reference, quaternion_starts=structure.quaternion_starts,
                       conserved=law is None, momentum_conserved=law is None, note=label)
            rows.append(row)
            error = scaled_error(run, reference, structure.quaternion_starts)
            error_series[f"{setup.label()}, {label}"] = (np.array(run.time[: len(error)]), error)
            if not run.completed:
                failures.append(f"{row.setup} ({label}): {row.outcome}")
            elif setup.method != "rk4" and round_off_probe is None:
                if row.error > (setup.tolerance or DEFAULT_TOLERANCE) * duration:
                    failures.append(f"{row.setup} ({label}): error {row.error:.1e} > tolerance × time")
            elif setup.method != "rk4":
                # Round-off rules: the motion's sensitivity grows any error
                # (see the spread), so the invariants are what is judged,
                # against the tolerance the run said it held.
                if run.held_tolerance is None:
                    failures.append(f"{row.setup} ({label}): no warning that the tolerance could not be held")
                allowed = (run.held_tolerance or 0.0) * duration
                drifts = [d for d in (row.k_drift, row.momentum_drift) if d is not None]
                if any(d > allowed for d in drifts):
                    failures.append(f"{row.setup} ({label}): K or momentum drift above {allowed:.1e}")
        if not reference.completed:
            failures.append(f"the reference ({label}) stopped: {reference.message}")
        if law is None:
            ref_row = _row(reference, note="reference")
            if max(ref_row.k_drift, ref_row.momentum_drift / 10.0) > max(1e-11, spread):
                failures.append(f"reference drifts: K {ref_row.k_drift:.1e}, momentum {ref_row.momentum_drift:.1e}")
            rows.append(ref_row)
    if mujoco_check:
        numbers["mujoco"] = mujoco_agreement(ctx, model, method=mujoco_method)
        mj = numbers["mujoco"]
        rows.append(Row(f"{mujoco_method} vs MuJoCo RK4 1e-4 s", mj["failure"] or "completed", error=mj["max_error"],
                        note=f"{mj['duration']:g} s, the validation's sine scenario (max abs θ, ν error)"))
        if mj["failure"]:
            failures.append(f"against MuJoCo: {mj['failure']}")
        elif mj["max_error"] > mujoco_limit:
            failures.append(f"MuJoCo disagrees by {mj['max_error']:.1e}")
    plots.error_figure(ctx.figure(key), error_series, f"{title}: scaled error against {reference_setup.label()}")
    if round_off_probe is None:
        verdict = "adaptive runs within tolerance × time of the reference; invariants kept"
    else:
        verdict = (f"round-off limits this vehicle (spread {max(numbers['spread'].values()):.1e}): adaptive runs "
                   "complete, say which tolerance they held, and keep K and momentum to it")
    verdict = verdict if not failures else "; ".join(failures)
    return CaseResult(key, title, checked, rows, verdict, not failures, ctx.figure(key), numbers)


def mujoco_agreement(ctx: Context, model: Path, duration: float = 2.0, method: str = "dop853") -> dict:
    """The FMU (`method`, its defaults; rk4 at MuJoCo's step) against
    MuJoCo's RK4 at 1e-4 s on the validation's sine scenario: an independent
    check of the same dynamics."""
    from nudyn_validation.compare import Settings, ValidationError, validate_model

    try:
        validation = validate_model(
            model, ctx.out_dir / "fmus" / f"{model.stem}_mujoco.fmu", ctx.nudyn, ["sine"],
            Settings(duration=duration, method=method,
                     fmu_parameters={"max_step": Settings.mujoco_step} if method == "rk4" else None),
        )
    except (ValidationError, DriverError) as e:
        return {"duration": duration, "max_error": math.inf, "failure": str(e)}
    summary = validation.results[0].summary()
    return {
        "duration": duration,
        "failure": "",
        "max_error": max(summary["max_theta_error"], summary["max_nu_error"]),
        "max_theta_error": summary["max_theta_error"],
        "max_nu_error": summary["max_nu_error"],
    }


def mass_ratio(ctx: Context) -> CaseResult:
    model = vehicles.mass_ratio(ctx.vehicles_dir)
    package = ctx.package(model)
    structure = ctx.structure(model)
    rng = ctx.rng()
    theta0 = start_pose(structure, rng)
    qvel = random_qvel(structure, rng, angular=0.2, linear=0.05)
    qvel[-3:] = rng.normal(0.0, 2.0, 3)  # the tip whirls at a few rad/s
    nu0 = nu_of(ctx.nudyn, model, theta0, qvel)
    # ε that changes each dof's rate by ~0.1 rad/s in a second.
    law = sine_law(0.1 * sqrt_d(ctx.nudyn, model, theta0, package.nv), rng)
    duration = 100.0 if ctx.long else 10.0
    return _accuracy_case(
        ctx, model, "mass_ratio", f"10⁶ mass ratio, {duration:g} s",
        "1000 kg bus, arm, 1 g tip on a ball joint; tumbling (ε = 0) and sine ε: scaled error against "
        "dop853 at 1e-12 (threshold tolerance × time), K and momentum drift, and MuJoCo for 2 s",
        theta0, nu0, law, duration, 0.05,
    )


# ---------------------------------------------------------------- case 3


def long_chain(ctx: Context) -> CaseResult:
    links = 1000
    model = vehicles.chain(ctx.vehicles_dir, links)
    package = ctx.package(model)
    structure = ctx.structure(model)
    rng = ctx.rng()
    theta0 = start_pose(structure, rng)
    nu0 = nu_of(ctx.nudyn, model, theta0, random_qvel(structure, rng, angular=0.02, linear=0.005))
    duration, comm_step = (10.0, 0.1) if ctx.long else (3.0, 0.1)
    cost = evaluation_cost(package, theta0, nu0, steps=20)
    setups = [Setup("rk4"), Setup("dop853"), Setup("dop853", tolerance=1e-6), Setup("dopri5", tolerance=1e-6)]
    if ctx.long:
        setups.append(Setup("dopri5"))
    runs = [simulate(package, s, theta0, nu0, duration, comm_step) for s in setups]
    # The chain's dampers take energy: the residual (K − K₀ − work) is the
    # integration's energy error; the momentum is conserved (internal forces).
    rows = [_row(r, conserved=False) for r in runs]
    for run, row in zip(runs, rows):
        row.note = "; ".join(filter(None, [f"{1e3 * run.wall_time / max(run.do_steps, 1):.0f} ms per doStep", row.note]))
    failures = [f"{r.setup}: {r.outcome}" for r in rows if r.outcome != "completed"]
    # RK4 is reported, not judged: its fixed steps promise no accuracy.
    failures += [f"{r.setup}: momentum drift {r.momentum_drift:.1e}" for r in rows
                 if r.outcome == "completed" and not r.setup.startswith("rk4") and r.momentum_drift > 1e-6]
    plots.drift_figure(ctx.figure("chain"), runs, f"{links}-link chain on a free base, {duration:g} s",
                       energy="residual")
    return CaseResult(
        "chain", f"{links}-body chain, {duration:g} s",
        f"gen_chain.py with {links} links (nv = {package.nv}), ε = 0: completes?, momentum drift, "
        "energy residual, cost per dynamics evaluation and per doStep",
        rows,
        "all completed, momentum kept" if not failures else "; ".join(failures),
        not failures, ctx.figure("chain"),
        {"nv": package.nv, "seconds_per_evaluation": cost, "duration": duration},
    )


# ---------------------------------------------------------------- case 4


def highest_modal_frequency(model: Path) -> float:
    """√(largest eigenvalue of M⁻¹K) at the model's pose, K the joint
    stiffnesses (rad/s), from MuJoCo's mass matrix: the fastest mode of the
    linearized structure."""
    import mujoco

    from nudyn_validation.mujoco_reference import load_model

    m = load_model(model)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    mass = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, mass)  # MuJoCo 4: (m, d, dst)
    stiffness = np.zeros(m.nv)
    for j in range(m.njnt):
        stiffness[m.jnt_dofadr[j]] = m.jnt_stiffness[j] if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE else 0.0
    c = np.linalg.cholesky(mass)
    ci = np.linalg.inv(c)
    return float(math.sqrt(np.max(np.linalg.eigvalsh(ci @ np.diag(stiffness) @ ci.T))))


def stiff_boom(ctx: Context) -> CaseResult:
    stiffness = 1e5
    model = vehicles.stiff_boom(ctx.vehicles_dir, stiffness)
    package = ctx.package(model)
    structure = ctx.structure(model)
    rng = ctx.rng()
    omega = highest_modal_frequency(model)
    theta0 = start_pose(structure, rng, hinge_offset=0.0)
    bends = [k for joint in structure.joints if "boom_bend" in joint.name for k in joint.qpos]
    theta0[bends] += rng.uniform(-0.01, 0.01, len(bends))  # the boom released 10 mrad off its rest shape
    qvel = np.zeros(package.nv)
    qvel[3:6] = rng.normal(0.0, 0.05, 3)  # the bus tumbles slowly
    nu0 = nu_of(ctx.nudyn, model, theta0, qvel)
    duration, comm_step = (100.0, 0.05) if ctx.long else (5.0, 0.05)
    # RK4 is stable for h·ω up to 2√2 ≈ 2.83 on an undamped oscillator.
    rk4_limit = 2 * math.sqrt(2) / omega
    stable_step = comm_step / math.ceil(comm_step / (0.9 * rk4_limit))
    setups = [
        Setup("rk4"),
        Setup("rk4", max_step=stable_step),
        Setup("dopri5"),
        Setup("dop853"),
        # Loose tolerances with no step cap: where accuracy alone would allow
        # long steps, stability caps them (the classic stiff regime).
        Setup("dopri5", tolerance=1e-4, max_step=comm_step),
        Setup("dop853", tolerance=1e-4, max_step=comm_step),
    ]
    reference = simulate(package, Setup("dop853", tolerance=1e-12, max_step=1e-3), theta0, nu0, duration, comm_step)
    runs = [simulate(package, s, theta0, nu0, duration, comm_step) for s in setups]
    rows = [_row(r, reference=reference, quaternion_starts=structure.quaternion_starts, conserved=False) for r in runs]
    failures = []
    for run, row in zip(runs, rows):
        finite = all(np.all(np.isfinite(x)) for x in (run.theta[-1], run.nu[-1]))
        if not finite:
            failures.append(f"{row.setup}: non-finite output")
        if not run.completed and not (0 <= run.time[-1] <= duration):
            failures.append(f"{row.setup}: discard without a LastSuccessfulTime inside the run")
        if run.completed and run.setup.method != "rk4" and row.error > (run.setup.tolerance or DEFAULT_TOLERANCE) * duration:
            failures.append(f"{row.setup}: error {row.error:.1e} above tolerance × time")
    plots.stiff_figure(ctx.figure("stiff_boom"), runs, reference, bends, omega,
                       f"boom with stiffness {stiffness:g} N m/rad, ω_max = {omega:.0f} rad/s")
    return CaseResult(
        "stiff_boom", f"Stiff boom (k = {stiffness:g}), {duration:g} s",
        f"flexible_boom's boom at stiffness {stiffness:g} N m/rad, released 10 mrad off its rest shape: "
        f"ω_max = {omega:.0f} rad/s ({omega / 2 / math.pi:.0f} Hz), RK4 stable below "
        f"h = 2.83/ω = {rk4_limit * 1e3:.1f} ms; outputs finite, discards with LastSuccessfulTime, "
        "adaptive runs within tolerance × time of dop853 at 1e-12",
        rows,
        "no NaN; adaptive runs within tolerance (they resolve the fast mode); RK4 above 2.83/ω is unstable"
        if not failures else "; ".join(failures),
        not failures, ctx.figure("stiff_boom"),
        {"omega_max": omega, "rk4_stable_step": rk4_limit, "duration": duration,
         "outcomes": {r.setup: r.outcome for r in rows}},
    )


# ---------------------------------------------------------------- case 5


def thin_rods(ctx: Context) -> CaseResult:
    model = vehicles.thin_rods(ctx.vehicles_dir)
    package = ctx.package(model)
    structure = ctx.structure(model)
    rng = ctx.rng()
    theta0 = start_pose(structure, rng)
    qvel = random_qvel(structure, rng, angular=0.5, linear=0.05)
    qvel[3:6] = rng.normal(0.0, 0.05, 3)  # the bus tumbles slowly
    qvel[[6, 9, 12]] = 5.0  # each rod spins about its own axis at 5 rad/s
    nu0 = nu_of(ctx.nudyn, model, theta0, qvel)
    law = sine_law(0.1 * sqrt_d(ctx.nudyn, model, theta0, package.nv), rng)
    duration = 20.0 if ctx.long else 5.0
    # M's near-null directions (each rod about its own axis) have pivots of
    # 1e-9 out of sums of order 10: round-off in ν̇ is ~1e-5 of it, so no
    # run of this vehicle in double precision is better than that (MuJoCo's
    # RK4 at 1e-4 and 2.5e-5 s differ by 7e-6 over 2 s), and a tolerance of
    # 1e-12 cannot be held. Fine RK4 is the reference, coarser RK4 probes
    # the spread.
    return _accuracy_case(
        ctx, model, "thin_rods", f"Thin rods (I = diag(1e-9, 1, 1)), {duration:g} s",
        "bus with three rods of inertia diag(1e-9, 1, 1), spinning 5 rad/s about their axes, tumbling "
        "(ε = 0) and sine ε: completes?, says which tolerance it held (fmi2Warning), K and momentum drift "
        "within it; scaled error against RK4 at 2.5e-5 s reported beside the spread (RK4 at 5e-5 s against it), "
        "which shows how the motion grows round-off; MuJoCo for 2 s (RK4 1e-4 s on both sides; threshold 1e-3)",
        theta0, nu0, law, duration, 0.05,
        reference_setup=Setup("rk4", max_step=2.5e-5), round_off_probe=Setup("rk4", max_step=5e-5),
        mujoco_limit=1e-3, mujoco_method="rk4",
    )


# ---------------------------------------------------------------- case 6


def top_motion(times, quaternion0, omega_body0, position0, velocity):
    """Exact torque-free motion of the axisymmetric top (inertia
    diag(I1, I1, I3)): R(t) = exp(t |L|/I1 [n]) R₀ exp(t ω₃ (I1 − I3)/I1 [e₃]),
    n = L/|L| fixed in the world; body rate ω(t) = I⁻¹ R(t)ᵀ L.  Returns
    (qpos (n, 7), qvel (n, 6)) in MuJoCo's free-joint coordinates."""
    i1, _, i3 = vehicles.TOP_INERTIA
    inertia = np.array(vehicles.TOP_INERTIA)
    r0 = quaternion_to_matrix(quaternion0)
    angular_momentum = r0 @ (inertia * omega_body0)
    precession = np.linalg.norm(angular_momentum) / i1
    axis = angular_momentum / np.linalg.norm(angular_momentum)
    spin = omega_body0[2] * (i1 - i3) / i1
    qpos, qvel = [], []
    for t in times:
        rotation = axis_angle_matrix(axis, precession * t) @ r0 @ axis_angle_matrix(np.array([0, 0, 1.0]), spin * t)
        qpos.append(np.concatenate([position0 + velocity * t, matrix_to_quaternion(rotation)]))
        qvel.append(np.concatenate([velocity, (rotation.T @ angular_momentum) / inertia]))
    return np.array(qpos), np.array(qvel)


def quaternion_to_matrix(q):
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def matrix_to_quaternion(r):
    """(w, x, y, z) from a rotation matrix (Shepperd: the largest of the
    four squares first, for accuracy)."""
    squares = np.array([1 + np.trace(r), 1 + r[0, 0] - r[1, 1] - r[2, 2], 1 - r[0, 0] + r[1, 1] - r[2, 2],
                        1 - r[0, 0] - r[1, 1] + r[2, 2]])
    k = int(np.argmax(squares))
    s = 2 * math.sqrt(squares[k])
    if k == 0:
        q = [s / 4, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    elif k == 1:
        q = [(r[2, 1] - r[1, 2]) / s, s / 4, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s]
    elif k == 2:
        q = [(r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, s / 4, (r[1, 2] + r[2, 1]) / s]
    else:
        q = [(r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, s / 4]
    return np.array(q)


def axis_angle_matrix(axis, angle):
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def rotation_error(q, q_exact) -> float:
    """Angle (rad) of the rotation between two orientations."""
    return 2 * math.asin(min(1.0, np.linalg.norm(matrix_to_quaternion(quaternion_to_matrix(q).T @ quaternion_to_matrix(q_exact))[1:])))


def fast_spin(ctx: Context) -> CaseResult:
    model = vehicles.spinning_top(ctx.vehicles_dir)
    package = ctx.package(model)
    rng = ctx.rng()
    quaternion0 = rng.normal(size=4)
    quaternion0 /= np.linalg.norm(quaternion0)
    omega0 = np.array([1.0, 0.5, 100.0])  # 100 rad/s about the symmetry axis, nutating
    velocity = np.array([0.1, -0.05, 0.02])
    theta0 = np.concatenate([[0.0, 0.0, 0.0], quaternion0])
    # M is diagonal for a body with its centre of mass at its frame's origin
    # and principal axes along it: ν = √M qvel.
    sqrt_mass = np.sqrt([vehicles.TOP_MASS] * 3 + list(vehicles.TOP_INERTIA))
    nu0 = sqrt_mass * np.concatenate([velocity, omega0])
    duration, comm_step = (100.0, 0.01) if ctx.long else (10.0, 0.01)
    setups = [Setup("rk4"), Setup("rk4", max_step=1e-3), Setup("dopri5"), Setup("dop853"),
              Setup("dop853", tolerance=1e-11), Setup("dop853", energy_projection=True)]
    runs = [simulate(package, s, theta0, nu0, duration, comm_step) for s in setups]
    exact_qpos, exact_qvel = top_motion(np.array(runs[-1].time), quaternion0, omega0, np.zeros(3), velocity)
    exact_nu = exact_qvel * sqrt_mass
    rows, series, failures = [], {}, []
    for run in runs:
        n = len(run.time)
        angle = np.array([rotation_error(q[3:], e[3:]) for q, e in zip(np.array(run.theta)[:, :], exact_qpos[:n])])
        nu_error = np.max(np.abs(np.array(run.nu) - exact_nu[:n]) / (1 + np.abs(exact_nu[:n])), axis=1)
        error = np.maximum(angle, nu_error)
        row = _row(run)
        row.error = float(np.max(error))
        row.note = f"max rotation error {np.max(angle):.1e} rad"
        rows.append(row)
        series[run.setup.label()] = (np.array(run.time), error)
        if not run.completed:
            failures.append(f"{row.setup}: {row.outcome}")
        elif run.setup.method != "rk4" and row.error > (run.setup.tolerance or DEFAULT_TOLERANCE) * duration:
            failures.append(f"{row.setup}: error {row.error:.1e} above tolerance × time")
    plots.error_figure(ctx.figure("spin"), series, "top spinning at 100 rad/s: error against the exact solution",
                       ylabel="max(rotation error (rad), scaled ν error)")
    return CaseResult(
        "spin", f"100 rad/s spin, {duration:g} s",
        "free axisymmetric body, ω = (1, 0.5, 100) rad/s: error against the exact torque-free motion "
        "(rotation angle, ν; threshold tolerance × time), K and momentum drift",
        rows,
        "adaptive runs within tolerance × time of the exact motion" if not failures else "; ".join(failures),
        not failures, ctx.figure("spin"), {"duration": duration},
    )


# ---------------------------------------------------------------- case 7


def extreme_inputs(ctx: Context) -> CaseResult:
    """ε = 1e300, NaN, ±Inf on bus_arm7, then a sweep of |ε| = 10^k."""
    model = vehicles.BUS_ARM7
    package = ctx.package(model)
    structure = ctx.structure(model)
    rng = ctx.rng()
    theta0 = start_pose(structure, rng)
    nu0 = nu_of(ctx.nudyn, model, theta0, random_qvel(structure, rng, angular=0.1, linear=0.05))
    comm_step = 0.01
    rows, failures = [], []
    for method in package.methods:
        for label, value in (("NaN", math.nan), ("+Inf", math.inf), ("-Inf", -math.inf), ("1e300", 1e300)):
            with start_instance(package, Setup(method), theta0, nu0) as fmu:
                fmu.step(comm_step)
                eps = np.zeros(package.nv)
                eps[7] = value
                set_status = status_of(fmu.set_array, "eps", eps)
                set_message = fmu.log.last_problem() if set_status else ""
                step_status = status_of(fmu.step, comm_step)
                step_message = fmu.log.last_problem() if step_status else ""
                finite = bool(np.all(np.isfinite(fmu.all_reals())))
                reached = fmu.last_successful_time() if step_status else fmu.time
                terminated = fmu.terminated() if step_status else False
            outcome = (f"setReal: {STATUS_NAMES[set_status]}; doStep: {STATUS_NAMES[step_status]}, "
                       f"LastSuccessfulTime = {reached:g} s{', terminated' if terminated else ''}")
            message = set_message or step_message
            rows.append(Row(f"{method}, eps[8] = {label}", outcome, note=f"outputs finite: {finite}; “{message}”"))
            if not finite:
                failures.append(f"{method} {label}: non-finite output")
            if math.isfinite(value):
                # Overflow: the step is discarded somewhere inside it.
                if step_status != 2 or not (comm_step <= reached < 2 * comm_step):
                    failures.append(f"{method} {label}: doStep gave {STATUS_NAMES[step_status]} at {reached:g}")
            elif set_status != 2 or step_status != 0:
                # Refused: the value never reaches the FMU, which steps on with the ε it had.
                failures.append(f"{method} {label}: setReal gave {STATUS_NAMES[set_status]}, "
                                f"then doStep {STATUS_NAMES[step_status]}")
    sweep = epsilon_sweep(package, theta0, nu0, comm_step)
    plots.sweep_figure(ctx.figure("extreme_inputs"), sweep, comm_step)
    return CaseResult(
        "extreme_inputs", "Huge and non-finite ε",
        "bus_arm7 after one step, then eps[8] set to NaN, ±Inf (must be refused by fmi2SetReal with fmi2Discard, the instance unchanged) "
        "or 1e300 (doStep must return fmi2Discard with LastSuccessfulTime); outputs stay finite",
        rows,
        "non-finite ε refused, overflow discarded, outputs finite" if not failures else "; ".join(failures),
        not failures, ctx.figure("extreme_inputs"), {"sweep": sweep},
    )


def epsilon_sweep(package: FmuPackage, theta0, nu0, comm_step: float) -> dict:
    """For |ε| = 10^k on every dof: how far one doStep gets, by method."""
    exponents = list(range(0, 301, 20))
    sweep = {"exponents": exponents}
    for method in package.methods:
        reached = []
        for k in exponents:
            with start_instance(package, Setup(method), theta0, nu0) as fmu:
                fmu.set_array("eps", np.full(package.nv, 10.0**k))
                status_of(fmu.step, comm_step)
                reached.append(fmu.time)
        sweep[method] = reached
    return sweep


CASES = {
    "tumbling": long_tumbling,
    "mass_ratio": mass_ratio,
    "chain": long_chain,
    "stiff_boom": stiff_boom,
    "thin_rods": thin_rods,
    "spin": fast_spin,
    "extreme_inputs": extreme_inputs,
}
