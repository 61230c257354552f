"""Shared fixtures for the Python tests: the example files, the nudyn binary
and its FMU library, exports cached on disk, and a runner for `nudyn eval`
that prints everything needed to debug a failure.

The suite runs in parallel (pytest-xdist, one process per core): session
fixtures run once per process, so what several processes need (exported
FMUs) is cached on disk under target/test-cache, keyed by the content of
everything it is made from, and made under a file lock."""

from __future__ import annotations

import contextlib
import fcntl
import functools
import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
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

# The FMUs the tests export carry linux64's library alone: nudyn packs every
# platform's library found in $NUDYN_FMU_BINARIES (else target/share/nudyn/
# binaries), and deflating the 6 MB win64 DLL into every export doubled its
# CPU (servicer: 0.17 against 0.08 s). Only the tests of the platforms read
# it, and they export with the binaries as built (`every_platform_built`).
os.environ["NUDYN_FMU_BINARIES"] = str(ROOT / "target" / "test-cache" / "linux64-only")


# The test files that take longest, longest first (their sums of test
# durations in a run of the whole suite on 2 workers on a loaded machine,
# 2026-11-29: 752, 321, 289, 249, 168, 107, 107 and 87 s; test_deep_models
# took 226 s there, which sharing its export since has about halved). Under
# pytest-xdist with --dist loadfile each file runs whole on one worker, so
# scripts/test.sh hands the files out in collection order
# (--no-loadscope-reorder) and they come first: a long file handed out
# last keeps one worker busy while the other has nothing left to do.
SLOWEST_FILES = ("test_campaign.py", "test_validation.py", "test_tendons.py", "test_constraints.py",
                 "test_stress.py", "test_deep_models.py", "test_tolerance_cost.py", "test_ctrl_inputs.py",
                 "test_corpus.py")


def pytest_collection_modifyitems(items):
    """The slowest files' tests first, each file's in its own order (a stable sort)."""
    rank = {name: position for position, name in enumerate(SLOWEST_FILES)}
    items.sort(key=lambda item: rank.get(item.path.name, len(SLOWEST_FILES)))


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


@pytest.fixture(scope="module")
def every_platform_built():
    """For a module of tests of the platforms' binaries: its exports pack
    every one built in target/share/nudyn/binaries, as a user's do."""
    with pytest.MonkeyPatch.context() as patch:
        patch.delenv("NUDYN_FMU_BINARIES")
        yield


@pytest.fixture(scope="module")
def once():
    """`once(make, *args)`: make(*args) the first time a test of the module
    asks for it, the same value after. For the runs several tests of a
    module check (MuJoCo's reference and nudyn's answers for a model).
    Under pytest-xdist a test file runs in one process (--dist loadfile),
    so each run is made once."""
    return functools.cache(lambda make, *args: make(*args))


CACHE_DIR = ROOT / "target" / "test-cache"


@contextlib.contextmanager
def file_lock(path: Path):
    """Holds an exclusive lock on `path` (created if missing) across processes."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _digest_files(digest, paths):
    for path in paths:
        digest.update(str(path).encode())
        digest.update(path.read_bytes() if path.is_file() else b"<missing>")


@pytest.fixture(scope="session")
def exported_fmu(cli):
    """`exported_fmu(model, **options)`: the FMU `cli.export(model, ...,
    **options)` writes, made once for every test process and kept in
    target/test-cache/fmus/<key>/ (read-only use: unzip it elsewhere). The
    key covers nudyn, the FMU library, the win64 DLL the export packs when
    it is built and the binaries folder it packs from (linux64-only, above,
    but for the tests of the platforms), the files of the model's folder and
    the options, so a rebuild or an edited model makes a new export."""
    binaries = hashlib.sha256()
    share = cli.binary.parent.parent / "share" / "nudyn" / "binaries" / "win64" / "nudyn_fmu.dll"
    _digest_files(binaries, [cli.binary, cli.fmu_library, share])

    def export(model: Path, **options) -> Path:
        digest = binaries.copy()
        _digest_files(digest, sorted(p for p in Path(model).parent.rglob("*") if p.is_file()))
        digest.update(f"{Path(model).resolve()} {sorted(options.items())}".encode())
        digest.update(os.environ.get("NUDYN_FMU_BINARIES", "").encode())
        folder = CACHE_DIR / "fmus" / digest.hexdigest()[:32]
        fmu = folder / f"{Path(model).stem}.fmu"
        with file_lock(CACHE_DIR / "fmus.lock"):
            if not fmu.is_file():
                shutil.rmtree(folder, ignore_errors=True)
                partial = folder.with_name(folder.name + ".partial")
                shutil.rmtree(partial, ignore_errors=True)
                cli.export(model, partial / fmu.name, **options)
                partial.rename(folder)
        return fmu

    return export


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


def tangent_jacobian(ref, qpos, qvel, torque, read, which: int, h: float) -> np.ndarray:
    """∂read(d)/∂x of mj_forward at (qpos, qvel, torque), x = δq (which 0,
    moved by mj_integratePos as mjd_transitionFD moves it), θ̇ (1) or the
    joint forces (2): central differences with one Richardson step (error
    O(h⁴)). `ref` is a nudyn_validation Reference; `read` picks an array of
    its MjData."""
    import mujoco

    def value(dx):
        moved = qpos.copy()
        deltas = [np.zeros(ref.nv) for _ in range(3)]
        deltas[which] = dx
        mujoco.mj_integratePos(ref.model, moved, deltas[0], 1.0)
        return read(ref.forward(moved, qvel + deltas[1], torque + deltas[2])).copy()

    def column(k, step):
        unit = np.zeros(ref.nv)
        unit[k] = step
        return (value(unit) - value(-unit)) / (2 * step)

    return np.column_stack([(4 * column(k, h / 2) - column(k, h)) / 3 for k in range(ref.nv)])


def run_eval(binary: Path, model: Path, stdin: str, timeout: float = 300) -> EvalResult:
    cmd = [str(binary), "eval", str(model)]
    proc = subprocess.run(
        cmd, input=stdin, capture_output=True, text=True, timeout=timeout, cwd=ROOT
    )
    return EvalResult(proc, cmd, stdin)


def assert_restores_bit_for_bit(running, fresh, advance, steps: int) -> None:
    """Saves `running`'s FMU state (and its serialization), advances it
    `steps` by `advance(instance, steps)`, then restores the state into
    `running` and, deserialized, into `fresh`, advances each as far and
    asserts that both end with the same reals, bit for bit. `running` is
    left at the end of that run."""
    state = running.fmu.getFMUstate()
    blob = running.fmu.serializeFMUstate(state)
    saved_time = running.time
    advance(running, steps)
    after = running.all_reals()

    running.fmu.setFMUstate(state)
    running.time = saved_time
    advance(running, steps)
    assert np.array_equal(running.all_reals(), after)

    restored = fresh.fmu.deSerializeFMUstate(blob)
    fresh.fmu.setFMUstate(restored)
    fresh.time = saved_time
    advance(fresh, steps)
    assert np.array_equal(fresh.all_reals(), after)
    fresh.fmu.freeFMUstate(restored)
    running.fmu.freeFMUstate(state)
