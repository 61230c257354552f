"""The suite's table (markdown) and numbers (JSON)."""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

from .cases import CaseResult


def _number(x) -> str:
    return "—" if x is None else f"{x:.1e}"


def _steps(x) -> str:
    return "—" if x is None or x != x else f"{x:.3g}"


def summary_table(results: list[CaseResult]) -> str:
    lines = ["| case | what was checked | verdict |", "|---|---|---|"]
    for r in results:
        lines.append(f"| {r.title} | {r.checked} | {'pass' if r.passed else '**FAIL**'}: {r.verdict} |")
    return "\n".join(lines) + "\n"


def case_table(result: CaseResult) -> str:
    lines = [
        f"### {result.title}",
        "",
        f"Checked: {result.checked}. Verdict: **{'pass' if result.passed else 'FAIL'}**, {result.verdict}.",
        f"Figure: `{result.figure.name}`.",
        "",
        "| set-up | outcome | max error | K drift | momentum drift | energy residual | steps/s | wall (s) | note |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for row in result.rows:
        wall = "—" if row.wall is None else f"{row.wall:.2f}"
        lines.append(
            f"| {row.setup} | {row.outcome} | {_number(row.error)} | {_number(row.k_drift)} | "
            f"{_number(row.momentum_drift)} | {_number(row.residual)} | {_steps(row.steps_per_second)} | {wall} | {row.note} |"
        )
    return "\n".join(lines) + "\n"


LEGEND = (
    "Max error: max over time and components of |x − x_ref| / (1 + |x_ref|) for θ and ν (quaternions up "
    "to sign), the measure the FMU's tolerance uses, against the case's reference. K drift: max |K − K₀|/K₀ "
    "(where K is conserved). Momentum drift: max(|ΔL|/|L₀|, |Δp|/|p₀|). Energy residual: max |K − K₀ − ∫ν·ν̇ dt| / K₀, "
    "the integration's energy error. Steps/s: internal steps (taken and rejected) per simulated second, as the "
    "FMU reports them in its logStepStatistics messages. "
    "Wall: seconds spent in fmi2DoStep. Defaults: dop853, tolerance 1e-8 per second, no max_step."
)


def write(results: list[CaseResult], out_dir: Path, long: bool) -> dict[str, Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    mode = "long" if long else "short"
    text = [f"# nudyn stress suite ({mode} mode)", "", summary_table(results), LEGEND, ""]
    text += [case_table(r) for r in results]
    paths = {"table": out_dir / "stress.md", "json": out_dir / "stress.json"}
    paths["table"].write_text("\n".join(text))
    numbers = {
        "mode": mode,
        "cases": [
            {
                "key": r.key,
                "title": r.title,
                "checked": r.checked,
                "passed": r.passed,
                "verdict": r.verdict,
                "figure": os.path.relpath(r.figure, out_dir),
                "rows": [dataclasses.asdict(row) for row in r.rows],
                "numbers": r.numbers,
            }
            for r in results
        ],
    }
    paths["json"].write_text(json.dumps(numbers, indent=2, default=float) + "\n")
    return paths
