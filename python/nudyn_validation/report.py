"""What people read: one PNG per vehicle (a row per scenario: θ and ν
trajectories of both sides, and the errors over time), a markdown table of
the max errors, run times and energy drift, and the same numbers as JSON."""

from __future__ import annotations

import io
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, no display needed
import matplotlib.pyplot as plt
import numpy as np
from PIL import Image  # matplotlib's own dependency

from .compare import ModelValidation, ScenarioResult
from .judgement import AGREES, CHAOTIC, DISAGREES, TWIN_FACTOR, TWIN_NUDGE, TWINS

# Trajectory panels show the components that move most, so that a few lines
# stay readable on vehicles with dozens of dofs.
CURVES_PER_PANEL = 5
MARKER_EVERY = 10  # MuJoCo's samples drawn as dots on every 10th point


def _most_moving(values: np.ndarray) -> np.ndarray:
    spread = np.ptp(values, axis=0)
    return np.sort(np.argsort(spread)[::-1][:CURVES_PER_PANEL])


def _trajectory_panel(ax, time, fmu, mujoco, symbol, unit_note):
    for k in _most_moving(mujoco):
        (line,) = ax.plot(time, fmu[:, k], lw=1.2, label=f"{symbol}[{k + 1}]")
        ax.plot(time[::MARKER_EVERY], mujoco[::MARKER_EVERY, k], "o", ms=2.5, color=line.get_color())
    ax.set_title(f"{symbol}: FMU (lines), MuJoCo (dots){unit_note}", fontsize=9)
    ax.legend(fontsize=6, loc="best", ncol=2)


def _error_panel(ax, result: ScenarioResult):
    floor = 1e-17  # exact agreement would not show on a log scale
    for values, label in (
        (result.theta_error(), "θ"),
        (result.nu_error(), "ν"),
        (result.kinetic_energy_error(), "K"),
        (result.momentum_error(), "momentum"),
        (result.twin_divergence(), "MuJoCo's twin"),
    ):
        ax.semilogy(result.time, np.maximum(values, floor), lw=1.2, label=label)
    ax.axhline(result.scenario.tolerance, color="k", ls="--", lw=0.8, label="θ, ν tolerance")
    ax.set_title("|FMU − MuJoCo| (max over components)", fontsize=9)
    ax.legend(fontsize=6, loc="best", ncol=2)


def plot(validation: ModelValidation, path: Path) -> Path:
    results = validation.results
    fig, axes = plt.subplots(len(results), 3, figsize=(13, 2.7 * len(results)), squeeze=False)
    for row, result in zip(axes, results):
        _trajectory_panel(row[0], result.time, result.fmu.theta, result.mujoco.theta, "θ", "")
        _trajectory_panel(row[1], result.time, result.fmu.nu, result.mujoco.nu, "ν", "")
        _error_panel(row[2], result)
        row[0].set_ylabel(result.scenario.name, fontsize=10, fontweight="bold")
    for ax in axes[-1]:
        ax.set_xlabel("time (s)", fontsize=8)
    for ax in axes.flat:
        ax.tick_params(labelsize=7)
    fig.suptitle(f"{validation.model_path.name}: the FMU in FMPy against MuJoCo", fontsize=11)
    fig.tight_layout()
    rendered = io.BytesIO()
    fig.savefig(rendered, dpi=70)
    plt.close(fig)
    # A 64-colour palette looks the same and takes a quarter of the bytes,
    # which matters for the picture committed to the repository.
    Image.open(rendered).convert("RGB").quantize(colors=64).save(path, optimize=True)
    return path


def _number(x: float | None) -> str:
    return "—" if x is None else f"{x:.1e}"


