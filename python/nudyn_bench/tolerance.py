"""Time to the accuracy asked, through the FMI interface: each example's
FMU in FMPy, with its defaults apart from `tolerance` (DOP853, no
max_step), 10 s of the validation's tumble in 0.1 s communication steps,
ε = 0, reading θ and ν at every communication point as a co-simulation
master does; against MuJoCo's RK4 (`mujoco.rollout`, a native loop) at the
step that reaches the same error.

The error of a run is the largest, over the communication points, of
|x − x_ref| / (1 + |x_ref|) over qpos (quaternions up to sign) and qvel:
the measure the FMU's tolerance is stated in. The reference is MuJoCo's
RK4 at a tiny step, checked against the FMU's own DOP853 at tolerance
1e-12. For each tolerance the target is the looser of the FMU's error and
the tolerance; MuJoCo RK4's time to reach it is interpolated (log-log)
between the two of its runs that bracket it. The time spent outside the
FMU is the FMPy loop's time less `nudyn-bench simulate`'s time for the
same integration (timed in Rust).

    .venv/bin/python scripts/bench_tolerance.py [--out docs/bench] [--quick]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from nudyn_driver.cli import Nudyn  # noqa: E402
from nudyn_driver.instance import Instance  # noqa: E402
from nudyn_driver.package import FmuPackage  # noqa: E402
from nudyn_validation.compare import quaternion_starts  # noqa: E402

from .cli import binaries, run_stamp  # noqa: E402
from .report import median  # noqa: E402
from .vehicles import ROOT, Vehicle, prepare  # noqa: E402
from .work_precision import MujocoRuns, Plan, nudyn_runs, time_at_error  # noqa: E402

EXAMPLES = ["bus_arm7", "fixed_rig", "flexible_boom", "servicer", "chain60"]
# Tolerances where the target applies (the FMU at most half of
# MuJoCo RK4's time); at 1e-4 FMPy's own per-call cost dominates.
JUDGED = (1e-6, 1e-8, 1e-10)


class Sizes:
    def __init__(self, quick: bool):
        self.examples = ["bus_arm7", "fixed_rig"] if quick else EXAMPLES
        self.duration = 0.4 if quick else 10.0
        self.communication_step = 0.1
        self.tolerances = [1e-4, 1e-6] if quick else [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]
        self.reference_step = 1e-3 if quick else 1e-5
        # MuJoCo RK4's ladder of steps: each divides the communication step.
        self.mujoco_steps = [0.1, 0.01] if quick else [0.1 / k for k in (1, 2, 4, 5, 10, 20, 40, 50, 100, 200, 400, 1000)]
        self.repetitions = 1 if quick else 5

    @property
    def communication_points(self) -> int:
        """The doSteps (and reads after them) of one run."""
        return int(round(self.duration / self.communication_step))


def scaled_error(model: mujoco.MjModel, qpos, qvel, reference_qpos, reference_qvel) -> float:
    """max |x − x_ref| / (1 + |x_ref|) over the samples, quaternions up to sign."""
    qpos = np.array(qpos, float)
    for a in quaternion_starts(model):
        flip = np.sum(qpos[:, a : a + 4] * reference_qpos[:, a : a + 4], axis=1) < 0
        qpos[flip, a : a + 4] *= -1
    errors = [np.abs(qpos - reference_qpos) / (1 + np.abs(reference_qpos)),
              np.abs(np.asarray(qvel) - reference_qvel) / (1 + np.abs(reference_qvel))]
    largest = max(e.max() for e in errors)
    return float(largest) if np.isfinite(largest) else float("inf")


def fmu_loop(
    package: FmuPackage, vehicle: Vehicle, tolerance: float, sizes: Sizes, read: str, logging: bool = False
) -> tuple[float, list, list, tuple[int, int]]:
    """Seconds of the doStep loop, θ and `read` (nu or qvel) at every
    communication point, and with `logging` the internal steps (taken,
    rejected) from fmi2DoStep's logStepStatistics ((0, 0) without: logging
    costs time, so timed runs go without it)."""
    h = sizes.communication_step
    with Instance(package, start={"tolerance": tolerance}, theta=vehicle.qpos, nu=vehicle.nu, logging_on=logging) as fmu:
        theta, other = [fmu.array("theta")], [fmu.array(read)]
        start = time.perf_counter()
        for n in range(sizes.communication_points):
            fmu.step(h, communication_point=n * h)
            theta.append(fmu.array("theta"))
            other.append(fmu.array(read))
        seconds = time.perf_counter() - start
        return seconds, theta, other, fmu.log.internal_steps()


def fmpy_reads(package: FmuPackage, vehicle: Vehicle, sizes: Sizes) -> float:
    """Seconds of the loop's reads alone (θ and ν at every communication
    point, no doStep): what this master costs whatever the FMU does in its
    steps, so a lower bound on any FMU's time in this loop."""
    with Instance(package, start={"tolerance": 1e-6}, theta=vehicle.qpos, nu=vehicle.nu) as fmu:
        fmu.array("theta"), fmu.array("nu")  # warm-up
        start = time.perf_counter()
        for _ in range(sizes.communication_points):
            fmu.array("theta")
            fmu.array("nu")
        return time.perf_counter() - start


