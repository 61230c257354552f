#!/usr/bin/env python3
"""ros34pw2 with each source of its W (issue 48, item 4), side by side in
one `nudyn-bench` process per vehicle: the default (θ̈'s derivatives in
closed form where they cover the vehicle, else forward differences), `exact` (closed form, else dual numbers) and `differences`;
steps, θ̈ evaluations, W formed, wall time (median of the repetitions) and
the error against dop853 at 1e-13 (largest |x − x_ref| / (1 + |x_ref|)
over θ, quaternions up to sign, and θ̇ at the 0.1 s points); and the cost
of one W of each kind in ν̇ evaluations (`nudyn-bench eval-cost`, the
cases timed interleaved).

    .venv/bin/python scripts/bench_ros_jacobian.py [--repetitions 3] [--out FILE.json] [VEHICLE ...]

VEHICLE: damped_stiff_boom, servicer, docked_servicer, bus_arm7 (default: all).
"""

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import mujoco
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))

from nudyn_bench.tolerance import scaled_error  # noqa: E402
from nudyn_bench.vehicles import prepare  # noqa: E402
from nudyn_validation.mujoco_reference import MujocoFactor  # noqa: E402

BENCH = ROOT / "target" / "release" / "nudyn-bench"
TOLERANCES = [1e-4, 1e-6, 1e-8, 1e-10]


def boom_state(work: Path) -> tuple[str, Path, Path, mujoco.MjModel]:
    """The damped stiff boom as tests/all/stiff_integration.rs starts it:
    the bus tumbling, the boom on its rest shape, the array turning."""
    path = ROOT / "tests" / "fixtures" / "damped_stiff_boom.xml"
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    half_yaw = 0.1
    data.qpos[:] = [0.5, -0.3, 1.0, np.cos(half_yaw), 0, 0, np.sin(half_yaw), 0, 0.02, 0, -0.03, 0.01, 0, 0, 0]
    data.qvel[:] = [0, 0, 0, 0.05, 0.1, -0.08, 0.1, 0, 0, 0, 0, 0, 0.2, -0.1]
    return at_state("damped_stiff_boom", path, work, model, data)


def docked_state(work: Path) -> tuple[str, Path, Path, mujoco.MjModel]:
    """The docked servicer at its file pose (welds closed), tumbling slowly."""
    path = ROOT / "tests" / "fixtures" / "constraints" / "docked_servicer.xml"
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    data.qvel[:] = 0.05 * np.cos(np.arange(model.nv) + 1.0)
    return at_state("docked_servicer", path, work, model, data)


def at_state(name: str, path: Path, work: Path, model: mujoco.MjModel, data: mujoco.MjData):
    mujoco.mj_forward(model, data)
    nu = MujocoFactor(model).nu(data, data.qvel)
    state = work / f"{name}.state.json"
    state.write_text(json.dumps({"theta": list(map(float, data.qpos)), "nu": list(map(float, nu)),
                                 "qvel": list(map(float, data.qvel))}))
    return name, path, state, model


def example_state(name: str, work: Path):
    vehicle = prepare(name, ROOT / "examples" / f"{name}.xml", work)
    return name, vehicle.path, vehicle.state_path, vehicle.model


def simulate(path: Path, state: Path, runs: list[str], repetitions: int, samples: bool = True) -> list[dict]:
    cmd = [str(BENCH), "simulate", str(path), "--state", str(state), "--duration", "10", "--sample", "0.1",
           "--repetitions", str(repetitions)] + [a for run in runs for a in ("--run", run)]
    if not samples:
        cmd.append("--no-samples")
    return json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)