def table(validation: ModelValidation) -> str:
    s = validation.settings
    params = ", ".join(f"{k} = {v:g}" for k, v in s.parameters().items()) or "its default parameters"
    lines = [
        f"`{validation.model_path.name}`, {s.duration:g} s, communication step {s.communication_step:g} s; "
        f"FMU: method {s.method}, {params}; MuJoCo: RK4, step {s.mujoco_step:g} s.",
        "",
        "| scenario | max θ error | max ν error | max sensordata error | max K error (J) | max momentum error | "
        "energy drift FMU / MuJoCo (J) | FMU time (s) | MuJoCo time (s) | tolerance θ, ν, sensors | "
        "MuJoCo's twin divergence | |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for result in validation.results:
        x = result.summary()
        drift = (
            f"{_number(x['energy_drift_fmu'])} / {_number(x['energy_drift_mujoco'])}"
            if x["energy_drift_fmu"] is not None
            else "—"
        )
        sensors = _number(x["max_sensordata_error"]) if result.mujoco.sensordata.size else "—"
        lines.append(
            f"| {x['scenario']} | {_number(x['max_theta_error'])} | {_number(x['max_nu_error'])} | {sensors} | "
            f"{_number(x['max_kinetic_energy_error'])} | {_number(x['max_momentum_error'])} | {drift} | "
            f"{x['fmu_seconds']:.2f} | {x['mujoco_seconds']:.2f} | {x['tolerance']:.0e} | "
            f"{_number(x['max_twin_divergence'])} | {x['verdict'] if x['passed'] else '**' + x['verdict'] + '**'} |"
        )
    lines += [
        "",
        "Errors are max over time and components, absolute (θ: quaternions up to sign; momentum: "
        "angular and linear, about the world origin; sensordata: relative to max(1, |value|), MuJoCo's "
        "sensors evaluated at the state reached with the inputs held). Energy drift is max |E(t) − E(0)|, "
        "E = K + potential energy of gravity and springs, where E is conserved "
        "(ε = 0, no joint damping and no servo pulling at ctrl = 0). Times are the integration's wall time; MuJoCo's includes "
        "the Python control callback at every RK4 stage. MuJoCo's twins are its same run from qvel moved by "
        f"±{TWIN_NUDGE:g} in every component ({TWINS} of them, the signs drawn differently); the twin divergence is "
        "their largest θ, ν or sensordata distance from MuJoCo. "
        f"Verdict: {AGREES} when the largest θ, ν or sensordata error is within the tolerance; {CHAOTIC} when "
        f"it is not but is within {TWIN_FACTOR:g} × the twin's divergence (MuJoCo cannot hold its own run "
        f"to the tolerance at this step either); {DISAGREES} otherwise.",
        "Scenarios: "
        + "; ".join(f"**{r.scenario.name}**: {r.scenario.description}" for r in validation.results)
        + ".",
    ]
    return "\n".join(lines + modal_table(validation)) + "\n"


def modal_table(validation: ModelValidation) -> list[str]:
    """For a vehicle with modal bodies: what the rows above compare, and the
    modal part (modal_part.py): per scenario the strain energy, the mode
    moved most and how far the modes take the joints from MuJoCo's rigid
    run, then each mode's range."""
    if not validation.modal:
        return []
    summaries = [part.summary() for part in validation.modal]
    lines = [
        "",
        "## The modal part",
        "",
        f"The vehicle has modal bodies, which MuJoCo ignores: the rows above compare the rigid part, the FMU "
        f"with its modes frozen (`{validation.rigid_fmu_path.name}`: the modal files' nodes and no modes), with "
        f"MuJoCo's rigid vehicle. Below, the FMU with its modes (`{validation.fmu_path.name}`) from the same "
        "state with the modes at rest, given the same held inputs (ε on the joints replayed, 0 on the modes; "
        "ctrl and wrenches). It is not judged: the modes are what MuJoCo does not have.",
        "",
        "| scenario | largest strain energy (J) | largest kinetic energy (J) | mode moved most | its largest \\|η\\| "
        "(√kg m) | joints' largest difference from MuJoCo's rigid run |",
        "|---|---|---|---|---|---|",
    ]
    for x in summaries:
        lines.append(
            f"| {x['scenario']} | {_number(x['max_strain_energy'])} | {_number(x['max_kinetic_energy'])} | "
            f"`{x['mode_moved_most']}` | {_number(x['max_abs_eta'])} | "
            f"{_number(x['max_joint_difference_from_rigid_mujoco'])} |"
        )
    lines += [
        "",
        "Each mode's range of η (least, greatest), by scenario:",
        "",
        "| mode | frequency (Hz) | " + " | ".join(x["scenario"] for x in summaries) + " |",
        "|---|---|" + "---|" * len(summaries),
    ]
    for k, mode in enumerate(summaries[0]["modes"]):
        ranges = " | ".join(
            f"{_number(x['modes'][k]['eta_range'][0])}, {_number(x['modes'][k]['eta_range'][1])}" for x in summaries
        )
        lines.append(f"| `{mode['name']}` | {mode['frequency_hz']:.4g} | {ranges} |")
    return lines


def write(validation: ModelValidation, out_dir: Path) -> dict[str, Path]:
    """The PNG, table.md and results.json in out_dir; returns their paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {
        "plot": plot(validation, out_dir / f"{validation.model_path.stem}.png"),
        "table": out_dir / "table.md",
        "json": out_dir / "results.json",
    }
    paths["table"].write_text(table(validation))
    s = validation.settings
    numbers = {
        "model": str(validation.model_path),
        "fmu": str(validation.fmu_path),
        "settings": {
            "duration": s.duration,
            "communication_step": s.communication_step,
            "mujoco_step": s.mujoco_step,
            "method": s.method,
            "fmu_parameters": s.parameters(),
            "seed": s.seed,
        },
        "scenarios": [r.summary() for r in validation.results],
        "passed": validation.passed,
    }
    if validation.modal:
        numbers["rigid_fmu"] = str(validation.rigid_fmu_path)
        numbers["modal"] = [part.summary() for part in validation.modal]
    paths["json"].write_text(json.dumps(numbers, indent=2) + "\n")
    return paths