def example(name: str, nudyn: Path, bench: Path, work: Path, sizes: Sizes) -> dict:
    vehicle = prepare(name, ROOT / "examples" / f"{name}.xml", work)
    package = FmuPackage.unzip(
        Nudyn(nudyn).export(vehicle.path, work / f"{name}.fmu", outputs=("qvel",)), work / f"{name}_fmu"
    )
    plan = Plan(sizes.duration, sizes.communication_step, sizes.reference_step, 1e-12, [], [], [], [])
    runs = MujocoRuns(vehicle)
    reference_qpos, reference_qvel = runs.reference(plan)

    def error(qpos, qvel):
        return scaled_error(vehicle.model, qpos, qvel, reference_qpos, reference_qvel)

    _, theta, qvel, _ = fmu_loop(package, vehicle, 1e-12, sizes, "qvel")
    reference_check = error(theta, qvel)
    fmu = {}
    for tolerance in sizes.tolerances:
        _, theta, qvel, (taken, rejected) = fmu_loop(package, vehicle, tolerance, sizes, "qvel", logging=True)
        fmu[f"{tolerance:g}"] = {"tolerance": tolerance, "error": error(theta, qvel), "steps": taken,
                                 "rejected": rejected, "seconds": [], "native_seconds": []}
    mujoco_runs = {f"{h:g}": {"step": h, "seconds": []} for h in sizes.mujoco_steps}
    reads_seconds = []
    for repetition in range(sizes.repetitions):
        reads_seconds.append(fmpy_reads(package, vehicle, sizes))
        # Interleaved: every FMU run, its native twin, then every MuJoCo run, per repetition.
        for entry in fmu.values():
            fmu_loop(package, vehicle, entry["tolerance"], sizes, "nu")  # untimed warm-up, as MuJoCo's
            entry["seconds"].append(fmu_loop(package, vehicle, entry["tolerance"], sizes, "nu")[0])
            [native] = nudyn_runs(bench, vehicle, [f"dop853:{entry['tolerance']:g}"], plan, samples=False)
            entry["native_seconds"].append(native["seconds"][0])
        for entry in mujoco_runs.values():
            seconds, qpos, qvel = runs.run("RK4", entry["step"], plan)
            entry["seconds"].append(seconds)
            if repetition == 0:
                entry["error"] = error(qpos, qvel)
    points = [(e["error"], median(e["seconds"])) for e in mujoco_runs.values()]
    reads = median(reads_seconds)
    for entry in fmu.values():
        fmu_seconds = median(entry["seconds"])
        entry["target"] = max(entry["error"], entry["tolerance"])
        entry["mujoco_seconds_at_target"] = time_at_error(points, entry["target"])
        entry["outside_share"] = max(0.0, 1.0 - median(entry["native_seconds"]) / fmu_seconds)
        mujoco_seconds = entry["mujoco_seconds_at_target"]
        entry["fmu_over_mujoco"] = fmu_seconds / mujoco_seconds if mujoco_seconds else None
        # Above 1, no FMU could meet the target in this loop.
        entry["reads_over_target"] = reads / (0.5 * mujoco_seconds) if mujoco_seconds else None
    return {"nv": vehicle.model.nv, "fmpy_reads_seconds": reads, "reference": f"MuJoCo RK4 at {sizes.reference_step:g} s",
            "reference_check": reference_check, "fmu": fmu, "mujoco_rk4": mujoco_runs}


