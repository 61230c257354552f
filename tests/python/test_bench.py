"""Smoke test of the benchmark command (`scripts/bench.py --quick`): it
runs every section at tiny sizes and writes what docs/performance.md
shows. It checks that the outputs are there and consistent, never how fast
anything is (a timed test on a shared machine would only measure the
machine)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from conftest import ROOT, nudyn_bin


def run_quick(script: str, out) -> None:
    """scripts/SCRIPT --quick --out OUT with this checkout's binaries."""
    proc = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / script), "--quick", "--out", str(out), "--bin-dir", str(nudyn_bin().parent)],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=ROOT,
        env={**os.environ, "PYTHONWARNINGS": "ignore"},
    )
    assert proc.returncode == 0, f"{script} failed\nstdout: {proc.stdout}\nstderr: {proc.stderr[-4000:]}"


def test_quick_benchmark_writes_results_table_and_plots(tmp_path):
    run_quick("bench.py", tmp_path)
    for name in ("results.json", "table.md", "scaling.png", "work_precision.png"):
        assert (tmp_path / name).stat().st_size > 0, name
    results = json.loads((tmp_path / "results.json").read_text())
    assert results["quick"] is True
    summary = results["summary"]
    for name, row in summary["eval_cost"].items():
        assert row["nudyn_ns"] > 0 and row["mj_forward_ns"] > 0, name
    # The dense O(N³) path computes the same ν̇ (its Ṁ by a central difference).
    for row in summary["scaling"]["rows"]:
        assert row["dense_difference"] < 1e-6, row
    # The reference of the work-precision runs is checked by an independent integration.
    for scenario in results["work_precision"].values():
        assert scenario["reference_check"]["difference"] < 1e-8
    assert set(summary["targets"]) == {"nu_dot_not_slower_than_mj_forward", "half_of_mujoco_best_at_1e-6", "linear_scaling"}
    assert "### Targets" in (tmp_path / "table.md").read_text()
    # The servicer's actuators and sensors are timed against its plain ν̇; a
    # vehicle without them has no such cases.
    ports = summary["eval_cost"]["servicer"]["ports"]
    assert set(ports) == {"stripped of actuators and sensors", "with actuators", "with actuators and sensors"}
    assert all(ratio > 0 for ratio in ports.values())
    assert not summary["eval_cost"]["bus_arm7"]["ports"]
    assert "### What the actuators and sensors cost" in (tmp_path / "table.md").read_text()


def test_quick_tolerance_benchmark_writes_table_and_plot(tmp_path):
    """`scripts/bench_tolerance.py --quick`: its outputs, and its reference
    checked against the FMU's own tight run (never a speed)."""
    run_quick("bench_tolerance.py", tmp_path)
    for name in ("tolerance.json", "tolerance.md", "tolerance.png"):
        assert (tmp_path / name).stat().st_size > 0, name
    results = json.loads((tmp_path / "tolerance.json").read_text())
    assert results["quick"] is True and set(results["examples"]) == {"bus_arm7", "fixed_rig"}
    for example in results["examples"].values():
        assert example["reference_check"] < 1e-7
        assert example["fmpy_reads_seconds"] > 0
        for entry in example["fmu"].values():
            assert entry["reads_over_target"] is None or entry["reads_over_target"] > 0
            # Steps reach past the communication points while ε holds
            # (docs/integration.md): fewer steps than points, but some.
            assert entry["steps"] >= 1 and entry["error"] < 10 * entry["tolerance"], entry
            assert 0.0 <= entry["outside_share"] < 1.0


def test_quick_methods_benchmark_writes_its_table(tmp_path):
    """`scripts/bench_methods.py --quick`: every adaptive method runs at each
    tolerance and meets it (never a speed)."""
    run_quick("bench_methods.py", tmp_path)
    assert (tmp_path / "methods.md").stat().st_size > 0
    results = json.loads((tmp_path / "methods.json").read_text())
    assert results["quick"] is True and set(results["examples"]) == {"bus_arm7", "fixed_rig"}
    for example in results["examples"].values():
        assert {run["method"] for run in example["runs"]} == {"bs3", "tsit5", "dopri5", "dop853"}
        for run in example["runs"]:
            # Steps reach past the communication points (docs/integration.md).
            assert run["accepted"] >= 1 and run["evaluations"] > 0 and run["error"] < 10 * run["tolerance"], run
            assert run["over_mujoco"] is None or run["over_mujoco"] > 0, run
            assert len(run["host_seconds"]) == 1 and run["host_seconds"][0] > 0, run
        assert all(entry["error"] < 1 for entry in example["mujoco_rk4"])


