"""The campaign's summary: OUT/report.md with the metrics' distributions,
the failed and the worst cases, and for each grid dispersion the metrics
per grid value; OUT/metrics.png (histograms and CDFs) and, per grid
dispersion, OUT/KEY.png (settling time against the grid value, the plot a
GNC engineer draws from a gain sweep)."""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pyarrow as pa  # noqa: E402

from .files import write_atomically  # noqa: E402
from .metrics import NAMES  # noqa: E402

WORST = 10


def _values(table: pa.Table, column: str) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in table.column(column).to_pylist()], float)


def grid_plot_name(key: str) -> str:
    """The file name of the plot of grid dispersion `key` (OUT/KEY.png)."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", key).strip("_") + ".png"


def write_report(campaign, table: pa.Table, out: Path) -> None:
    metrics = [m for m in NAMES if m in table.column_names and np.any(np.isfinite(_values(table, m)))]
    status = table.column("status").to_pylist() if table.num_rows else []
    ok = sum(s == "ok" for s in status)
    lines = [
        f"# Campaign {campaign.name}",
        "",
        f"{table.num_rows} of {campaign.cases} cases run: {ok} ok, {table.num_rows - ok} failed. "
        f"Model {campaign.source.name}, {campaign.duration:g} s at a {campaign.step:g} s communication step"
        + (", closed loop with the controller FMU" if campaign.controller else "")
        + f"; campaign seed {campaign.seed}.",
        "",
        "| metric | median | 95 % | max | cases with a value |",
        "|---|---|---|---|---|",
    ]
    for metric in metrics:
        v = _values(table, metric)
        finite = v[np.isfinite(v)]
        lines.append(
            f"| {metric} | {np.median(finite):.4g} | {np.percentile(finite, 95):.4g} | {np.max(finite):.4g} | {finite.size} |"
        )
    failed = [i for i, s in enumerate(status) if s != "ok"]
    if failed:
        lines += ["", "## Failed cases", "", "| case | status | message |", "|---|---|---|"]
        cases, messages = table.column("case").to_pylist(), table.column("message").to_pylist()
        lines += [f"| {cases[i]} | {status[i]} | {messages[i]} |" for i in failed[:WORST]]
    if "settling_time" in metrics:
        settling = _values(table, "settling_time")
        order = np.argsort(np.where(np.isfinite(settling), settling, np.inf))[::-1][:WORST]
        keys = campaign.columns()
        lines += ["", "## Worst cases (longest settling time; never settled first)", "",
                  "| case | settling_time | peak_nu | " + " | ".join(keys) + " |",
                  "|---|---|---|" + "---|" * len(keys)]
        rows = table.to_pylist()
        for i in order:
            row = rows[i]
            drawn = " | ".join(_short(row[k]) for k in keys)
            lines.append(f"| {row['case']} | {_short(row['settling_time'])} | {_short(row['peak_nu'])} | {drawn} |")
    for dispersion in campaign.dispersions:
        if dispersion.distribution != "grid" or "settling_time" not in metrics:
            continue
        lines += _grid_section(table, dispersion.key, metrics, out)
    _plot_metrics(table, metrics, out / "metrics.png")
    lines += ["", "![histograms and CDFs of the metrics](metrics.png)", ""]
    write_atomically(out / "report.md", lambda temporary: temporary.write_text("\n".join(lines)))


def _short(value) -> str:
    if isinstance(value, list):
        return "[" + ", ".join(f"{v:.3g}" for v in value) + "]"
    if value is None:
        return "—"
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def _grid_section(table: pa.Table, key: str, metrics: list[str], out: Path) -> list[str]:
    grid = _values(table, key)
    levels = np.unique(grid[np.isfinite(grid)])
    settling = _values(table, "settling_time")
    lines = ["", f"## Against {key}", "", f"| {key} | cases | settled | median settling_time | 95 % settling_time |",
             "|---|---|---|---|---|"]
    medians, p95 = [], []
    for level in levels:
        chosen = settling[grid == level]
        finite = chosen[np.isfinite(chosen)]
        medians.append(np.median(finite) if finite.size else np.nan)
        p95.append(np.percentile(finite, 95) if finite.size else np.nan)
        lines.append(f"| {level:g} | {chosen.size} | {finite.size} | {medians[-1]:.4g} | {p95[-1]:.4g} |")
    figure, axis = plt.subplots(figsize=(6, 4))
    axis.plot(grid, settling, ".", alpha=0.3, label="cases")
    axis.plot(levels, medians, "o-", label="median")
    axis.plot(levels, p95, "s--", label="95th percentile")
    axis.set_xscale("log" if levels.size and np.all(levels > 0) else "linear")
    axis.set_xlabel(key)
    axis.set_ylabel("settling time (s)")
    axis.legend()
    figure.tight_layout()
    name = grid_plot_name(key)
    write_atomically(out / name, lambda temporary: figure.savefig(temporary, dpi=110, format="png"))
    plt.close(figure)
    return lines + ["", f"![settling time against {key}]({name})"]


def _plot_metrics(table: pa.Table, metrics: list[str], path: Path) -> None:
    figure, axes = plt.subplots(max(1, len(metrics)), 2, figsize=(9, 2.4 * max(1, len(metrics))), squeeze=False)
    for row, metric in enumerate(metrics):
        v = _values(table, metric)
        v = v[np.isfinite(v)]
        axes[row, 0].hist(v, bins=30)
        axes[row, 0].set_ylabel(metric)
        axes[row, 1].plot(np.sort(v), np.linspace(0, 1, v.size), drawstyle="steps-post")
        axes[row, 1].set_ylabel("CDF")
    figure.tight_layout()
    write_atomically(path, lambda temporary: figure.savefig(temporary, dpi=100, format="png"))
    plt.close(figure)
