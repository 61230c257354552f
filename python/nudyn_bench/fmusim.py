"""The Reference FMUs' fmusim as a second native host for issue 36 (beside
`bench/native/fmu_host.c`): the examples' FMU 2.0 in co-simulation for 10 s
of the validation's tumble in 0.1 s communication steps, ε = 0, `auto`
and `dop853` at tolerances 1e-4 … 1e-10, timed in fmusim, in the native
host and against MuJoCo RK4 under the issue's rule (as auto.py).

fmusim is not built here: give the executable (`--fmusim PATH`). Its
process time holds a fixed cost (unzipping the FMU, reading its
modelDescription, loading the library, instantiating, initializing,
writing the CSV, removing the unzipped copy); each repetition also runs it
with `--stop-time 0` (the same start values, no step) and the simulation's
time is the median of the full runs less the median of the empty runs.
The native host times its stepping loop only (instantiation and
initialization outside). All runs of a vehicle are interleaved in each
repetition. fmusim gets the start values the native host sets (θ, ν, the
`method` enumeration's value, `tolerance`) with `--start-value`, passes no
tolerance to fmi2SetupExperiment (as the host), and records θ and ν at
every communication point; its last row is compared to the host's. The
two do not step alike: fmusim asks the FMU for a step from n * 0.1 to
(n + 1) * 0.1 (its size the difference), the host for 0.1 from n * 0.1, and
from n = 5 on the ends differ by an ulp (6 * 0.1 != 0.5 + 0.1), so the
results part by round-off (with a 0.125 s step, exact in binary, they are
the same to the bit).

    .venv/bin/python scripts/bench_fmusim.py --fmusim PATH [--out DIR] [--quick]
"""

from __future__ import annotations

import argparse
import csv
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from nudyn_driver.package import FmuPackage

from . import native_host
from .auto import EXAMPLES, METHODS, STEP, exported_with_reference, simulate
from .cli import binaries, run_stamp
from .methods import mujoco_reaching, rk4_ladder
from .report import median
from .tolerance import scaled_error
from .vehicles import ROOT, Vehicle, prepare

TOLERANCES = [1e-4, 1e-6, 1e-8, 1e-10]


def fmusim_command(fmusim: Path, fmu: Path, package: FmuPackage, vehicle: Vehicle, settings: dict, stop: float,
                   output: Path, log: Path) -> list[str]:
    """fmusim's command line for the FMU from the vehicle's state with
    `settings` (method by item name, other parameters by value), recording
    θ and ν every STEP up to `stop`."""
    cmd = [str(fmusim), "--interface-type", "cs", "--start-time", "0", "--stop-time", repr(stop),
           "--output-interval", repr(STEP), "--output-file", str(output), "--log-file", str(log)]
    for name, value in zip(package.names("theta") + package.names("nu"), [*map(float, vehicle.qpos),
                                                                             *map(float, vehicle.nu)]):
        cmd += ["--start-value", name, repr(value)]
    for name, value in settings.items():
        value = package.enumeration_value(name, value) if name == "method" else repr(float(value))
        cmd += ["--start-value", name, str(value)]
    for name in package.names("theta") + package.names("nu"):
        cmd += ["--output-variable", name]
    return cmd + [str(fmu)]


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def fmusim_run(cmd: list[str]) -> tuple[float, float]:
    """Runs fmusim; its wall time and CPU time (user + system) in seconds
    (it must exit 0)."""
    cpu, start = _children_cpu(), time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    seconds, cpu = time.perf_counter() - start, _children_cpu() - cpu
    if proc.returncode != 0:
        raise RuntimeError(f"fmusim failed ({proc.returncode}): {proc.stdout}{proc.stderr}")
    return seconds, cpu


def last_row(output: Path) -> tuple[float, list[float]]:
    """The time and values of the CSV's last row."""
    with open(output, newline="") as f:
        rows = list(csv.reader(f))
    return float(rows[-1][0]), [float(v) for v in rows[-1][1:]]


