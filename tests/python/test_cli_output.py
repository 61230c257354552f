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