def verdict(entry: dict) -> str:
    ratio = entry["fmu_over_mujoco"]
    if ratio is None:
        return "MuJoCo RK4 does not reach it"
    if entry["tolerance"] not in JUDGED:
        return f"{ratio:.2f}"
    if ratio <= 0.5:
        return f"{ratio:.2f} (met)"
    return f"{ratio:.2f} (**not met**; FMPy's reads alone take {100 * entry['reads_over_target']:.0f} % of the target)"


def table(results: dict) -> str:
    lines = [
        f"Measured {results['date']} at commit {results['commit']} on {results['machine']}; MuJoCo "
        f"{results['mujoco']}. {results['duration']:g} s of the validation's tumble, communication step "
        f"{results['communication_step']:g} s, FMU defaults apart from `tolerance` (dop853, no max_step); "
        f"times are medians of {results['repetitions']} interleaved repetitions."
        + (" **Quick run: the numbers mean nothing.**" if results["quick"] else ""),
        "",
    ]
    for name, ex in results["examples"].items():
        lines += [
            f"#### {name} (nv = {ex['nv']}; reference {ex['reference']}, which the FMU's dop853 at 1e-12 "
            f"meets to {ex['reference_check']:.1e})",
            "",
            f"FMPy's reads alone (θ and ν at the {round(results['duration'] / results['communication_step'])} "
            f"communication points, no doStep): {1e3 * ex['fmpy_reads_seconds']:.2f} ms.",
            "",
            "| tolerance | error | error / tol | steps (rejected) | FMU in FMPy (ms) | outside the FMU | "
            "MuJoCo RK4 to max(error, tol) (ms) | FMU / MuJoCo |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for e in ex["fmu"].values():
            mj = e["mujoco_seconds_at_target"]
            lines.append(
                f"| {e['tolerance']:g} | {e['error']:.1e} | {e['error'] / e['tolerance']:.2g} | {e['steps']} ({e['rejected']}) | "
                f"{1e3 * median(e['seconds']):.2f} | {100 * e['outside_share']:.0f} % | "
                f"{'—' if mj is None else f'{1e3 * mj:.2f}'} | {verdict(e)} |"
            )
        lines.append("")
    return "\n".join(lines)


def plot(results: dict, path: Path) -> None:
    examples = results["examples"]
    fig, axes = plt.subplots(1, len(examples), figsize=(4.2 * len(examples), 4.2), squeeze=False)
    for ax, (name, ex) in zip(axes[0], examples.items()):
        fmu = sorted((e["error"], median(e["seconds"]), e["tolerance"]) for e in ex["fmu"].values())
        ax.loglog([p[0] for p in fmu], [p[1] for p in fmu], marker="o", label="FMU dop853 in FMPy")
        for error, seconds, tolerance in fmu:
            ax.annotate(f"{tolerance:g}", (error, seconds), fontsize=7, textcoords="offset points", xytext=(3, 3))
        # Runs that blew up (error above 1) would only stretch the axis.
        mj = sorted((e["error"], median(e["seconds"])) for e in ex["mujoco_rk4"].values() if e["error"] < 1.0)
        ax.loglog([p[0] for p in mj], [p[1] for p in mj], marker="s", label="MuJoCo RK4 (rollout)")
        ax.set_title(name)
        ax.set_xlabel("max scaled error over the run")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].set_ylabel("wall time (s)")
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="bench_tolerance.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "bench", help="where tolerance.{json,md,png} go")
    parser.add_argument("--quick", action="store_true", help="tiny sizes, for a smoke test: the numbers mean nothing")
    parser.add_argument("--bin-dir", type=Path, default=ROOT / "target" / "release", help="where nudyn and nudyn-bench are")
    args = parser.parse_args(argv)
    sizes = Sizes(args.quick)
    found = binaries(args.bin_dir, "bench_tolerance.py")
    if found is None:
        return 2
    bench, nudyn = found
    results = {
        **run_stamp(args.quick),
        "mujoco": mujoco.__version__,
        "duration": sizes.duration,
        "communication_step": sizes.communication_step,
        "repetitions": sizes.repetitions,
        "examples": {},
    }
    with tempfile.TemporaryDirectory() as tmp:
        for name in sizes.examples:
            print(f"bench_tolerance: {name}", file=sys.stderr, flush=True)
            results["examples"][name] = example(name, nudyn, bench, Path(tmp), sizes)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "tolerance.json").write_text(json.dumps(results, indent=1) + "\n")
    (args.out / "tolerance.md").write_text(table(results))
    plot(results, args.out / "tolerance.png")
    print(table(results))
    return 0
