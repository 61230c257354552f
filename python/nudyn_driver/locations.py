"""Where the Python tools find nudyn and its files, in a source checkout
(python/ beside target/ and examples/) or installed from the wheel (the
`nudyn` executable in the environment's scripts folder, the example
vehicles under <prefix>/share/nudyn/examples, outputs under ./out)."""

from __future__ import annotations

import os
import shutil
import sys
import sysconfig
from pathlib import Path

CHECKOUT = Path(__file__).resolve().parents[2]
IN_CHECKOUT = (CHECKOUT / "Cargo.toml").is_file() and (CHECKOUT / "examples").is_dir()


def nudyn_binary() -> Path:
    """$NUDYN_BIN; else the checkout's target/release/nudyn; else the wheel's
    `nudyn` beside this Python, or the one on the PATH."""
    if "NUDYN_BIN" in os.environ:
        return Path(os.environ["NUDYN_BIN"])
    if IN_CHECKOUT:
        return CHECKOUT / "target" / "release" / "nudyn"
    installed = Path(sysconfig.get_path("scripts")) / "nudyn"
    if installed.is_file():
        return installed
    on_path = shutil.which("nudyn")
    return Path(on_path) if on_path else installed


def examples_dir() -> Path:
    """The example vehicles (and campaigns/ of example campaigns)."""
    if IN_CHECKOUT:
        return CHECKOUT / "examples"
    return Path(sys.prefix) / "share" / "nudyn" / "examples"


def output_dir(*parts: str) -> Path:
    """Where a tool writes by default: the checkout's out/, else ./out."""
    return (CHECKOUT / "out" if IN_CHECKOUT else Path.cwd() / "out").joinpath(*parts)