def w_costs(path: Path, state: Path) -> dict:
    cmd = [str(BENCH), "eval-cost", str(path), "--state", str(state), "--repetitions", "15"]
    result = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
    median = {name: float(np.median(times)) for name, times in result["nanoseconds"].items()}
    nu_dot = median["nudyn"]
    pick = lambda prefix: next((v for k, v in median.items() if k.startswith(prefix)), float("nan"))  # noqa: E731
    return {"nv": result["nv"], "nu_dot_ns": nu_dot,
            "qacc_in_nu_dot": pick("nudyn qacc") / nu_dot,
            "closed_form_w_in_nu_dot": pick("nudyn θ̈ Jacobians in θ and θ̇ (closed form)") / nu_dot,
            "exact_w_in_nu_dot": pick("nudyn ros34pw2 W from exact") / nu_dot,
            "differences_w_in_nu_dot": pick("nudyn ros34pw2 W by forward") / nu_dot}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repetitions", type=int, default=3)
    parser.add_argument("--out", type=Path)
    parser.add_argument("vehicles", nargs="*")
    args = parser.parse_args()
    results = []
    with tempfile.TemporaryDirectory() as work:
        work = Path(work)
        vehicles = {"damped_stiff_boom": lambda: boom_state(work), "servicer": lambda: example_state("servicer", work),
                    "docked_servicer": lambda: docked_state(work), "bus_arm7": lambda: example_state("bus_arm7", work)}
        unknown = set(args.vehicles) - set(vehicles)
        if unknown:
            parser.error(f"unknown vehicles {sorted(unknown)}; known: {', '.join(vehicles)}")
        for key in args.vehicles or list(vehicles):
            name, path, state, model = vehicles[key]()
            costs = w_costs(path, state)
            closed_form = (f"{costs['closed_form_w_in_nu_dot']:.1f} ν̇" if np.isfinite(costs["closed_form_w_in_nu_dot"])
                           else "not covered")
            print(f"{name}: nv {costs['nv']}, ν̇ {costs['nu_dot_ns']:.0f} ns; θ̈ {costs['qacc_in_nu_dot']:.2f} ν̇; "
                  f"W in closed form {closed_form}, "
                  f"by dual numbers {costs['exact_w_in_nu_dot']:.1f} ν̇, by differences "
                  f"{costs['differences_w_in_nu_dot']:.1f} ν̇", flush=True)
            reference = simulate(path, state, ["dop853:1e-13"], 1)[0]
            ref_qpos, ref_qvel = np.array(reference["qpos"]), np.array(reference["qvel"])
            rows = []
            for tolerance in TOLERANCES:
                sources = ["default", "exact", "differences"]
                runs = simulate(path, state, [f"ros34pw2:{tolerance:g}", f"ros34pw2/exact:{tolerance:g}",
                                              f"ros34pw2/differences:{tolerance:g}"], args.repetitions)
                row = {"tolerance": tolerance}
                for key, run in zip(sources, runs):
                    n = len(run["qpos"])
                    error = scaled_error(model, run["qpos"], run["qvel"], ref_qpos[:n], ref_qvel[:n])
                    row[key] = {k: run[k] for k in ("accepted", "rejected", "evaluations", "jacobians",
                                                     "exact_jacobians", "failed")}
                    row[key]["seconds"] = float(np.median(run["seconds"]))
                    row[key]["error"] = error
                    row[key]["reached"] = run["time"][-1]
                    row[key]["evaluations_per_step"] = run["evaluations"] / max(1, run["accepted"] + run["rejected"])
                rows.append(row)
                print(f"  {tolerance:g}:", " | ".join(
                    f"{key} {r['accepted']}+{r['rejected']} steps, {r['evaluations']} θ̈ "
                    f"({r['evaluations_per_step']:.2f}/step), W {r['jacobians']} ({r['exact_jacobians']} exact), "
                    f"{r['seconds'] * 1e3:.0f} ms, error/tol {r['error'] / tolerance:.2g}, reached {r['reached']:g}"
                    for key, r in ((key, row[key]) for key in sources)), flush=True)
            results.append({"vehicle": name, "costs": costs, "rows": rows})
    if args.out:
        args.out.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
