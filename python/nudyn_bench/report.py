"""From the raw timings of results.json to the summary (medians, ratios
per repetition, scaling exponent, the targets), table.md and the plots."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the backend)
import numpy as np  # noqa: E402

from .work_precision import time_at_error  # noqa: E402

MJ_FORWARD = "mj_forward"
MJ_STAGES = "mj_fwdPosition+Velocity+Acceleration"
MJ_SMOOTH = "mj_kinematics+comPos+makeM+factorM+fwdVelocity+fwdAcceleration"
TARGET_ERROR = 1e-6
SHORTCUTS = ["no_gravity", "no_springs", "no_dampers", "no_armature"]


def median(values) -> float:
    return float(np.median(values))


def paired_ratio(numerator, denominator) -> float:
    """Median over repetitions of the ratio within each repetition."""
    return float(np.median(np.asarray(numerator) / np.asarray(denominator)))


# The cases `nudyn-bench eval-cost` times for a vehicle with actuators or sensors.
PORT_CASES = {
    "stripped of actuators and sensors": "nudyn stripped of actuators and sensors",
    "with actuators": "nudyn with actuators",
    "with actuators and sensors": "nudyn with actuators and sensors",
}


def cost_row(entry: dict) -> dict:
    ns = entry["nanoseconds"]
    row = {"nv": entry["nv"], "nudyn_ns": median(ns["nudyn"])}
    for key, name in (("mj_forward", MJ_FORWARD), ("mj_stages", MJ_STAGES), ("mj_smooth", MJ_SMOOTH), ("dense", "dense")):
        if name in ns:
            row[f"{key}_ns"] = median(ns[name])
            row[f"{key}_over_nudyn"] = paired_ratio(ns[name], ns["nudyn"])
    pin = entry.get("pinocchio", {})
    if pin.get("converts"):
        row["pinocchio_aba_ns"] = median(pin["nanoseconds"])
        row["pinocchio_call_floor_ns"] = median(pin["one_hinge_nanoseconds"])
    else:
        row["pinocchio_problem"] = pin.get("problem")
    if entry.get("dense_difference") is not None:
        row["dense_difference"] = entry["dense_difference"]
    # What each shortcut buys: time without it over time with all.
    row["shortcuts"] = {}
    for shortcut in SHORTCUTS:
        name = f"nudyn without {shortcut}"
        if name in ns:
            row["shortcuts"][shortcut] = paired_ratio(ns[name], ns["nudyn"])
    if "nudyn without shortcuts" in ns:
        row["shortcuts"]["all"] = paired_ratio(ns["nudyn without shortcuts"], ns["nudyn"])
    # What the physical ports cost: time of each case over plain ν̇.
    row["ports"] = {
        name: paired_ratio(ns[case], ns["nudyn"])
        for name, case in PORT_CASES.items()
        if case in ns
    }
    return row


def scaling_exponent(links, times) -> float:
    """Least-squares slope of log(time) against log(N)."""
    return float(np.polyfit(np.log(links), np.log(times), 1)[0])


def summarize(results: dict) -> dict:
    summary = {"eval_cost": {name: cost_row(e) for name, e in results["eval_cost"].items()}}
    chains = sorted(results["scaling"].values(), key=lambda e: e["links"])
    scaling = {"links": [e["links"] for e in chains], "rows": [cost_row(e) for e in chains]}
    links = np.array(scaling["links"], float)
    nudyn = np.array([r["nudyn_ns"] for r in scaling["rows"]])
    large = links >= min(100, links.max())
    scaling["nudyn_exponent"] = scaling_exponent(links[large], nudyn[large])
    mj = np.array([r.get("mj_forward_ns", np.nan) for r in scaling["rows"]])
    with_mj = large & np.isfinite(mj)
    scaling["mj_forward_exponent"] = scaling_exponent(links[with_mj], mj[with_mj]) if with_mj.sum() >= 2 else None
    if 200 in scaling["links"] and 2000 in scaling["links"]:
        scaling["ratio_2000_over_200_separate_runs"] = float(nudyn[scaling["links"].index(2000)] / nudyn[scaling["links"].index(200)])
    pair = results.get("scaling_side_by_side")
    if pair:
        (small, large), (small_ns, large_ns) = pair["links"], pair["nanoseconds"]
        scaling["side_by_side"] = {
            "links": [small, large],
            "nudyn_ns": [median(small_ns), median(large_ns)],
            "ratio": paired_ratio(large_ns, small_ns),
        }
    summary["scaling"] = scaling

    summary["work_precision"] = {name: work_precision_summary(wp) for name, wp in results["work_precision"].items()}

    f = results.get("fmi")
    if f:
        s = f["seconds"]
        summary["fmi"] = {
            "native_us_per_step": median(s["native"]) / f["steps"] * 1e6,
            "fmpy_do_step_us_per_step": median(s["fmpy_do_step"]) / f["steps"] * 1e6,
            "fmpy_with_io_us_per_step": median(s["fmpy_with_io"]) / f["steps"] * 1e6,
            "overhead_do_step_us": (median(s["fmpy_do_step"]) - median(s["native"])) / f["steps"] * 1e6,
            "overhead_with_io_us": (median(s["fmpy_with_io"]) - median(s["native"])) / f["steps"] * 1e6,
            "fmpy_do_step_over_native": paired_ratio(s["fmpy_do_step"], s["native"]),
        }
    summary["targets"] = targets(summary)
    return summary


def work_precision_summary(wp: dict) -> dict:
    """Wall time at max error 1e-6 of each method, the best of each side, their ratio."""
    families = {}
    for side in ("nudyn", "mujoco"):
        for run, entry in wp[side].items():
            family = f"{'nudyn' if side == 'nudyn' else 'MuJoCo'} {run.split(':')[0]}"
            families.setdefault(family, []).append((entry["error"], median(entry["seconds"])))
    at_target = {family: time_at_error(points, TARGET_ERROR) for family, points in families.items()}
    best = {}
    for side in ("nudyn", "MuJoCo"):
        reached = {f: t for f, t in at_target.items() if f.startswith(side) and t is not None}
        best[side] = min(reached.items(), key=lambda kv: kv[1]) if reached else None
    out = {"seconds_at_1e-6": at_target, "best": best}
    if best["nudyn"] and best["MuJoCo"]:
        out["nudyn_over_mujoco"] = best["nudyn"][1] / best["MuJoCo"][1]
    return out


def targets(summary: dict) -> dict:
    out = {}
    ratios = {n: r["mj_forward_over_nudyn"] for n, r in summary["eval_cost"].items() if "mj_forward_over_nudyn" in r}
    out["nu_dot_not_slower_than_mj_forward"] = {
        "mj_forward_over_nudyn": ratios,
        "met": bool(ratios) and all(r >= 1.0 for r in ratios.values()),
    }
    ratios = {name: wp.get("nudyn_over_mujoco") for name, wp in summary["work_precision"].items()}
    out["half_of_mujoco_best_at_1e-6"] = {
        "nudyn_over_mujoco": ratios,
        "met": bool(ratios) and all(r is not None and r < 0.5 for r in ratios.values()),
    }
    # Judged on the two chains timed side by side (the separate runs' ratio is reported beside it).
    pair = summary["scaling"].get("side_by_side")
    scaling_ratio = pair["ratio"] if pair and pair["links"] == [200, 2000] else None
    out["linear_scaling"] = {
        "ratio_2000_over_200": scaling_ratio,
        "ratio_2000_over_200_separate_runs": summary["scaling"].get("ratio_2000_over_200_separate_runs"),
        "exponent": summary["scaling"]["nudyn_exponent"],
        "met": scaling_ratio is not None and scaling_ratio <= 11.0,
    }
    return out


def _us(ns) -> str:
    return "—" if ns is None else f"{ns / 1e3:.2f}"


def _ratio(value) -> str:
    return "—" if value is None else f"{value:.2f}"


def targets_text(summary: dict) -> str:
    t = summary["targets"]
    a, b, c = t["nu_dot_not_slower_than_mj_forward"], t["half_of_mujoco_best_at_1e-6"], t["linear_scaling"]
    ratios = ", ".join(f"{n} {r:.2f}" for n, r in a["mj_forward_over_nudyn"].items())
    return "\n".join(
        [
            f"- ν̇ no slower than mj_forward: {'met' if a['met'] else 'NOT met'} (mj_forward time / nudyn time: {ratios})",
            f"- at max error 1e-6 over 10 s, under half of MuJoCo's best wall time: {'met' if b['met'] else 'NOT met'} "
            f"(nudyn's best / MuJoCo's best: {', '.join(f'{n} {_ratio(r)}' for n, r in b['nudyn_over_mujoco'].items())})",
            f"- linear scaling, time(N=2000) ≤ 11 × time(N=200): {'met' if c['met'] else 'NOT met'} "
            f"(ratio {_ratio(c['ratio_2000_over_200'])}, the two timed side by side; from their separate runs in the "
            f"scaling table {_ratio(c['ratio_2000_over_200_separate_runs'])}; fitted exponent {c['exponent']:.2f})",
        ]
    )


def table(results: dict) -> str:
    s = results["summary"]
    lines = [
        f"Measured {results['date']} at commit {results['commit']} on {results['machine']['processor']} "
        f"({results['machine']['platform']}); MuJoCo {results['versions']['mujoco']}, Pinocchio {results['versions']['pinocchio']}."
        + (" **Quick run: the numbers mean nothing.**" if results["quick"] else ""),
        "",
        "### Targets",
        "",
        targets_text(s),
        "",
        "### One evaluation (µs, medians; ratios are medians of per-repetition ratios)",
        "",
        "| vehicle | nv | nudyn ν̇ | mj_forward | MuJoCo stages | MuJoCo smooth | mj_forward / nudyn | smooth / nudyn | pin.aba from Python (floor) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in s["eval_cost"].items():
        pin = f"{_us(r['pinocchio_aba_ns'])} ({_us(r['pinocchio_call_floor_ns'])})" if "pinocchio_aba_ns" in r else "does not convert"
        lines.append(
            f"| {name} | {r['nv']} | {_us(r['nudyn_ns'])} | {_us(r.get('mj_forward_ns'))} | {_us(r.get('mj_stages_ns'))} | "
            f"{_us(r.get('mj_smooth_ns'))} | {_ratio(r.get('mj_forward_over_nudyn'))} | {_ratio(r.get('mj_smooth_over_nudyn'))} | {pin} |"
        )
    problems = [f"{n}: {r['pinocchio_problem']}" for n, r in s["eval_cost"].items() if r.get("pinocchio_problem")]
    if problems:
        lines += ["", "Pinocchio: " + "; ".join(problems) + "."]
    lines += [
        "",
        "### What each shortcut buys (time with it turned off / time with all taken)",
        "",
        "| vehicle | " + " | ".join(SHORTCUTS) + " | all |",
        "|---|" + "---|" * (len(SHORTCUTS) + 1),
    ]
    for name, r in s["eval_cost"].items():
        cells = [_ratio(r["shortcuts"].get(k)) if k in r["shortcuts"] else "not taken" for k in SHORTCUTS + ["all"]]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    ported = {name: r["ports"] for name, r in s["eval_cost"].items() if r.get("ports")}
    if ported:
        lines += [
            "",
            "### What the actuators and sensors cost (time / time of ν̇ alone, same state)",
            "",
            "| vehicle | " + " | ".join(PORT_CASES) + " |",
            "|---|" + "---|" * len(PORT_CASES),
        ]
        for name, ports in ported.items():
            lines.append(f"| {name} | " + " | ".join(_ratio(ports.get(k)) for k in PORT_CASES) + " |")
    sc = s["scaling"]
    lines += [
        "",
        f"### Scaling: chains of N links on a free base (µs per evaluation); fitted exponents (N ≥ 100): nudyn {sc['nudyn_exponent']:.2f}, "
        f"mj_forward {_ratio(sc['mj_forward_exponent'])}",
        "",
        "| N | nv | nudyn ν̇ | mj_forward | dense O(N³) ν̇ | pin.aba from Python | dense − nudyn (relative) |",
        "|---|---|---|---|---|---|---|",
    ]
    for links, r in zip(sc["links"], sc["rows"]):
        diff = f"{r['dense_difference']:.1e}" if "dense_difference" in r else "—"
        lines.append(
            f"| {links} | {r['nv']} | {_us(r['nudyn_ns'])} | {_us(r.get('mj_forward_ns'))} | {_us(r.get('dense_ns'))} | "
            f"{_us(r.get('pinocchio_aba_ns'))} | {diff} |"
        )
    pair = sc.get("side_by_side")
    if pair:
        (small, large), (small_ns, large_ns) = pair["links"], pair["nudyn_ns"]
        lines += [
            "",
            f"Timed side by side (in turn, within each repetition): N={small} {_us(small_ns)} µs, N={large} {_us(large_ns)} µs, "
            f"ratio {pair['ratio']:.2f} (median of per-repetition ratios).",
        ]
    for name, wp in results["work_precision"].items():
        ws = s["work_precision"][name]
        lines += [
            "",
            f"### Work-precision, {name}: {wp['vehicle']}, {wp['duration']:g} s from {wp['start']} (error: largest |qpos| or |qvel| "
            f"difference from {wp['reference']}, every {wp['sample']:g} s; {wp['reference_check']['run']} differs from it by "
            f"{wp['reference_check']['difference']:.1e})",
            "",
            "| method | wall time at max error 1e-6 (ms) |",
            "|---|---|",
        ]
        for family, seconds in sorted(ws["seconds_at_1e-6"].items()):
            lines.append(f"| {family} | {'not reached' if seconds is None else f'{seconds * 1e3:.2f}'} |")
        lines += ["", "| run | max error | wall time (ms) | steps |", "|---|---|---|---|"]
        for side in ("nudyn", "mujoco"):
            for run, e in wp[side].items():
                error = "failed" if e["error"] == float("inf") else f"{e['error']:.1e}"
                lines.append(f"| {'nudyn' if side == 'nudyn' else 'MuJoCo'} {run} | {error} | {median(e['seconds']) * 1e3:.2f} | {e['steps']} |")
    f = s.get("fmi")
    if f:
        lines += [
            "",
            f"### FMI overhead: {results['fmi']['vehicle']}, RK4, {results['fmi']['steps']} doSteps of {results['fmi']['step']:g} s (µs per step)",
            "",
            "| native loop | FMPy doStep | FMPy doStep + set ε + get θ, ν | overhead of doStep | overhead with I/O |",
            "|---|---|---|---|---|",
            f"| {f['native_us_per_step']:.2f} | {f['fmpy_do_step_us_per_step']:.2f} | {f['fmpy_with_io_us_per_step']:.2f} | "
            f"{f['overhead_do_step_us']:.2f} | {f['overhead_with_io_us']:.2f} |",
        ]
    return "\n".join(lines) + "\n"


def plot_work_precision(results: dict, path: Path) -> None:
    scenarios = results["work_precision"]
    fig, axes = plt.subplots(1, len(scenarios), figsize=(6.5 * len(scenarios), 5), squeeze=False)
    for ax, (name, wp) in zip(axes[0], scenarios.items()):
        for side, marker in (("nudyn", "o"), ("mujoco", "s")):
            families = {}
            for run, e in wp[side].items():
                families.setdefault(run.split(":")[0], []).append((median(e["seconds"]), e["error"]))
            for family, points in families.items():
                points = sorted(p for p in points if np.isfinite(p[1]))
                label = f"{'nudyn' if side == 'nudyn' else 'MuJoCo'} {family}"
                ax.loglog([p[1] for p in points], [p[0] for p in points], marker=marker, label=label)
        ax.axvline(TARGET_ERROR, color="gray", linestyle=":", linewidth=1)
        ax.set_xlabel(f"max error over {wp['duration']:g} s (qpos, qvel)")
        ax.set_ylabel("wall time (s)")
        ax.set_title(f"{wp['vehicle']}, {name}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def plot_scaling(results: dict, path: Path) -> None:
    sc = results["summary"]["scaling"]
    links = np.array(sc["links"], float)
    fig, ax = plt.subplots(figsize=(7, 5))
    for key, label in (
        ("nudyn_ns", "nudyn ν̇ (O(N))"),
        ("mj_forward_ns", "MuJoCo mj_forward"),
        ("dense_ns", "dense ν̇ via M (O(N³))"),
        ("pinocchio_aba_ns", "Pinocchio ABA (from Python)"),
    ):
        points = [(n, r[key]) for n, r in zip(links, sc["rows"]) if key in r]
        if points:
            ax.loglog([p[0] for p in points], [p[1] / 1e3 for p in points], marker="o", label=label)
    reference = sc["rows"][0]["nudyn_ns"] / 1e3 * links / links[0]
    ax.loglog(links, reference, color="gray", linestyle=":", linewidth=1, label="slope 1")
    ax.set_xlabel("links N")
    ax.set_ylabel("µs per evaluation")
    ax.set_title("Cost of one evaluation against chain length")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write(results: dict, out: Path) -> None:
    (out / "table.md").write_text(table(results))
    plot_scaling(results, out / "scaling.png")
    if results.get("work_precision"):
        plot_work_precision(results, out / "work_precision.png")
