"""`nudyn eval` on bad input: a non-zero exit and a message on stderr that
names the problem; never a crash, never NaN in the output."""

from __future__ import annotations

import json
import re

import pytest

from conftest import EXAMPLES_DIR, run_eval
from nudyn_validation.mujoco_reference import Reference

MODEL = EXAMPLES_DIR / "bus_arm7.xml"


@pytest.fixture(scope="module")
def good():
    ref = Reference.from_file(MODEL)
    return {"theta": ref.model.qpos0.tolist(), "qvel": [0.1] * ref.nv}, ref.nq, ref.nv


def expect_error(result, *patterns):
    assert result.returncode != 0, f"expected a non-zero exit\n{result.describe()}"
    assert result.returncode < 128 and result.returncode > 0, f"crashed?\n{result.describe()}"
    assert result.stderr.strip(), f"expected a message on stderr\n{result.describe()}"
    for p in patterns:
        assert re.search(p, result.stderr, re.IGNORECASE), (
            f"the message should mention /{p}/\n{result.describe()}"
        )


@pytest.mark.parametrize("field", ["theta", "qvel", "nu", "eps", "torque"])
@pytest.mark.parametrize("delta", [-1, 1])
def test_wrong_length(nudyn, good, field, delta):
    req, nq, nv = good
    req = dict(req)
    n = nq if field == "theta" else nv
    if field == "nu":
        del req["qvel"]
    req[field] = [0.0] * (n + delta)
    if field == "theta":
        req[field][0] = 1.0  # keep the quaternion non-zero
    expect_error(run_eval(nudyn, MODEL, json.dumps(req)), rf"\b{field}\b", rf"\b{n}\b")


def test_missing_theta(nudyn, good):
    req, _, _ = good
    req = {k: v for k, v in req.items() if k != "theta"}
    expect_error(run_eval(nudyn, MODEL, json.dumps(req)), r"\btheta\b")


def test_missing_velocity(nudyn, good):
    req, _, _ = good
    req = {"theta": req["theta"]}
    expect_error(run_eval(nudyn, MODEL, json.dumps(req)), r"\b(qvel|nu)\b")


def test_bare_nan(nudyn, good):
    req, _, _ = good
    text = json.dumps(req).replace("[0.1,", "[NaN,", 1)
    assert "NaN" in text
    expect_error(run_eval(nudyn, MODEL, text), r"no NaN or Infinity")


def test_not_json(nudyn):
    expect_error(run_eval(nudyn, MODEL, "this is not json"), r"json|expected|line|column|invalid|parse")


def test_empty_input(nudyn):
    expect_error(run_eval(nudyn, MODEL, ""), r"json|expected|eof|empty|input|parse")


def test_non_number_entry(nudyn, good):
    """A value of the wrong type is named by its place, 1-based like the
    FMU's variables (qvel[2] is the second entry)."""
    req, _, _ = good
    req = dict(req)
    req["qvel"] = [0.1, "fast"] + req["qvel"][2:]
    expect_error(run_eval(nudyn, MODEL, json.dumps(req)), r"qvel\[2\]: invalid type: string \"fast\", expected f64")


def test_wrong_type_in_an_array_of_requests(nudyn, good):
    req, _, _ = good
    bad = {**req, "theta": {"w": 1}}
    expect_error(run_eval(nudyn, MODEL, json.dumps([req, req, bad])), r"request 2, theta: invalid type: map")


def test_unknown_field_is_named(nudyn, good):
    req, _, _ = good
    expect_error(run_eval(nudyn, MODEL, json.dumps({**req, "omega": [0.0]})), r"unknown field `omega`")


def test_bad_element_in_array(nudyn, good):
    req, nq, _ = good
    bad = dict(req)
    bad["theta"] = bad["theta"][:-1]
    expect_error(run_eval(nudyn, MODEL, json.dumps([req, bad])), r"\btheta\b")


def test_missing_model_file(nudyn, good, tmp_path):
    req, _, _ = good
    missing = tmp_path / "no_such_vehicle.xml"
    result = run_eval(nudyn, missing, json.dumps(req))
    expect_error(result, r"no_such_vehicle")
    assert result.stderr.count("No such file or directory") == 1, "the OS error is said once"
