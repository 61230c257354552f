"""`python scripts/control_demo.py detumble|arm`: exports the plant and
controller FMUs, closes the loop in FMPy and in libcosim, checks what the
scenario must reach and the Lyapunov bound, writes the plot (docs/control/
by default), the OspSystemStructure.xml and results.json, and prints a table.
Exit status 0 when every check passes, 1 when one fails."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from fmpy import read_model_description  # noqa: E402

from .analysis import Analysis, analyse  # noqa: E402
from .reference import LawParameters, ReferenceLaw  # noqa: E402
from nudyn_driver.locations import CHECKOUT, IN_CHECKOUT, nudyn_binary, output_dir  # noqa: E402

from .scenarios import SCENARIOS, Scenario  # noqa: E402
from .simulators import export, run_fmpy, run_libcosim  # noqa: E402

# V may exceed its value at the step's start by at most the bound, up to
# the plant's integration error (tolerance 1e-8 per second) relative to V(0).
BOUND_SLACK = 1e-7


def law_of(scenario: Scenario, controller_fmu: Path) -> ReferenceLaw:
    """The reference law with the controller FMU's start values and the scenario's settings."""
    description = read_model_description(str(controller_fmu))
    values = {v.name: float(v.start) for v in description.modelVariables if v.causality == "parameter"}
    values |= scenario.controller

    def block(prefix: str) -> np.ndarray:
        return np.array([values[name] for name in values if name.startswith(prefix + "[")])

    target = block("target") if scenario.end_effector is None else np.concatenate(
        [block("target_position"), block("target_quaternion")])
    return ReferenceLaw(scenario.mjcf, scenario.end_effector, LawParameters(block("c1"), block("c2"), target))


def checks(scenario: Scenario, analysis: Analysis) -> dict[str, bool]:
    """What must hold, by name."""
    result = {
        "eps is the law (MuJoCo reference) at the state it was computed from": analysis.law_mismatch < 1e-7,
        "V stays within the sample-and-hold bound": analysis.bound_violation <= BOUND_SLACK,
        "worst increase of V within the c h bound": bool(np.all(analysis.increase <= analysis.ch_bound + BOUND_SLACK * analysis.lyapunov[0])),
    }
    if scenario.nu_tolerance is not None:
        result[f"|nu| < {scenario.nu_tolerance:g} at the end"] = analysis.speed[-1] < scenario.nu_tolerance
    if scenario.position_tolerance is not None:
        result[f"position error < {scenario.position_tolerance:g} m at the end"] = \
            analysis.position_error[-1] < scenario.position_tolerance
        result[f"rotation error < {scenario.rotation_tolerance:g} rad at the end"] = \
            analysis.rotation_error[-1] < scenario.rotation_tolerance
    return result


def run(scenario: Scenario, nudyn: Path, workdir: Path) -> tuple[list[Analysis], Path]:
    plant, controller = export(nudyn, scenario, workdir)
    law = law_of(scenario, controller)
    analyses = [analyse(runner(plant, controller, scenario, workdir), law) for runner in (run_fmpy, run_libcosim)]
    return analyses, workdir / "libcosim" / "OspSystemStructure.xml"


COLORS = {"FMPy": "tab:blue", "libcosim": "tab:orange"}


def plot(scenario: Scenario, analyses: list[Analysis], path: Path) -> None:
    pose = scenario.end_effector is not None
    figure, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    for a in analyses:
        style = {"color": COLORS[a.simulator], "label": a.simulator,
                 "linestyle": "-" if a.simulator == "FMPy" else "--"}
        axes[0].semilogy(a.time, np.maximum(a.speed, 1e-16), **style)
        axes[1].semilogy(a.time, np.maximum(a.lyapunov, 1e-30), **style)
        starts = a.time[:: a.substeps][:-1]
        axes[2].semilogy(starts, np.maximum(a.bound, 1e-30), color=COLORS[a.simulator], linewidth=0.8,
                         label=f"{a.simulator}: bound B_k (sample and hold)")
        rising = a.increase > 0
        if not np.any(rising):
            axes[2].plot([], [], " ", label=f"{a.simulator}: V never rises within a step")
        else:
            axes[2].semilogy(starts[rising], a.increase[rising], "o", color=COLORS[a.simulator], markersize=3,
                             label=f"{a.simulator}: increase of V within step k")
        if pose:
            axes[0].semilogy(a.time, np.maximum(a.position_error, 1e-16), color=COLORS[a.simulator], linestyle=":",
                             label=f"{a.simulator}: |position error| (m)")
            axes[0].semilogy(a.time, np.maximum(a.rotation_error, 1e-16), color=COLORS[a.simulator], linestyle="-.",
                             label=f"{a.simulator}: |rotation error| (rad)")
    axes[0].set_title("|nu|" + (" and the end effector's errors" if pose else ""))
    axes[1].set_title("V = K + U (" + ("U = 1/2 dY^T c2 dY" if pose else "U = 0: V = K") + ")")
    axes[2].set_title("V(t) - V(t_k) within each controller step")
    if scenario.nu_tolerance:
        axes[0].axhline(scenario.nu_tolerance, color="gray", linewidth=0.8)
    # The arm starts at rest: leave out the drop of |nu| from 0 at t = 0.
    axes[0].set_ylim(bottom=1e-12)
    for ax in axes:
        ax.set_xlabel("t (s)")
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=7)
    figure.suptitle(scenario.title + f"; h = {scenario.step} s, plant sampled every h/{scenario.substeps}", fontsize=10)
    figure.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=110)
    plt.close(figure)


def table(scenario: Scenario, analyses: list[Analysis], passed: dict[str, dict[str, bool]]) -> str:
    rows = ["| simulator | delay (steps of h) | eps vs reference law | worst increase of V within a step (J) | sample-and-hold bound there (J) | c h bound there (J) | final abs(nu) | final position / rotation error | wall time (s) | checks |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for a in analyses:
        s = a.summary()
        errors = "—" if s["final_position_error"] is None else \
            f"{s['final_position_error']:.1e} m / {s['final_rotation_error']:.1e} rad"
        ok = "pass" if all(passed[a.simulator].values()) else "FAIL"
        rows.append(f"| {a.simulator} | {a.delay} | {s['law_mismatch']:.0e} | {s['worst_increase']:.2e} | "
                    f"{s['bound_there']:.2e} | {s['ch_bound_there']:.2e} | {s['final_speed']:.1e} | {errors} | "
                    f"{s['wall_time']:.2f} | {ok} |")
    return "\n".join(rows)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenario", choices=sorted(SCENARIOS))
    parser.add_argument("--nudyn", type=Path, default=nudyn_binary())
    parser.add_argument("--plot", type=Path, help="the picture (default docs/control/SCENARIO.png)")
    parser.add_argument("--out", type=Path, help="FMUs, OspSystemStructure.xml, results.json (default out/control/SCENARIO)")
    args = parser.parse_args(argv)
    scenario = SCENARIOS[args.scenario]()
    out = args.out or output_dir("control", scenario.name)
    analyses, structure = run(scenario, args.nudyn.resolve(), out)
    passed = {a.simulator: checks(scenario, a) for a in analyses}
    picture = args.plot or (CHECKOUT / "docs" / "control" if IN_CHECKOUT else out) / f"{scenario.name}.png"
    plot(scenario, analyses, picture)
    results = {"scenario": scenario.name, "title": scenario.title,
               "runs": [{**a.summary(), "checks": passed[a.simulator]} for a in analyses]}
    (out / "results.json").write_text(json.dumps(results, indent=2, default=float))
    print(scenario.title)
    print(table(scenario, analyses, passed))
    for simulator, result in passed.items():
        for name, ok in result.items():
            print(f"  {simulator}: {'pass' if ok else 'FAIL'}: {name}")
    print(f"plot: {picture}\nsystem structure: {structure}\nresults: {out / 'results.json'}")
    return 0 if all(all(r.values()) for r in passed.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
