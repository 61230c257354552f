"""One figure per case, written small (low dpi, a 64-colour palette) so
that the ones shown in docs/stress.md can be committed."""

from __future__ import annotations

import io
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only
import matplotlib.pyplot as plt
import numpy as np
from PIL import Image  # matplotlib's own dependency

from .measures import energy_residual, kinetic_energy_drift, momentum_drift, scaled_error

# Exact agreement would not show on a log scale.
FLOOR = 1e-17


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    rendered = io.BytesIO()
    fig.savefig(rendered, dpi=60)
    plt.close(fig)
    Image.open(rendered).convert("RGB").quantize(colors=64).save(path, optimize=True)
    return path


def _log_panel(ax, title, ylabel=None):
    ax.set_yscale("log")
    ax.set_title(title, fontsize=9)
    ax.set_xlabel("time (s)", fontsize=8)
    if ylabel:
        ax.set_ylabel(ylabel, fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(True, which="major", lw=0.3)


def _style(setup):
    """Energy-projected runs dashed."""
    return {"ls": "--" if setup.energy_projection else "-", "lw": 1.1}


def drift_figure(path: Path, runs, title: str, energy: str = "k") -> Path:
    """Energy (K drift, or the energy residual where forces do work) and
    momentum drift against time, one line per set-up."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8))
    colours = {}
    for run in runs:
        key = (run.setup.method, run.setup.tolerance, run.setup.max_step)
        colour = colours.setdefault(key, f"C{len(colours)}")
        values = kinetic_energy_drift(run) if energy == "k" else energy_residual(run)
        axes[0].plot(run.time, np.maximum(values, FLOOR), color=colour, label=run.setup.label(), **_style(run.setup))
        axes[1].plot(run.time, np.maximum(momentum_drift(run), FLOOR), color=colour, **_style(run.setup))
    _log_panel(axes[0], "|K − K₀| / K₀" if energy == "k" else "|energy residual| / K₀  (K − K₀ − work)")
    _log_panel(axes[1], "momentum drift: max(|ΔL|/|L₀|, |Δp|/|p₀|)")
    axes[0].legend(fontsize=6, ncol=2, loc="lower right")
    fig.suptitle(title, fontsize=10)
    return _save(fig, path)


def error_figure(path: Path, series: dict, title: str, ylabel: str = "max |x − x_ref| / (1 + |x_ref|)") -> Path:
    fig, ax = plt.subplots(figsize=(8, 4))
    for label, (time, error) in series.items():
        ax.plot(time, np.maximum(error, FLOOR), lw=1.1, label=label, ls="--" if "sine" in label else "-")
    _log_panel(ax, title, ylabel)
    ax.legend(fontsize=6, ncol=2, loc="best")
    return _save(fig, path)


def stiff_figure(path: Path, runs, reference, bends, omega: float, title: str) -> Path:
    """The first boom hinge against time (how RK4 at the default step goes
    unstable), and each run's error against the reference."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8))
    time = np.array(reference.time)
    axes[0].plot(time, np.array(reference.theta)[:, bends[0]], color="k", lw=2.5, alpha=0.3, label="reference")
    for run in runs:
        theta = np.array(run.theta)[:, bends[0]]
        (line,) = axes[0].plot(run.time, theta, lw=1.0, label=run.setup.label())
        error = scaled_error(run, reference, [])
        axes[1].plot(run.time[: len(error)], np.maximum(error, FLOOR), lw=1.0, color=line.get_color())
        if not run.completed:
            axes[0].plot(run.time[-1], theta[-1], "x", color=line.get_color(), ms=8)
    reference_range = np.ptp(np.array(reference.theta)[:, bends[0]])
    middle = np.mean(np.array(reference.theta)[:, bends[0]])
    axes[0].set_ylim(middle - 3 * reference_range, middle + 3 * reference_range)
    axes[0].set_title("boom_bend1 (rad); × where a run was discarded", fontsize=9)
    axes[0].set_xlabel("time (s)", fontsize=8)
    axes[0].tick_params(labelsize=7)
    axes[0].legend(fontsize=6, loc="upper right")
    _log_panel(axes[1], "scaled error against dop853 at 1e-12")
    fig.suptitle(title, fontsize=10)
    return _save(fig, path)


def sweep_figure(path: Path, sweep: dict, comm_step: float) -> Path:
    fig, ax = plt.subplots(figsize=(7, 3.5))
    for method in (key for key in sweep if key != "exponents"):
        ax.plot(sweep["exponents"], np.array(sweep[method]) / comm_step, "o-", ms=3, lw=1, label=method)
    ax.set_xlabel("log10 |ε| (every dof)", fontsize=8)
    ax.set_ylabel("fraction of the doStep completed", fontsize=8)
    ax.set_title(f"one doStep of {comm_step:g} s with a huge held ε: where it stops (fmi2Discard below 1)", fontsize=9)
    ax.tick_params(labelsize=7)
    ax.legend(fontsize=7)
    ax.grid(True, lw=0.3)
    return _save(fig, path)
