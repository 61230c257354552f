"""The wheel: a user with only Python installs it into a fresh environment
and exports and runs an FMU, with no Rust toolchain anywhere on the PATH.

Needs scripts/build-wheel.sh to have run (scripts/test.sh runs it). The
packages come from pip's cache or PyPI, at the pins of requirements.txt.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest
from conftest import EXAMPLES_DIR, ROOT
from fmpy import simulate_fmu

WHEELS = ROOT / "target" / "wheels"


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """A fresh virtual environment with the wheel and its extras installed."""
    wheels = sorted(WHEELS.glob("nudyn-*.whl"))
    if len(wheels) != 1:
        pytest.fail(f"expected one wheel in {WHEELS}, found {wheels}: run scripts/build-wheel.sh", pytrace=False)
    root = tmp_path_factory.mktemp("wheel")
    venv = root / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    # The repository's pins, as constraints (which cannot carry extras).
    constraints = root / "constraints.txt"
    constraints.write_text(re.sub(r"\[[a-z,]+\]", "", (ROOT / "requirements.txt").read_text()))
    # --no-compile: pip would compile every module of every package to
    # bytecode up front; Python compiles what the tests import when they import it.
    subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "install", "--quiet", "--disable-pip-version-check",
                    "--no-compile", "-c", str(constraints), f"{wheels[0]}[all]"], check=True, timeout=900)
    return venv


def run(venv, *command, cwd):
    """`command` with only the environment's bin on the PATH: no cargo, rustc or compiler."""
    env = {"HOME": os.environ.get("HOME", "/root"), "PATH": str(venv / "bin"), "MPLBACKEND": "Agg"}
    assert shutil.which("cargo", path=env["PATH"]) is None and shutil.which("rustc", path=env["PATH"]) is None
    proc = subprocess.run([str(venv / "bin" / command[0]), *command[1:]], capture_output=True, text=True, env=env,
                          cwd=cwd, timeout=600)
    assert proc.returncode == 0, f"{command}: {proc.stdout}\n{proc.stderr}"
    return proc


def test_the_installed_nudyn_exports_an_fmu_that_runs(installed, tmp_path, nudyn, fmu_library):
    examples = installed / "share" / "nudyn" / "examples"
    fmu = tmp_path / "bus.fmu"
    proc = run(installed, "nudyn", "export", str(examples / "bus_arm7.xml"), "-o", str(fmu), cwd=tmp_path)
    assert proc.stdout.strip() == f"wrote {fmu} with binaries for linux64, win64"
    script = ("import sys\nfrom fmpy import simulate_fmu\nimport numpy as np\n"
              "r = simulate_fmu(sys.argv[1], stop_time=1.0, start_values={'nu[4]': 0.5, 'nu[9]': -0.2})\n"
              "np.save(sys.argv[2], np.array([list(row) for row in r]))\n")
    run(installed, "python", "-c", script, str(fmu), str(tmp_path / "installed.npy"), cwd=tmp_path)
    # The same run of the FMU the checkout's build exports: the same code, the same numbers.
    reference = tmp_path / "reference.fmu"
    subprocess.run([str(nudyn), "export", str(EXAMPLES_DIR / "bus_arm7.xml"), "-o", str(reference)],
                   env={**os.environ, "NUDYN_FMU_LIB": str(fmu_library)}, check=True, capture_output=True)
    expected = simulate_fmu(str(reference), stop_time=1.0, start_values={"nu[4]": 0.5, "nu[9]": -0.2})
    assert np.array_equal(np.load(tmp_path / "installed.npy"), np.array([list(row) for row in expected]))


def test_the_installed_tools_run(installed, tmp_path):
    examples = installed / "share" / "nudyn" / "examples"
    run(installed, "nudyn-validate", str(examples / "fixed_rig.xml"), "--scenario", "tumble", "--duration", "0.2",
        "--out", str(tmp_path / "validation"), cwd=tmp_path)
    results = json.loads((tmp_path / "validation" / "results.json").read_text())
    (tumble,) = results["scenarios"]
    assert tumble["passed"] and tumble["max_theta_error"] < 1e-8 and tumble["max_nu_error"] < 1e-8, tumble
    for tool in ("nudyn-campaign", "nudyn-control-demo", "nudyn-thruster-demo"):
        assert run(installed, tool, "--help", cwd=tmp_path).stdout.startswith(f"usage: {tool}")
