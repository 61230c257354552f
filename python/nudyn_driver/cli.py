"""nudyn's command line (and its benchmark binary's) run from Python: one
runner, whose failures are CommandError with the command and its stderr."""

from __future__ import annotations

import json
import os
import subprocess
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from .errors import CommandError, DriverError
from .structure import VehicleStructure


def run_command(command: Iterable, stdin: str | None = None, env: Mapping[str, str] | None = None) -> str:
    """Runs `command` (paths allowed) and returns its stdout; raises
    CommandError when it exits with a non-zero status."""
    command = [str(part) for part in command]
    proc = subprocess.run(command, input=stdin, capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        raise CommandError(command, proc.returncode, proc.stderr)
    return proc.stdout


def run_json(command: Iterable, request: Any = None) -> Any:
    """Runs `command` with `request` as JSON on stdin (if given) and parses
    the JSON it prints."""
    stdin = None if request is None else json.dumps(request)
    return json.loads(run_command(command, stdin))


class Nudyn:
    """The nudyn binary at `binary`. `fmu_library`, when given, is the FMU
    binary `export` packs (NUDYN_FMU_LIB); nudyn's default is the
    libnudyn_fmu.so beside itself."""

    def __init__(self, binary: Path, fmu_library: Path | None = None):
        self.binary = Path(binary)
        self.fmu_library = fmu_library

    def run(self, *arguments, stdin: str | None = None) -> str:
        """`nudyn ARGUMENTS...`; its stdout."""
        if not self.binary.is_file():
            raise DriverError(
                f"nudyn binary not found at {self.binary}: build it with `cargo build --release --workspace`"
            )
        env = None if self.fmu_library is None else {**os.environ, "NUDYN_FMU_LIB": str(self.fmu_library)}
        return run_command([self.binary, *arguments], stdin, env)

    def export(
        self,
        model: Path,
        fmu: Path,
        *,
        outputs: Iterable[str] = (),
        controller: bool = False,
        end_effector: str | None = None,
        model_identifier: str | None = None,
        fmi_version: int = 2,
        wrench_inputs: Iterable[str] = (),
        method: str | None = None,
    ) -> Path:
        """`nudyn export MODEL -o FMU` with the options given; makes FMU's
        directory if needed and returns the FMU's path."""
        fmu = Path(fmu)
        fmu.parent.mkdir(parents=True, exist_ok=True)
        arguments: list = ["export", model, "-o", fmu]
        if outputs:
            arguments += ["--outputs", ",".join(outputs)]
        if controller:
            arguments.append("--controller")
        if end_effector is not None:
            arguments += ["--end-effector", end_effector]
        if model_identifier is not None:
            arguments += ["--model-identifier", model_identifier]
        if fmi_version != 2:
            arguments += ["--fmi-version", str(fmi_version)]
        if wrench_inputs:
            arguments += ["--wrench-inputs", ",".join(wrench_inputs)]
        if method is not None:
            arguments += ["--method", method]
        self.run(*arguments)
        return fmu

    def describe(self, model: Path) -> VehicleStructure:
        """`nudyn describe MODEL --json`: the joints and their θ/ν addresses."""
        return VehicleStructure.from_json(json.loads(self.run("describe", model, "--json")))

    def eval(self, model: Path, request: Any) -> Any:
        """`nudyn eval MODEL` of one request (a dict) or several (a list)."""
        return json.loads(self.run("eval", model, stdin=json.dumps(request)))