def vehicle_runs(vehicle: Vehicle, bench: Path, nudyn: Path, host: Path, fmusim: Path, work: Path,
                 quick: bool, repetitions: int) -> dict:
    duration = 0.4 if quick else 10.0
    steps = round(duration / STEP)
    package, ref_qpos, ref_qvel = exported_with_reference(vehicle, bench, nudyn, work, duration)
    fmu = work / f"{vehicle.name}.fmu"
    runs = []
    for method in METHODS:
        for tolerance in TOLERANCES[:2] if quick else TOLERANCES:
            run = simulate(bench, vehicle, f"{method}:{tolerance:g}", duration)
            settings = {"method": method, "tolerance": tolerance}
            stem = work / f"{vehicle.name}_{method}_{tolerance:g}"
            runs.append({
                "method": method, "tolerance": tolerance, "chosen": run["chosen"], "ended_with": run["ended_with"],
                "error": scaled_error(vehicle.model, run["qpos"], run["qvel"], ref_qpos, ref_qvel),
                "settings": settings, "host_seconds": [], "fmusim_seconds": [], "fmusim_empty_seconds": [],
                "fmusim_cpu": [], "fmusim_empty_cpu": [],
                "full": fmusim_command(fmusim, fmu, package, vehicle, settings, duration, Path(f"{stem}.csv"),
                                       Path(f"{stem}.log")),
                "empty": fmusim_command(fmusim, fmu, package, vehicle, settings, 0.0, Path(f"{stem}_0.csv"),
                                        Path(f"{stem}_0.log")),
                "csv": Path(f"{stem}.csv"), "log": Path(f"{stem}.log"),
            })
    mujoco, plan, rk4 = rk4_ladder(vehicle, duration, ref_qpos, ref_qvel, quick)
    host_last = {}
    for _ in range(repetitions):
        for run in runs:
            for kind, key in (("full", ""), ("empty", "_empty")):
                seconds, cpu = fmusim_run(run[kind])
                run[f"fmusim{key}_seconds"].append(seconds)
                run[f"fmusim{key}_cpu"].append(cpu)
            result = native_host.run(host, package, vehicle, run["settings"], STEP, steps)
            run["host_seconds"].append(result["seconds"][0])
            host_last[id(run)] = result["theta"][-1] + result["nu"][-1]
        for entry in rk4:
            entry["seconds"].append(mujoco.run("RK4", entry["step"], plan)[0])
    out = []
    for run in runs:
        end_time, fmusim_last = last_row(run["csv"])
        host = host_last[id(run)]
        differences = [abs(a - b) / (1 + abs(b)) for a, b in zip(fmusim_last, host)]
        mujoco_step, mujoco_seconds = mujoco_reaching(run, rk4)
        fmusim_seconds = median(run["fmusim_seconds"]) - median(run["fmusim_empty_seconds"])
        host_seconds = median(run["host_seconds"])
        out.append({
            **{k: run[k] for k in ("method", "tolerance", "chosen", "ended_with", "error", "host_seconds",
                                   "fmusim_seconds", "fmusim_empty_seconds", "fmusim_cpu", "fmusim_empty_cpu")},
            "fmusim_net_seconds": fmusim_seconds,
            "fmusim_net_cpu": median(run["fmusim_cpu"]) - median(run["fmusim_empty_cpu"]),
            "mujoco_step": mujoco_step, "mujoco_seconds": mujoco_seconds,
            "fmusim_over_mujoco": fmusim_seconds / mujoco_seconds if mujoco_seconds else None,
            "host_over_mujoco": host_seconds / mujoco_seconds if mujoco_seconds else None,
            "fmusim_end_time": end_time,
            # fmusim's CSV prints 16 significant digits: equal when the host's
            # value printed so reads back as fmusim's.
            "end_equal_to_16_digits": all(float(f"{b:.16g}") == a for a, b in zip(fmusim_last, host)),
            "end_max_difference": max(differences),
            "fmusim_log": run["log"].read_text().strip().splitlines(),
        })
    return {"runs": out, "mujoco_rk4": rk4}


