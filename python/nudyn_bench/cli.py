"""`scripts/bench.py`: every benchmark of docs/bench, one progress bar.

    .venv/bin/python scripts/bench.py [--out docs/bench] [--quick]

needs `cargo build --release --workspace` first (it runs
target/release/nudyn-bench and target/release/nudyn); `bash scripts/bench.sh`
does both. Writes results.json, table.md, work_precision.png and
scaling.png to --out. --quick runs tiny sizes in seconds (the CI smoke
test): its numbers mean nothing.
"""

from __future__ import annotations

import argparse
import datetime
import json
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

import mujoco
from tqdm import tqdm

from . import cost, fmi, report, work_precision
from .vehicles import ROOT, chain_model, prepare, prepare_chain_without_mujoco, write_chain

EXAMPLES = ["bus_arm7", "flexible_boom", "fixed_rig", "chain60", "servicer"]
# Pinocchio 4.1's MJCF reader took all 24 GB of memory on the 1000-link chain.
PINOCCHIO_MAX_LINKS = 500
PINOCCHIO_TOO_DEEP = f"not run past {PINOCCHIO_MAX_LINKS} links: Pinocchio's MJCF reader ran out of memory (24 GB) on 1000"
# MuJoCo 4.0 refuses to compile deeper body trees ("depth limit exceeded").
MUJOCO_MAX_LINKS = 1000


def arguments(argv):
    parser = argparse.ArgumentParser(prog="bench.py", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "bench", help="where the results go (default docs/bench)")
    parser.add_argument("--quick", action="store_true", help="tiny sizes, for a smoke test: the numbers mean nothing")
    parser.add_argument("--bin-dir", type=Path, default=ROOT / "target" / "release", help="where nudyn and nudyn-bench are")
    return parser.parse_args(argv)


class Sizes:
    """How much each section runs."""

    def __init__(self, quick: bool):
        self.examples = ["bus_arm7", "fixed_rig", "servicer"] if quick else EXAMPLES
        self.chains = [10, 20] if quick else [10, 20, 50, 100, 200, 500, 1000, 2000]
        # The scaling target's pair, also timed side by side.
        self.scaling_pair = (10, 20) if quick else (200, 2000)
        self.dense_max = 20 if quick else 500
        self.repetitions = 3 if quick else 21
        self.batch_ms = 2.0 if quick else 20.0
        self.plan = work_precision.QUICK if quick else work_precision.FULL
        # Seven: a run of about 1 ms (MuJoCo RK4 at 0.1 s) has shown slow
        # outliers in two of three repetitions on a shared machine.
        self.work_precision_repetitions = 1 if quick else 7
        self.fmi_duration = 0.1 if quick else 10.0
        self.fmi_repetitions = 1 if quick else 5


def git_commit() -> str:
    proc = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT)
    return proc.stdout.strip() or "unknown"


def run_stamp(quick: bool) -> dict:
    """What every benchmark's numbers are stamped with: when, from which
    commit, whether they are a smoke test's, and on what machine."""
    return {
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "commit": git_commit(),
        "quick": quick,
        "machine": platform.platform(),
    }


def binaries(bin_dir: Path, prog: str) -> tuple[Path, Path] | None:
    """(nudyn-bench, nudyn) in `bin_dir`, or None after saying which is missing."""
    bench, nudyn = bin_dir / "nudyn-bench", bin_dir / "nudyn"
    for binary in (bench, nudyn):
        if not binary.is_file():
            print(f"{prog}: {binary} is missing: run `cargo build --release --workspace`", file=sys.stderr)
            return None
    return bench, nudyn


def main(argv=None) -> int:
    args = arguments(argv)
    sizes = Sizes(args.quick)
    found = binaries(args.bin_dir, "bench.py")
    if found is None:
        return 2
    bench, nudyn = found
    args.out.mkdir(parents=True, exist_ok=True)
    import pinocchio

    results = {
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "commit": git_commit(),
        "quick": args.quick,
        "machine": {"platform": platform.platform(), "processor": platform.processor() or platform.machine()},
        "versions": {"mujoco": mujoco.__version__, "pinocchio": pinocchio.__version__, "python": platform.python_version()},
        "eval_cost": {},
        "scaling": {},
        "work_precision": {},
    }
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        tasks = []
        for name in sizes.examples:
            tasks.append((f"ν̇ cost: {name}", lambda name=name: eval_cost_example(results, bench, name, work, sizes)))
        chains = {}
        for links in sizes.chains:
            tasks.append(
                (f"scaling: chain of {links}", lambda links=links: scaling_chain(results, bench, nudyn, links, work, sizes, chains))
            )
        small, large = sizes.scaling_pair
        tasks.append((f"scaling: chains of {small} and {large} side by side", lambda: scaling_side_by_side(results, bench, sizes, chains)))
        for scenario in work_precision.SCENARIOS:
            tasks.append(
                (f"work-precision: bus_arm7, {scenario}", lambda scenario=scenario: work_precision_section(results, bench, scenario, work, sizes))
            )
        tasks.append(("FMI overhead: bus_arm7", lambda: fmi_section(results, nudyn, bench, work, sizes)))
        with tqdm(total=len(tasks), unit="task", dynamic_ncols=True) as bar:
            for description, task in tasks:
                bar.set_description(description)
                task()
                bar.update()
    results["summary"] = report.summarize(results)
    (args.out / "results.json").write_text(json.dumps(results, indent=1) + "\n")
    report.write(results, args.out)
    print(report.targets_text(results["summary"]))
    return 0


