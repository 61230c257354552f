"""Shared fixtures for the Python tests: the example files, the nudyn binary
and its FMU library, and a runner for `nudyn eval` that prints everything
needed to debug a failure."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
EXAMPLES_DIR = ROOT / "examples"
EXAMPLES = sorted(EXAMPLES_DIR.glob("*.xml"))
# The importer's fixtures exercise every supported MJCF feature (orientations,
# euler sequences, defaults, geom inertia, flags): MuJoCo must agree on them too.
IMPORTER_FIXTURES = sorted((ROOT / "tests" / "fixtures" / "mjcf").glob("*.xml"))

sys.path.insert(0, str(HERE))
# The MuJoCo reference and the validation against the FMU are a package
# outside tests/, shared with scripts/validate.py.
sys.path.insert(0, str(ROOT / "python"))

from nudyn_driver.cli import Nudyn  # noqa: E402  (needs the path above)


def example_ids():
    return [p.stem for p in EXAMPLES]


def nudyn_bin() -> Path:
    """The nudyn binary: $NUDYN_BIN, else target/release/nudyn (repo root)."""
    path = Path(os.environ.get("NUDYN_BIN", "target/release/nudyn"))
    if not path.is_absolute():
        path = ROOT / path
    return path


@pytest.fixture(scope="session")
def nudyn():
    """Path of the nudyn binary; fails (never skips) when it is missing."""
    path = nudyn_bin()
    if not (path.is_file() and os.access(path, os.X_OK)):
        pytest.fail(
            f"nudyn binary not found or not executable at {path} "
            "(set NUDYN_BIN, or run `cargo build --release` first)",
            pytrace=False,
        )
    return path


@pytest.fixture(scope="session")
def fmu_library(nudyn):
    """libnudyn_fmu.so beside the nudyn binary, built if needed (a plain
    `cargo build --release` or `cargo test` does not build the cdylib)."""
    if "NUDYN_FMU_LIB" in os.environ:
        return Path(os.environ["NUDYN_FMU_LIB"])
    profile_dir = nudyn.parent
    cmd = ["cargo", "build", "-q", "-p", "nudyn-fmu", "--target-dir", str(profile_dir.parent)]
    if profile_dir.name == "release":
        cmd.append("--release")
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 0, f"{' '.join(cmd)} failed:\n{proc.stderr}"
    return profile_dir / "libnudyn_fmu.so"


@pytest.fixture(scope="session")
def cli(nudyn, fmu_library):
    """The nudyn command line, exporting FMUs with the library above."""
    return Nudyn(nudyn, fmu_library)


def _reject_constant(name):
    raise ValueError(f"nudyn eval printed a non-finite number: {name}")


class EvalResult:
    def __init__(self, proc: subprocess.CompletedProcess, cmd, stdin: str):
        self.returncode = proc.returncode
        self.stdout = proc.stdout
        self.stderr = proc.stderr
        self.cmd = cmd
        self.stdin = stdin

    def describe(self) -> str:
        stdin = self.stdin if len(self.stdin) < 2000 else self.stdin[:2000] + "..."
        return (
            f"command: {' '.join(map(str, self.cmd))}\nexit code: {self.returncode}\n"
            f"stdin: {stdin}\nstdout: {self.stdout[:4000]}\nstderr: {self.stderr[:4000]}"
        )

    def json(self):
        """The parsed output; fails the test unless the command succeeded and
        printed strict JSON (no NaN/Infinity)."""
        if self.returncode != 0:
            pytest.fail(f"nudyn eval failed\n{self.describe()}", pytrace=False)
        try:
            return json.loads(self.stdout, parse_constant=_reject_constant)
        except ValueError as e:
            problem = str(e)
        pytest.fail(f"nudyn eval printed invalid JSON: {problem}\n{self.describe()}", pytrace=False)


def run_eval(binary: Path, model: Path, stdin: str, timeout: float = 300) -> EvalResult:
    cmd = [str(binary), "eval", str(model)]
    proc = subprocess.run(
        cmd, input=stdin, capture_output=True, text=True, timeout=timeout, cwd=ROOT
    )
    return EvalResult(proc, cmd, stdin)
