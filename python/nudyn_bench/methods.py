"""What each adaptive method costs per tolerance, integrated natively
(`nudyn-bench simulate`, no FMI layer): every example for 10 s of the
validation's tumble in 0.1 s advances (communication steps), at tolerances
1e-4 … 1e-10. Per run: the error delivered (largest |x − x_ref| / (1 +
|x_ref|) over qpos, quaternions up to sign, and qvel at the advances'
ends, against the same integrator's dop853 at 1e-13), the steps taken and
rejected, the θ̈ evaluations and the median time of 5 repetitions. The
cheapest method at each tolerance is what `method = auto` should pick.

Beside them, timed in the same repetitions, MuJoCo's RK4 (`mujoco.rollout`)
under the rule of issue 36: a co-simulation master stops it at every
communication point, so its step is the largest of 0.1 s / k (k = 1, 2,
4, 5, 10, …, 1000: each divides the communication step) whose error
reaches the looser of the tolerance and the method's error. The ratio
method / MuJoCo is the integrators' alone: no FMI calls on either side.
And the same runs through the example's FMU in the native master of
issue 36 (`bench/native/fmu_host.c`: one doStep and one fmi2GetReal of θ
and ν per communication step, timed over the whole run, no Python), and
its ratio to MuJoCo's time: the one the issue judges.

    .venv/bin/python scripts/bench_methods.py [--out docs/bench] [--quick]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from nudyn_driver.cli import Nudyn, run_json
from nudyn_driver.package import FmuPackage

from . import native_host

from .cli import binaries, run_stamp
from .report import median
from .tolerance import scaled_error
from .vehicles import ROOT, Vehicle, prepare
from .work_precision import MujocoRuns, Plan

EXAMPLES = ["bus_arm7", "fixed_rig", "flexible_boom", "servicer", "chain60"]
METHODS = ["bs3", "tsit5", "dopri5", "dop853"]
TOLERANCES = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]
# bs3's order 3 takes 10⁵–10⁶ steps in 10 s below these on the faster
# examples, which only lengthens the run: it is never the cheapest there.
BS3_TIGHTEST = {"chain60": 1e-5, "flexible_boom": 1e-5}
BS3_TIGHTEST_DEFAULT = 1e-8


MUJOCO_STEPS = [0.1 / k for k in (1, 2, 4, 5, 10, 20, 40, 50, 100, 200, 400, 1000)]


def simulate(bench: Path, vehicle: Vehicle, run: str, duration: float, repetitions: int) -> dict:
    cmd = [str(bench), "simulate", str(vehicle.path), "--state", str(vehicle.state_path), "--duration", str(duration),
           "--sample", "0.1", "--repetitions", str(repetitions), "--run", run]
    return run_json(cmd)[0]


def rk4_ladder(vehicle: Vehicle, duration: float, ref_qpos: np.ndarray, ref_qvel: np.ndarray,
               quick: bool) -> tuple[MujocoRuns, Plan, list[dict]]:
    """MuJoCo's RK4 at each step of the ladder (its first three when
    `quick`) over `duration` in 0.1 s samples: the runs, their plan, and per
    step its error against the reference, with an empty list for its times."""
    mujoco = MujocoRuns(vehicle)
    plan = Plan(duration, 0.1, 0.0, 0.0, [], [], [], [])
    rk4 = []
    for step in MUJOCO_STEPS[:3] if quick else MUJOCO_STEPS:
        _, qpos, qvel = mujoco.run("RK4", step, plan)
        rk4.append({"step": step, "error": scaled_error(vehicle.model, qpos, qvel, ref_qpos, ref_qvel), "seconds": []})
    return mujoco, plan, rk4


def reaching_entry(run: dict, rk4: list[dict]) -> dict | None:
    """MuJoCo's RK4 under the issue's rule for a run: the entry of `rk4`
    (each with its step and error) with the longest step whose error is
    within max(the run's error, its tolerance); None when no step reaches it."""
    target = max(run["error"], run["tolerance"])
    reaching = [entry for entry in rk4 if entry["error"] <= target]
    return max(reaching, key=lambda entry: entry["step"]) if reaching else None


def mujoco_reaching(run: dict, rk4: list[dict]) -> tuple[float | None, float | None]:
    """The step of `reaching_entry` and its median seconds (each entry timed
    in `seconds`); (None, None) when no step reaches it."""
    best = reaching_entry(run, rk4)
    return (None, None) if best is None else (best["step"], median(best["seconds"]))


def example(name: str, bench: Path, nudyn: Path, host: Path, work: Path, quick: bool) -> dict:
    vehicle = prepare(name, ROOT / "examples" / f"{name}.xml", work)
    package = FmuPackage.unzip(Nudyn(nudyn).export(vehicle.path, work / f"{name}.fmu"), work / f"{name}_fmu")
    duration, repetitions = (0.4, 1) if quick else (10.0, 5)
    reference = simulate(bench, vehicle, "dop853:1e-13", duration, 1)
    ref_qpos, ref_qvel = np.array(reference["qpos"]), np.array(reference["qvel"])
    runs = []
    for method in METHODS:
        for tolerance in TOLERANCES[:2] if quick else TOLERANCES:
            if method == "bs3" and tolerance < BS3_TIGHTEST.get(name, BS3_TIGHTEST_DEFAULT):
                continue
            run = simulate(bench, vehicle, f"{method}:{tolerance:g}", duration, 1)
            error = scaled_error(vehicle.model, run["qpos"], run["qvel"], ref_qpos, ref_qvel)
            runs.append({"method": method, "tolerance": tolerance, "error": error, "accepted": run["accepted"],
                         "rejected": run["rejected"], "evaluations": run["evaluations"], "seconds": [],
                         "host_seconds": []})
    mujoco, plan, rk4 = rk4_ladder(vehicle, duration, ref_qpos, ref_qvel, quick)
    # Interleaved, so that the machine's load falls alike on both sides.
    for _ in range(repetitions):
        for run in runs:
            timed = simulate(bench, vehicle, f"{run['method']}:{run['tolerance']:g}", duration, 1)
            run["seconds"].append(timed["seconds"][0])
            settings = {"method": run["method"], "tolerance": run["tolerance"]}
            hosted = native_host.run(host, package, vehicle, settings, 0.1, round(duration / 0.1))
            run["host_seconds"].append(hosted["seconds"][0])
        for entry in rk4:
            entry["seconds"].append(mujoco.run("RK4", entry["step"], plan)[0])
    for run in runs:
        run["mujoco_step"], mujoco_seconds = mujoco_reaching(run, rk4)
        run["over_mujoco"] = median(run["seconds"]) / mujoco_seconds if mujoco_seconds else None
        run["host_over_mujoco"] = median(run["host_seconds"]) / mujoco_seconds if mujoco_seconds else None
    return {"runs": runs, "mujoco_rk4": rk4}


def table(results: dict) -> str:
    lines = [f"# Each method's cost per tolerance ({results['date']}, {results['commit']})", "",
             "10 s in 0.1 s communication steps; per method: error / tolerance, steps (rejected), θ̈ "
             "evaluations; the integrator's median ms (`nudyn-bench simulate`) and its ratio to MuJoCo RK4's "
             "time at the largest step dividing 0.1 s that reaches max(error, tolerance) (— where none does); "
             "the FMU's median ms in the native master and its ratio. **Bold**: the least FMU time at that "
             "tolerance." + (" **Quick run: the numbers mean nothing.**" if results["quick"] else ""), ""]
    for name, ex in results["examples"].items():
        lines += [f"## {name}", "", "| tolerance | " + " | ".join(METHODS) + " |", "|---" * (len(METHODS) + 1) + "|"]
        for tolerance in sorted({r["tolerance"] for r in ex["runs"]}, reverse=True):
            cells = {r["method"]: r for r in ex["runs"] if r["tolerance"] == tolerance}
            fastest = min(cells.values(), key=lambda r: median(r["host_seconds"]))["method"]
            row = []
            for method in METHODS:
                r = cells.get(method)
                if r is None:
                    row.append("")
                    continue
                def ratio(value):
                    return "—" if value is None else f"{value:.2f}"

                host = f"{1e3 * median(r['host_seconds']):.2f}"
                row.append(f"{r['error'] / tolerance:.2g}, {r['accepted']} ({r['rejected']}), {r['evaluations']}; "
                           f"{1e3 * median(r['seconds']):.2f}, {ratio(r['over_mujoco'])}; "
                           + (f"**{host}**" if method == fastest else host) + f", {ratio(r['host_over_mujoco'])}")
            lines.append(f"| {tolerance:g} | " + " | ".join(row) + " |")
        lines.append("")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="bench_methods.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "bench", help="where methods.{json,md} go")
    parser.add_argument("--quick", action="store_true", help="tiny sizes, for a smoke test: the numbers mean nothing")
    parser.add_argument("--bin-dir", type=Path, default=ROOT / "target" / "release", help="where nudyn-bench is")
    args = parser.parse_args(argv)
    found = binaries(args.bin_dir, "bench_methods.py")
    if found is None:
        return 2
    bench, nudyn = found
    results = {
        **run_stamp(args.quick),
        "examples": {},
    }
    with tempfile.TemporaryDirectory() as tmp:
        host = native_host.build(Path(tmp))
        for name in EXAMPLES[:2] if args.quick else EXAMPLES:
            print(f"bench_methods: {name}", file=sys.stderr, flush=True)
            results["examples"][name] = example(name, bench, nudyn, host, Path(tmp), args.quick)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "methods.json").write_text(json.dumps(results, indent=1) + "\n")
    (args.out / "methods.md").write_text(table(results))
    print(table(results))
    return 0