def eval_cost_example(results: dict, bench: Path, name: str, work: Path, sizes: Sizes) -> None:
    vehicle = prepare(name, ROOT / "examples" / f"{name}.xml", work)
    entry = cost.eval_cost(bench, vehicle, sizes.repetitions, sizes.batch_ms, shortcuts=True, dense=False)
    entry["pinocchio"] = cost.pinocchio_aba(vehicle, sizes.repetitions, sizes.batch_ms / 1e3)
    results["eval_cost"][name] = entry


def scaling_chain(results: dict, bench: Path, nudyn: Path, links: int, work: Path, sizes: Sizes, chains: dict) -> None:
    name = f"chain{links}"
    path = write_chain(links, work / f"{name}.xml")
    if links <= MUJOCO_MAX_LINKS:
        vehicle = prepare(name, path, work, model=chain_model(links))
    else:
        vehicle = prepare_chain_without_mujoco(links, path, nudyn, work)
    chains[links] = vehicle
    repetitions = sizes.repetitions if links <= 200 else max(3, sizes.repetitions // 3)
    entry = cost.eval_cost(bench, vehicle, repetitions, sizes.batch_ms, shortcuts=False, dense=links <= sizes.dense_max)
    entry["links"] = links
    if links <= PINOCCHIO_MAX_LINKS:
        entry["pinocchio"] = cost.pinocchio_aba(vehicle, repetitions, sizes.batch_ms / 1e3)
    else:
        entry["pinocchio"] = {"converts": False, "problem": PINOCCHIO_TOO_DEEP}
    results["scaling"][name] = entry


def scaling_side_by_side(results: dict, bench: Path, sizes: Sizes, chains: dict) -> None:
    """The scaling target's two chains timed in turn in one process: their
    ratio per repetition is not at the mercy of how busy the machine was
    during each chain's own run, minutes apart."""
    small, large = sizes.scaling_pair
    entries = cost.eval_cost_side_by_side(bench, [chains[small], chains[large]], sizes.repetitions, sizes.batch_ms)
    results["scaling_side_by_side"] = {"links": [small, large], "nanoseconds": [e["nanoseconds"] for e in entries]}


def work_precision_section(results: dict, bench: Path, scenario: str, work: Path, sizes: Sizes) -> None:
    plan = sizes.plan
    rate_scale = work_precision.SCENARIOS[scenario]
    vehicle = prepare(f"bus_arm7_x{rate_scale:g}", ROOT / "examples" / "bus_arm7.xml", work, rate_scale=rate_scale)
    runs = work_precision.MujocoRuns(vehicle)
    reference_qpos, reference_qvel = runs.reference(plan)
    model = vehicle.model

    def error(qpos, qvel):
        return work_precision.max_error(model, qpos, qvel, reference_qpos, reference_qvel)

    [check] = work_precision.nudyn_runs(bench, vehicle, [f"dop853:{plan.reference_tolerance:g}"], plan)
    nudyn_names = work_precision.nudyn_run_names(plan)
    mujoco_names = work_precision.mujoco_run_names(plan)
    nudyn_entries = {name: {"seconds": []} for name in nudyn_names}
    mujoco_entries = {f"{name}:{h:g}": {"seconds": []} for name, h in mujoco_names}
    for repetition in range(sizes.work_precision_repetitions):
        # Interleaved: all of nudyn's runs, then all of MuJoCo's, per repetition.
        for out in work_precision.nudyn_runs(bench, vehicle, nudyn_names, plan):
            entry = nudyn_entries[out["run"]]
            entry["seconds"].append(out["seconds"][0])
            if repetition == 0:
                entry.update(steps=out["accepted"], rejected=out["rejected"], failed=out["failed"])
                entry["error"] = float("inf") if out["failed"] else error(out["qpos"], out["qvel"])
        for name, h in mujoco_names:
            seconds, qpos, qvel = runs.run(name, h, plan)
            entry = mujoco_entries[f"{name}:{h:g}"]
            entry["seconds"].append(seconds)
            if repetition == 0:
                entry.update(error=error(qpos, qvel), steps=int(round(plan.duration / h)))
    results["work_precision"][scenario] = {
        "vehicle": "bus_arm7",
        "start": f"the validation's tumble (seed 1) with {rate_scale:g}× its rates",
        "duration": plan.duration,
        "sample": plan.sample,
        "reference": f"MuJoCo RK4 at {plan.reference_step:g} s",
        "reference_check": {
            "run": f"nudyn dop853:{plan.reference_tolerance:g}",
            "difference": error(check["qpos"], check["qvel"]),
        },
        "nudyn": nudyn_entries,
        "mujoco": mujoco_entries,
    }


def fmi_section(results: dict, nudyn: Path, bench: Path, work: Path, sizes: Sizes) -> None:
    vehicle = prepare("bus_arm7", ROOT / "examples" / "bus_arm7.xml", work)
    results["fmi"] = fmi.fmi_overhead(nudyn, bench, vehicle, 1e-3, sizes.fmi_duration, sizes.fmi_repetitions, work)
    results["fmi"]["vehicle"] = "bus_arm7"