def test_quick_auto_benchmark_writes_its_table(tmp_path):
    """`scripts/bench_auto.py --quick`: auto and dop853 run on an example
    and a random tree, meet the tolerance, and say what auto chose (never a
    speed)."""
    run_quick("bench_auto.py", tmp_path)
    assert "median of 1 trees" in (tmp_path / "auto.md").read_text()
    results = json.loads((tmp_path / "auto.json").read_text())
    assert results["quick"] is True and set(results["vehicles"]) == {"bus_arm7", "tree0"}
    for vehicle in results["vehicles"].values():
        for run in vehicle["runs"]:
            # Steps reach past the communication points (docs/integration.md).
            assert run["accepted"] >= 1 and run["error"] < 10 * run["tolerance"], run
            assert (run["chosen"] is not None) == (run["method"] == "auto"), run
            assert run["host_seconds"][0] > 0 and run["fmpy_seconds"][0] > 0, run
            # MuJoCo timed beside each FMU run, at the step that reaches the run's accuracy.
            if run["mujoco_step"] is not None:
                assert len(run["paired_mujoco_seconds"]) == len(run["host_seconds"]), run
                ratio = min(run["host_seconds"]) / min(run["paired_mujoco_seconds"])
                assert run["host_over_mujoco"] == pytest.approx(ratio), run
        assert all(entry["error"] < 1 for entry in vehicle["mujoco_rk4"])


def test_random_trees_are_read_alike_by_mujoco_and_nudyn(nudyn, tmp_path):
    """The benchmark's random trees: MuJoCo and nudyn read the same
    joints, and MuJoCo's mass matrix factor gives nudyn's ν from its qvel."""
    import mujoco
    import numpy as np

    from nudyn_bench.trees import write_tree
    from nudyn_driver.cli import Nudyn
    from nudyn_validation.mujoco_reference import MujocoFactor

    for seed in range(3):
        path = write_tree(seed, tmp_path / f"tree{seed}.xml")
        model = mujoco.MjModel.from_xml_path(str(path))
        data = mujoco.MjData(model)
        rng = np.random.default_rng(seed)
        data.qvel[:] = rng.uniform(-1.0, 1.0, model.nv)
        mujoco.mj_forward(model, data)
        got = Nudyn(nudyn).eval(path, {"theta": list(map(float, data.qpos)), "qvel": list(map(float, data.qvel))})
        want = MujocoFactor(model).nu(data, data.qvel)
        np.testing.assert_allclose(got["nu"], want, rtol=0, atol=1e-10)


def test_chains_built_for_mujoco_equal_the_generated_files():
    """MuJoCo cannot read bodies nested 500 deep, so the benchmark builds its
    chains with MuJoCo's model editor: they must be gen_chain.py's chains."""
    import numpy as np

    from nudyn_bench.vehicles import chain_model
    from nudyn_validation.mujoco_reference import load_model

    built, read = chain_model(60), load_model(ROOT / "examples" / "chain60.xml")
    assert (built.nq, built.nv) == (read.nq, read.nv)
    for field in ("body_mass", "body_inertia", "body_ipos", "body_iquat", "body_pos", "body_quat", "jnt_axis", "dof_armature", "dof_damping", "qpos0"):
        assert np.allclose(getattr(built, field), getattr(read, field), rtol=0, atol=1e-15), field


@pytest.mark.skipif(not os.environ.get("NUDYN_FMUSIM"), reason="no fmusim given (NUDYN_FMUSIM=PATH)")
def test_quick_fmusim_benchmark_agrees_with_the_native_host(tmp_path):
    """`scripts/bench_fmusim.py --quick` with the fmusim NUDYN_FMUSIM names:
    it runs the FMU to the end, and its last θ and ν are the native host's
    (never a speed). fmusim steps to (n + 1) * 0.1 from n * 0.1, the host by
    0.1 from n * 0.1: from the sixth step (6 * 0.1 != 0.5 + 0.1) the
    FMU's targets differ by an ulp, so only closeness is asked."""
    proc = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "bench_fmusim.py"), "--quick", "--out", str(tmp_path),
         "--bin-dir", str(nudyn_bin().parent), "--fmusim", os.environ["NUDYN_FMUSIM"]],
        capture_output=True, text=True, timeout=600, cwd=ROOT, env={**os.environ, "PYTHONWARNINGS": "ignore"},
    )
    assert proc.returncode == 0, f"stdout: {proc.stdout}\nstderr: {proc.stderr[-4000:]}"
    results = json.loads((tmp_path / "fmusim.json").read_text())
    runs = results["vehicles"]["bus_arm7"]["runs"]
    assert len(runs) == 4
    for run in runs:
        assert abs(run["fmusim_end_time"] - 0.4) < 1e-12 and run["end_max_difference"] < 1e-12, run
        assert run["fmusim_seconds"][0] > 0 and run["host_seconds"][0] > 0, run
