"""The stress suite's short mode (scripts/stress.py without --long), one
test per case, with thresholds that say what the FMU must achieve."""

from __future__ import annotations

import numpy as np
import pytest

from nudyn_stress.cases import CASES, DEFAULT_TOLERANCE, Context, projected_k_bound


@pytest.fixture(scope="module")
def context(nudyn, tmp_path_factory):
    return Context(nudyn, tmp_path_factory.mktemp("stress"), long=False)


def rows_by_setup(result, note=None):
    return {row.setup: row for row in result.rows if note is None or row.note == note}


def test_long_tumbling_keeps_its_invariants(context):
    result = CASES["tumbling"](context)
    duration = result.numbers["duration"]
    for row in result.rows:
        assert row.outcome == "completed", row
        tolerance = float(row.setup.split("tol ")[1].split(",")[0]) if "tol " in row.setup else DEFAULT_TOLERANCE
        assert row.momentum_drift <= tolerance * duration, row
        assert row.k_drift <= tolerance * duration, row
        if "projected" in row.setup:
            assert row.k_drift < projected_k_bound(row, duration), row
    loose = rows_by_setup(result)["dop853, tol 1e-06, max_step 10"]
    assert loose.k_drift > 1e3 * rows_by_setup(result)["dop853, tol 1e-06, max_step 10, projected"].k_drift
    assert result.figure.is_file() and result.passed, result.verdict


def test_mass_ratio_is_accurate(context):
    result = CASES["mass_ratio"](context)
    for row in result.rows:
        if row.note.startswith("ε = 0") or row.note.startswith("sine ε"):
            assert row.outcome == "completed", row
    for note in ("ε = 0", "sine ε"):
        for setup in ("dopri5", "dop853"):
            assert rows_by_setup(result, note)[setup].error <= DEFAULT_TOLERANCE * 10.0
    assert result.numbers["mujoco"]["max_error"] <= 1e-6
    assert result.passed, result.verdict


def test_long_chain_completes(context):
    result = CASES["chain"](context)
    for row in result.rows:
        assert row.outcome == "completed", row
        if not row.setup.startswith("rk4"):
            assert row.momentum_drift <= 1e-6, row
    assert result.passed, result.verdict


def test_stiff_boom_never_outputs_nan(context):
    result = CASES["stiff_boom"](context)
    duration = result.numbers["duration"]
    assert 250 < result.numbers["omega_max"] < 400  # √(k/J) for k = 1e5, J ≈ 1 kg m²
    for row in result.rows:
        if row.outcome != "completed":
            reached = float(row.outcome.split("t = ")[1].split(" s")[0])
            assert row.outcome.startswith("fmi2Discard") and 0 <= reached <= duration, row
        elif not row.setup.startswith("rk4"):
            tolerance = float(row.setup.split("tol ")[1].split(",")[0]) if "tol " in row.setup else DEFAULT_TOLERANCE
            assert row.error <= tolerance * duration, row
    assert result.passed, result.verdict


def test_thin_rods_are_integrated(context):
    """Round-off limits this vehicle: the adaptive runs complete, say which
    tolerance they held, and keep K and momentum to it."""
    result = CASES["thin_rods"](context)
    assert all(row.outcome == "completed" for row in result.rows), result.verdict
    assert max(result.numbers["spread"].values()) > 1e-6, "the case no longer shows a round-off limit"
    assert result.numbers["mujoco"]["max_error"] <= 1e-3
    assert result.passed, result.verdict


def test_fast_spin_matches_the_exact_motion(context):
    result = CASES["spin"](context)
    rows = rows_by_setup(result)
    assert rows["dop853"].error <= DEFAULT_TOLERANCE * 10.0
    assert rows["dop853, tol 1e-11"].error <= 1e-11 * 10.0
    assert rows["dop853, projected"].k_drift < 1e-12
    assert result.passed, result.verdict


def test_huge_and_non_finite_inputs(context):
    result = CASES["extreme_inputs"](context)
    for row in result.rows:
        assert "outputs finite: True" in row.note, row
        if row.setup.endswith(("NaN", "Inf")):
            assert row.outcome.startswith("setReal: fmi2Discard; doStep: fmi2OK"), row
            assert "is not finite" in row.note
        else:
            assert "doStep: fmi2Discard" in row.outcome and "terminated" in row.outcome, row
            assert "stopped at t = " in row.note
    sweep = result.numbers["sweep"]
    methods = [key for key in sweep if key != "exponents"]
    assert methods == ["rk4", "dopri5", "dop853", "ros34pw2", "bs3", "tsit5", "auto"], "every method of the FMU"
    for method in methods:
        reached = np.array(sweep[method])
        assert np.all(np.isfinite(reached)) and reached[0] == pytest.approx(0.01)
        assert reached[-1] < 0.01, "10^300 cannot be integrated"
    assert result.passed, result.verdict
