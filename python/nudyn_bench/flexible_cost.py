"""The cost of one ν̇ of the flexible example (examples/flexible_spacecraft/)
beside one mj_forward of MuJoCo on a vehicle with as many degrees of
freedom: each appendage a chain of as many hinged rods as it has modes
(nudyn_validation.flexible_example.lumped_equivalent). Timed side by side
in one process by `nudyn-bench eval-cost` (docs/flexible.md, "Cost").

    python -m nudyn_bench.flexible_cost [--bin-dir target/release] [--repetitions 25]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from pathlib import Path

import mujoco
import numpy as np

from nudyn_driver.cli import run_json
from nudyn_validation.flexible_example import lumped_equivalent

from .vehicles import ROOT, mujoco_library

EXAMPLE = ROOT / "examples" / "flexible_spacecraft" / "flexible_spacecraft.xml"
CASES = {"ν̇": "nudyn", "θ̈ (integrators' stage)": "nudyn qacc (integrator stage)"}


def measure(bench: Path, repetitions: int, batch_ms: float) -> dict:
    modes = {name: 4 for name in ("array_left", "array_right", "boom")}
    lumped = mujoco.MjModel.from_xml_string(lumped_equivalent(modes))
    rng = np.random.default_rng(49)
    turn = rng.normal(size=4)
    theta = [0.1, 0.2, 0.3, *(turn / np.linalg.norm(turn))] + list(0.01 * rng.standard_normal(lumped.nq - 7))
    qvel = list(0.1 * rng.standard_normal(lumped.nv))
    with tempfile.TemporaryDirectory() as folder:
        binary, state = Path(folder) / "lumped.mjb", Path(folder) / "state.json"
        mujoco.mj_saveModel(lumped, str(binary))
        state.write_text(json.dumps({"theta": [float(x) for x in theta], "nu": qvel, "qvel": qvel}))
        result = run_json([str(bench), "eval-cost", str(EXAMPLE), "--state", str(state), "--mujoco-lib",
                           str(mujoco_library()), "--mujoco-model", str(binary), "--repetitions", str(repetitions),
                           "--batch-ms", str(batch_ms)])
    times = result["nanoseconds"]
    forward = times["mj_forward"]
    rows = {}
    for label, key in CASES.items():
        ratios = [ours / theirs for ours, theirs in zip(times[key], forward)]
        quartiles = statistics.quantiles(ratios, n=4)
        rows[label] = {"nanoseconds": statistics.median(times[key]), "ratio_median": statistics.median(ratios),
                       "ratio_quartiles": [quartiles[0], quartiles[2]], "ratio_best": min(ratios)}
    return {"nv": lumped.nv, "mj_forward_nanoseconds": statistics.median(forward), "cases": rows}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m nudyn_bench.flexible_cost", description=__doc__)
    parser.add_argument("--bin-dir", type=Path, default=ROOT / "target" / "release")
    parser.add_argument("--repetitions", type=int, default=25)
    parser.add_argument("--batch-ms", type=float, default=20.0)
    args = parser.parse_args(argv)
    bench = args.bin_dir / "nudyn-bench"
    if not bench.is_file():
        print(f"flexible_cost: {bench} is missing: run `cargo build --release --workspace`", file=sys.stderr)
        return 2
    result = measure(bench, args.repetitions, args.batch_ms)
    print(f"nv = {result['nv']}; mj_forward of the lumped equivalent: {result['mj_forward_nanoseconds']:.0f} ns")
    print("| nudyn | ns (median) | / mj_forward, median of the repetitions' ratios | quartiles | best |")
    print("|---|---|---|---|---|")
    for label, row in result["cases"].items():
        low, high = row["ratio_quartiles"]
        print(f"| {label} | {row['nanoseconds']:.0f} | {row['ratio_median']:.2f} | {low:.2f}–{high:.2f} "
              f"| {row['ratio_best']:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
