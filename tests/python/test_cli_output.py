"""The commands' output as a person and a pipe see it: a reader that has
gone (`nudyn eval … | head`) ends the command quietly with exit 0, as Unix
tools do; numbers in messages are readable; `nudyn simulate` streams its
rows (CSV) or keeps them out of memory (JSON), shows progress on a
terminal, and says what it waits for when stdin is one."""

from __future__ import annotations

import json
import os
import pty
import re
import subprocess
import sys

import pytest

from conftest import EXAMPLES_DIR

MODEL = EXAMPLES_DIR / "bus_arm7.xml"
COMMANDS = {
    "describe": (["describe", str(MODEL)], None),
    "describe --json": (["describe", str(MODEL), "--json"], None),
    "eval": (["eval", str(MODEL)], json.dumps({"theta": [0, 0, 0, 1, 0, 0, 0] + [0.1] * 7, "nu": [0.1] * 13})),
    "simulate": (["simulate", str(MODEL), "--step", "0.01", "--stop", "0.1"], "{}"),
    "simulate --format csv": (["simulate", str(MODEL), "--step", "0.01", "--stop", "0.1", "--format", "csv"], "{}"),
    # Stops at once when the reader has gone, rather than running to the end.
    "endless simulate --format csv": (["simulate", str(MODEL), "--step", "0.01", "--stop", "1e9", "--format", "csv"],
                                      "{}"),
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
        (["--step", "0.01", "--stop", "1", "--tolerance", "-1e-9"], "--tolerance must be positive, found -1e-9"),
        (["--step", "-1E-2", "--stop", "1"], "--step must be positive and --stop non-negative, found -0.01 and 1"),
    ],
    ids=["negative step", "tiny step", "negative max step", "negative exponent form", "negative upper-case exponent"],
)
def test_simulate_refuses_bad_steps_in_readable_words(nudyn, arguments, says):
    """A negative value is a value, not a flag, and a tiny one is not printed with 300 digits."""
    proc = subprocess.run([str(nudyn), "simulate", str(MODEL), *arguments], input="{}", capture_output=True,
                          text=True)
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr.strip() == f"nudyn: error: {says}"


def test_csv_rows_stream_as_they_are_computed(nudyn):
    """The first rows of a run to t = 1e9 s arrive while it runs."""
    proc = subprocess.Popen([str(nudyn), "simulate", str(MODEL), "--step", "0.01", "--stop", "1e9", "--format", "csv"],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        proc.stdin.write("{}")
        proc.stdin.close()
        header = proc.stdout.readline().strip().split(",")
        rows = [list(map(float, proc.stdout.readline().split(","))) for _ in range(3)]
        assert proc.poll() is None, "still running"
    finally:
        proc.kill()
        proc.wait()
    assert header == ["time"] + [f"theta[{k}]" for k in range(1, 15)] + [f"nu[{k}]" for k in range(1, 14)]
    assert [row[0] for row in rows] == [0.0, 0.01, 0.02] and all(len(row) == 28 for row in rows)


def test_csv_and_json_hold_the_same_numbers(nudyn):
    arguments = [str(nudyn), "simulate", str(MODEL), "--step", "0.01", "--stop", "0.05"]
    state = json.dumps({"nu": [0.1] * 13})
    as_json = json.loads(subprocess.run(arguments, input=state, capture_output=True, text=True, check=True).stdout)
    as_csv = subprocess.run(arguments + ["--format", "csv"], input=state, capture_output=True, text=True,
                            check=True).stdout.splitlines()[1:]
    for k, line in enumerate(as_csv):
        row = [float(x) for x in line.split(",")]
        assert row == [as_json["time"][k], *as_json["theta"][k], *as_json["nu"][k]]


def test_a_long_json_run_keeps_its_states_out_of_memory(nudyn):
    """100 000 states of 28 numbers would take over 20 MB in memory (and
    their JSON text twice that); the columns wait in temporary files
    instead. Measured in a process of its own, whose only child is nudyn."""
    measure = (
        "import resource, subprocess, sys\n"
        "subprocess.run(sys.argv[1:], input=b'{}', stdout=subprocess.DEVNULL, check=True)\n"
        "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n"
    )
    arguments = [str(nudyn), "simulate", str(MODEL), "--step", "1e-4", "--stop", "10", "--max-step", "0.01"]
    peak_kib = int(subprocess.run([sys.executable, "-c", measure, *arguments], capture_output=True, text=True,
                                  check=True).stdout)
    assert peak_kib < 20_000, f"peak resident memory {peak_kib} KiB"


def run_on_a_terminal(arguments, stdin_text=None, terminal_stdin=False):
    """Runs nudyn with stderr (and stdin, if asked) on a pseudo-terminal;
    returns what the terminal showed."""
    leader, follower = pty.openpty()
    proc = subprocess.Popen(arguments, stdin=follower if terminal_stdin else subprocess.PIPE,
                            stdout=subprocess.DEVNULL, stderr=follower)
    os.close(follower)
    if terminal_stdin:
        os.write(leader, stdin_text.encode() + b"\n\x04")
    else:
        proc.stdin.write(stdin_text.encode())
        proc.stdin.close()
    shown = b""
    while True:
        try:
            chunk = os.read(leader, 4096)
        except OSError:  # the terminal closed with the process
            break
        if not chunk:
            break
        shown += chunk
    proc.wait()
    os.close(leader)
    return proc.returncode, shown.decode(errors="replace")


def test_a_long_run_shows_its_progress_on_a_terminal(nudyn):
    """A run of about 2 s (the bar appears after 1 s)."""
    code, shown = run_on_a_terminal([str(nudyn), "simulate", str(EXAMPLES_DIR / "chain60.xml"), "--step", "1e-3",
                                     "--stop", "30", "--format", "csv"], "{}")
    assert code == 0, shown
    assert re.search(r"simulate \[[=> ]+\] \d+/30000 steps", shown), shown


def test_a_short_run_and_a_pipe_show_no_progress(nudyn):
    code, shown = run_on_a_terminal([str(nudyn), "simulate", str(MODEL), "--step", "0.01", "--stop", "0.1"], "{}")
    assert (code, shown) == (0, "")
    proc = subprocess.run([str(nudyn), "simulate", str(EXAMPLES_DIR / "chain60.xml"), "--step", "1e-3", "--stop", "6",
                           "--format", "csv"], input="{}", capture_output=True, text=True)
    assert (proc.returncode, proc.stderr) == (0, "")


@pytest.mark.parametrize("command", ["simulate", "eval"])
def test_a_terminal_on_stdin_is_told_what_to_type(nudyn, command):
    arguments = [str(nudyn), command, str(MODEL)]
    if command == "simulate":
        arguments += ["--step", "0.01", "--stop", "0.01"]
        state = "{}"
    else:
        state = json.dumps({"theta": [0, 0, 0, 1, 0, 0, 0] + [0.1] * 7, "nu": [0.1] * 13})
    code, shown = run_on_a_terminal(arguments, state, terminal_stdin=True)
    assert code == 0, shown
    assert "as JSON from standard input" in shown and "Ctrl-D" in shown, shown