def table(results: dict) -> str:
    lines = [f"# fmusim and the native host against MuJoCo ({results['date']}, {results['commit']})", "",
             "10 s of each example's tumble in 0.1 s communication steps, FMU 2.0 CS. fmusim ms: median process "
             "time less the median of the same command with --stop-time 0 (empty run ms); fmusim CPU ms: the "
             "same on its user + system time; native ms: the host's timed stepping loop; MuJoCo RK4 ms at the "
             "largest 0.1 s / k step reaching max(error, tolerance); end: fmusim's last row against the host's "
             "(=: equal to the 16 digits fmusim prints, else the largest relative difference)."
             + (" **Quick run: the numbers mean nothing.**" if results["quick"] else ""), "",
             "| example | tolerance | method | fmusim ms | (empty run ms) | fmusim CPU ms | native ms | MuJoCo ms "
             "| fmusim / MuJoCo | native / MuJoCo | end |", "|---" * 11 + "|"]

    def number(value, form):
        return "—" if value is None else format(value, form)

    for name, vehicle in results["vehicles"].items():
        for run in sorted(vehicle["runs"], key=lambda r: (-r["tolerance"], METHODS.index(r["method"]))):
            method = run["method"]
            if run["chosen"]:
                moved = f"→{run['ended_with']}" if run["ended_with"] != run["chosen"] else ""
                method += f" ({run['chosen']}{moved})"
            end = "=" if run["end_equal_to_16_digits"] else f"{run['end_max_difference']:.1e}"
            lines.append(
                f"| {name} | {run['tolerance']:g} | {method} | {1e3 * run['fmusim_net_seconds']:.2f} "
                f"| {1e3 * median(run['fmusim_empty_seconds']):.1f} | {1e3 * run['fmusim_net_cpu']:.2f} "
                f"| {1e3 * median(run['host_seconds']):.2f} "
                f"| {number(run['mujoco_seconds'] and 1e3 * run['mujoco_seconds'], '.2f')} "
                f"| {number(run['fmusim_over_mujoco'], '.2f')} | {number(run['host_over_mujoco'], '.2f')} | {end} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="bench_fmusim.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--fmusim", type=Path, required=True, help="the fmusim executable (built by hand)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "bench", help="where fmusim.{json,md} go")
    parser.add_argument("--quick", action="store_true", help="tiny sizes, for a smoke test: the numbers mean nothing")
    parser.add_argument("--bin-dir", type=Path, default=ROOT / "target" / "release", help="where nudyn-bench is")
    parser.add_argument("--examples", nargs="+", default=EXAMPLES, help="which examples (default: all five)")
    parser.add_argument("--repetitions", type=int, default=5, help="interleaved repetitions (default 5)")
    args = parser.parse_args(argv)
    found = binaries(args.bin_dir, "bench_fmusim.py")
    if found is None:
        return 2
    bench, nudyn = found
    results = {**run_stamp(args.quick), "fmusim": str(args.fmusim), "vehicles": {}}
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        host = native_host.build(work)
        for name in args.examples[:1] if args.quick else args.examples:
            print(f"bench_fmusim: {name}", file=sys.stderr, flush=True)
            vehicle = prepare(name, ROOT / "examples" / f"{name}.xml", work)
            results["vehicles"][name] = vehicle_runs(vehicle, bench, nudyn, host, args.fmusim, work, args.quick,
                                                     1 if args.quick else args.repetitions)
            (args.out / "fmusim.json").write_text(json.dumps(results, indent=1) + "\n")
    (args.out / "fmusim.md").write_text(table(results))
    print(table(results))
    return 0
