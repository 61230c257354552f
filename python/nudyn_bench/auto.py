"""Time to the accuracy asked with `method = auto`, judged as issue 36
judges it: on every example, issue 50's slow station and on 10 random
six-body trees (trees.py),
10 s of the validation's tumble from each in 0.1 s communication steps,
ε = 0, at tolerances 1e-4 … 1e-10, `auto` and the default `dop853`:

- the error delivered (largest |x − x_ref| / (1 + |x_ref|) over qpos,
  quaternions up to sign, and qvel at the communication points, against
  `nudyn-bench simulate`'s dop853 at 1e-13), the steps and evaluations,
  and the method `auto` chose and ended with;
- the FMU's time in the native host (`bench/native/fmu_host.c`: one
  doStep and one fmi2GetReal of θ and ν per communication step, no
  Python) and in FMPy (the same loop through `nudyn_driver.Instance`);
- MuJoCo's RK4 (`mujoco.rollout`) under the issue's rule: a master stops
  it at every communication point, so its step is the largest 0.1 s / k
  (k = 1, 2, 4, 5, 10, …, 1000) that reaches the looser of the tolerance
  and the FMU's error; both ratios to its time.

Every timing is the fastest over the repetitions, which interleave all
runs of a vehicle. In each repetition the FMU in the native host and
then MuJoCo at the run's step are each timed as the fastest of the runs
back to back that fit in 0.25 s (up to 30; a longer run spans both speeds
below on its own); FMPy's as one run. The shared machines here run a
process at one of two speeds about 1.45 times apart, each lasting a
fraction of a second (bus_arm7's auto at 1e-6: 1.2 or 1.8 ms; MuJoCo at
0.05 s: 2.2 or 3.2 ms): medians of single runs paired as they came gave
ratios from 0.39 to 0.61 for the same build, and even the fastest of 30
runs back to back was at the slower speed in one repetition of five now
and then. The fastest over all repetitions is the faster speed on both
sides, so the ratios compare like with like. The trees' line is the
median over the trees of each tree's value.

With `--work-precision` it also redraws the work-precision plot of
docs/performance.md with every explicit method and `auto`
(`work_precision_auto.png` and `.json`: bus_arm7's tumble and fast
tumble, as `scripts/bench.py` runs them).

    .venv/bin/python scripts/bench_auto.py [--out docs/bench] [--quick] [--work-precision]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from nudyn_driver.cli import Nudyn, run_json
from nudyn_driver.instance import Instance
from nudyn_driver.package import FmuPackage

from . import cli, native_host, report
from . import work_precision as work_precision_runs
from .cli import binaries, run_stamp
from .methods import reaching_entry, rk4_ladder
from .report import median
from .tolerance import scaled_error
from .trees import write_tree
from .vehicles import ROOT, Vehicle, prepare

EXAMPLES = ["bus_arm7", "fixed_rig", "flexible_boom", "servicer", "chain60"]
# Issue 50's slow station: two 7-dof arms on a 5000 kg free base, the
# tumble's rates scaled so that the base turns at about 0.01 rad/s.
STATION = ("slow_station", ROOT / "tests" / "fixtures" / "slow_station.xml", 0.03)
TREES = 10
METHODS = ["auto", "dop853"]
TOLERANCES = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]
STEP = 0.1
# Each timing of a repetition is the fastest of the runs back to back that
# fit in this time, at most 30 (module docs).
FASTEST_WITHIN = 0.25


def runs_within(seconds: float) -> int:
    """How many more runs of `seconds` each to time, after the first: none
    for a run of a quarter second or more, which spans both of the
    machine's speeds as MuJoCo's run beside it does."""
    return int(min(FASTEST_WITHIN / max(seconds, 1e-6), 30)) - 1 if seconds < FASTEST_WITHIN else 0


def simulate(bench: Path, vehicle: Vehicle, run: str, duration: float) -> dict:
    cmd = [str(bench), "simulate", str(vehicle.path), "--state", str(vehicle.state_path), "--duration", str(duration),
           "--sample", str(STEP), "--run", run]
    return run_json(cmd)[0]


def exported_with_reference(vehicle: Vehicle, bench: Path, nudyn: Path, work: Path,
                            duration: float) -> tuple[FmuPackage, np.ndarray, np.ndarray]:
    """The vehicle's FMU, unpacked, and the reference run the errors are
    measured against (dop853 at 1e-13): its qpos and qvel."""
    package = FmuPackage.unzip(Nudyn(nudyn).export(vehicle.path, work / f"{vehicle.name}.fmu"),
                               work / f"{vehicle.name}_fmu")
    reference = simulate(bench, vehicle, "dop853:1e-13", duration)
    if reference["failed"]:
        # dop853 at 1e-13 with steps past the points can stall where round-off rules (tree5 at
        # 8.6 s, docs/integration.md): 1e-12 then, still a hundredth of the tightest tolerance.
        print(f"bench_auto: {vehicle.name}: reference at 1e-13 failed ({reference['failed']}); at 1e-12",
              file=sys.stderr, flush=True)
        reference = simulate(bench, vehicle, "dop853:1e-12", duration)
    return package, np.array(reference["qpos"]), np.array(reference["qvel"])


def fmpy_seconds(package: FmuPackage, vehicle: Vehicle, settings: dict, steps: int) -> float:
    """The FMU in FMPy: one doStep and reads of θ and ν per communication step, timed."""
    with Instance(package, start=settings, theta=vehicle.qpos, nu=vehicle.nu) as fmu:
        start = time.perf_counter()
        for n in range(steps):
            fmu.step(STEP, communication_point=n * STEP)
            fmu.array("theta")
            fmu.array("nu")
        return time.perf_counter() - start


def vehicle_runs(vehicle: Vehicle, bench: Path, nudyn: Path, host: Path, work: Path, quick: bool) -> dict:
    duration, repetitions = (0.4, 1) if quick else (10.0, 5)
    steps = round(duration / STEP)
    package, ref_qpos, ref_qvel = exported_with_reference(vehicle, bench, nudyn, work, duration)
    runs = []
    for method in METHODS:
        for tolerance in TOLERANCES[:2] if quick else TOLERANCES:
            run = simulate(bench, vehicle, f"{method}:{tolerance:g}", duration)
            runs.append({
                "method": method, "tolerance": tolerance,
                "error": scaled_error(vehicle.model, run["qpos"], run["qvel"], ref_qpos, ref_qvel),
                "accepted": run["accepted"], "rejected": run["rejected"], "evaluations": run["evaluations"],
                "chosen": run["chosen"], "ended_with": run["ended_with"], "host_seconds": [], "fmpy_seconds": [],
            })
    mujoco, plan, rk4 = rk4_ladder(vehicle, duration, ref_qpos, ref_qvel, quick)
    for run in runs:
        reaching = reaching_entry(run, rk4)
        run["mujoco_step"] = reaching and reaching["step"]
        run["paired_mujoco_seconds"] = []
    for _ in range(repetitions):
        for run in runs:
            settings = {"method": run["method"], "tolerance": run["tolerance"]}
            first = native_host.run(host, package, vehicle, settings, STEP, steps)["seconds"][0]
            more = runs_within(first)
            more_runs = native_host.run(host, package, vehicle, settings, STEP, steps, more)["seconds"] if more else []
            run["host_seconds"].append(min([first, *more_runs]))
            if run["mujoco_step"] is not None:
                mujoco_runs = [mujoco.run("RK4", run["mujoco_step"], plan)[0]]
                mujoco_runs += [mujoco.run("RK4", run["mujoco_step"], plan)[0] for _ in range(runs_within(mujoco_runs[0]))]
                run["paired_mujoco_seconds"].append(min(mujoco_runs))
            run["fmpy_seconds"].append(fmpy_seconds(package, vehicle, settings, steps))
    for run in runs:
        paired = run["paired_mujoco_seconds"]
        run["mujoco_seconds"] = min(paired) if paired else None
        for key in ("host", "fmpy"):
            run[f"{key}_fastest"] = min(run[f"{key}_seconds"])
            run[f"{key}_over_mujoco"] = run[f"{key}_fastest"] / run["mujoco_seconds"] if paired else None
    # The ladder's errors; its times are the pairs' above.
    return {"runs": runs, "mujoco_rk4": [{"step": entry["step"], "error": entry["error"]} for entry in rk4]}


def _cell(runs: list[dict], key: str):
    values = [r[key] for r in runs if r[key] is not None]
    return median(values) if len(values) == len(runs) else None


def summary(vehicles: dict, names: list[str], method: str, tolerance: float) -> dict:
    """The run of `method` at `tolerance`, or over several vehicles the median of each value."""
    runs = [next(r for r in vehicles[n]["runs"] if r["method"] == method and r["tolerance"] == tolerance)
            for n in names]
    out = {key: _cell(runs, key) for key in ("error", "accepted", "rejected", "evaluations", "mujoco_seconds",
                                               "host_over_mujoco", "fmpy_over_mujoco")}
    out["host_seconds"] = median([r["host_fastest"] for r in runs])
    out["fmpy_seconds"] = median([r["fmpy_fastest"] for r in runs])
    out["methods"] = sorted({f"{r['chosen']}→{r['ended_with']}" if r["chosen"] != r["ended_with"] else str(r["chosen"])
                             for r in runs if r["chosen"]})
    return out


def table(results: dict) -> str:
    trees = [n for n in results["vehicles"] if n.startswith("tree")]
    rows = [(n, [n]) for n in results["vehicles"] if not n.startswith("tree")]
    if trees:
        rows.append((f"median of {len(trees)} trees", trees))
    lines = [f"# `method = auto` against MuJoCo ({results['date']}, {results['commit']})", "",
             "10 s of each vehicle's tumble in 0.1 s communication steps (the slow station's rates scaled to a turn "
             "of about 0.01 rad/s). Per tolerance and method: the method auto "
             "chose (→ the one it moved up to); error / tolerance; steps (rejected); θ̈ evaluations; the FMU's "
             "fastest ms in the native host and in FMPy; MuJoCo RK4's fastest ms at the largest step dividing 0.1 s that "
             "reaches max(error, tolerance); native / MuJoCo and FMPy / MuJoCo (— where MuJoCo reaches it at no "
             "step down to 1e-4 s). Trees: medians over the trees of each value."
             + (" **Quick run: the numbers mean nothing.**" if results["quick"] else ""), ""]
    for label, names in rows:
        lines += [f"## {label}", "", "| tolerance | method | error / tol | steps | evaluations | native ms | FMPy ms "
                  "| MuJoCo ms | native / MuJoCo | FMPy / MuJoCo |", "|---" * 10 + "|"]
        for tolerance in sorted({r["tolerance"] for r in results["vehicles"][names[0]]["runs"]}, reverse=True):
            for method in METHODS:
                s = summary(results["vehicles"], names, method, tolerance)

                def number(value, form):
                    return "—" if value is None else format(value, form)

                label_method = method + (f" ({', '.join(s['methods'])})" if method == "auto" else "")
                lines.append(
                    f"| {tolerance:g} | {label_method} | {number(s['error'] and s['error'] / tolerance, '.2g')} "
                    f"| {number(s['accepted'], '.0f')} ({number(s['rejected'], '.0f')}) "
                    f"| {number(s['evaluations'], '.0f')} | {1e3 * s['host_seconds']:.2f} "
                    f"| {1e3 * s['fmpy_seconds']:.2f} | {number(s['mujoco_seconds'] and 1e3 * s['mujoco_seconds'], '.2f')} "
                    f"| {number(s['host_over_mujoco'], '.2f')} | {number(s['fmpy_over_mujoco'], '.2f')} |")
        lines.append("")
    return "\n".join(lines)


def work_precision(bench: Path, out: Path, quick: bool, stamp: dict) -> None:
    """bench.py's work-precision sections with every explicit method and auto."""
    results = {**stamp, "work_precision": {}}
    sizes = cli.Sizes(quick)
    with tempfile.TemporaryDirectory() as tmp:
        for scenario in work_precision_runs.SCENARIOS:
            print(f"bench_auto: work-precision, {scenario}", file=sys.stderr, flush=True)
            cli.work_precision_section(results, bench, scenario, Path(tmp), sizes)
    results["summary"] = {name: report.work_precision_summary(wp) for name, wp in results["work_precision"].items()}
    (out / "work_precision_auto.json").write_text(json.dumps(results, indent=1) + "\n")
    report.plot_work_precision(results, out / "work_precision_auto.png")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="bench_auto.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "bench", help="where auto.{json,md} go")
    parser.add_argument("--quick", action="store_true", help="tiny sizes, for a smoke test: the numbers mean nothing")
    parser.add_argument("--bin-dir", type=Path, default=ROOT / "target" / "release", help="where nudyn-bench is")
    parser.add_argument("--work-precision", action="store_true", help="only the work-precision plot with every method")
    args = parser.parse_args(argv)
    found = binaries(args.bin_dir, "bench_auto.py")
    if found is None:
        return 2
    bench, nudyn = found
    stamp = run_stamp(args.quick)
    args.out.mkdir(parents=True, exist_ok=True)
    if args.work_precision:
        work_precision(bench, args.out, args.quick, stamp)
        return 0
    results = {**stamp, "vehicles": {}}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        host = native_host.build(work)
        vehicles = [(name, ROOT / "examples" / f"{name}.xml", 1.0) for name in (EXAMPLES[:1] if args.quick else EXAMPLES)]
        vehicles += [] if args.quick else [STATION]
        vehicles += [(f"tree{seed}", write_tree(seed, work / f"tree{seed}.xml"), 1.0)
                     for seed in range(1 if args.quick else TREES)]
        for name, path, rate_scale in vehicles:
            print(f"bench_auto: {name}", file=sys.stderr, flush=True)
            vehicle = prepare(name, path, work, rate_scale=rate_scale)
            results["vehicles"][name] = vehicle_runs(vehicle, bench, nudyn, host, work, args.quick)
    (args.out / "auto.json").write_text(json.dumps(results, indent=1) + "\n")
    (args.out / "auto.md").write_text(table(results))
    print(table(results))
    return 0
