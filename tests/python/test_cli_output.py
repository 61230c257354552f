"""The commands' output into a pipe whose reader has gone (`nudyn eval … |
head`): it ends quietly with exit 0, as Unix tools do, not in a panic."""

from __future__ import annotations

import json
import os
import subprocess

import pytest

from conftest import EXAMPLES_DIR

MODEL = EXAMPLES_DIR / "bus_arm7.xml"
COMMANDS = {
    "describe": (["describe", str(MODEL)], None),
    "describe --json": (["describe", str(MODEL), "--json"], None),
    "eval": (["eval", str(MODEL)], json.dumps({"theta": [0, 0, 0, 1, 0, 0, 0] + [0.1] * 7, "nu": [0.1] * 13})),
    "simulate": (["simulate", str(MODEL), "--step", "0.01", "--stop", "0.1"], "{}"),
}


@pytest.mark.parametrize("name", COMMANDS)
def test_a_reader_that_stopped_reading_is_no_error(nudyn, name):
    arguments, stdin = COMMANDS[name]
    read_end, write_end = os.pipe()
    os.close(read_end)  # every write now fails with EPIPE
    try:
        proc = subprocess.run([str(nudyn), *arguments], input=stdin, stdout=write_end, stderr=subprocess.PIPE,
                              text=True)
    finally:
        os.close(write_end)
    assert (proc.returncode, proc.stderr) == (0, "")


@pytest.mark.parametrize(
    "arguments, says",
    [
        (["--step", "-0.01", "--stop", "1"], "--step must be positive and --stop non-negative, found -0.01 and 1"),
        (["--step", "1e-300", "--stop", "1"], "--stop 1 is not a multiple of --step 1e-300"),
        (["--step", "0.01", "--stop", "1", "--max-step", "-0.5"], "--max-step must be positive, found -0.5"),
    ],
    ids=["negative step", "tiny step", "negative max step"],
)
def test_simulate_refuses_bad_steps_in_readable_words(nudyn, arguments, says):
    """A negative value is a value, not a flag, and a tiny one is not printed with 300 digits."""
    proc = subprocess.run([str(nudyn), "simulate", str(MODEL), *arguments], input="{}", capture_output=True,
                          text=True)
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr.strip() == f"nudyn: error: {says}"
