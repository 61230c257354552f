#!/usr/bin/env python3
"""Checks that building one crate alone compiles nothing that the whole
workspace's build has not compiled already:

    python3 scripts/check-unified-features.py

scripts/test.sh builds every target of the workspace the tests use, then the wheel
(maturin builds nudyn-cli alone) and runs modeldescription's example
(`cargo run -p modeldescription`). Cargo unifies a dependency's features
only among the crates a command builds, so those two would compile the
tree again with fewer features unless the crate `workspace-hack` asks for
the workspace's features. This compares cargo's unit graphs (what each
command would compile: crate, target, features, profile) and names every
dependency whose features differ, to add to workspace-hack/Cargo.toml
(`[build-dependencies]` for build scripts and proc macros, whose profile
has opt-level 0). The unit graph is an unstable cargo option: RUSTC_BOOTSTRAP=1
allows it on the stable toolchain."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# What scripts/test.sh builds in the release profile (every target but the
# benchmarks and the crates' unit tests, which it builds at opt-level 0).
WORKSPACE = ["--workspace", "--lib", "--bins", "--test", "*", "--examples"]
BUILT_ALONE = {
    "the wheel (maturin)": ["-p", "nudyn-cli"],
    "tests/python/test_modeldescription_schema.py": ["-p", "modeldescription", "--example", "write_example"],
}


def units(selection: list[str]) -> dict[tuple, str]:
    """What `cargo build --release SELECTION` compiles: a key per unit, and its package."""
    command = ["cargo", "build", "--release", "--locked", *selection, "--unit-graph", "-Z", "unstable-options"]
    proc = subprocess.run(command, cwd=ROOT, capture_output=True, text=True,
                          env={**os.environ, "RUSTC_BOOTSTRAP": "1"})
    if proc.returncode != 0:
        sys.exit(f"check-unified-features: `{' '.join(command)}` failed:\n{proc.stderr}")
    found = {}
    for unit in json.loads(proc.stdout)["units"]:
        key = (unit["pkg_id"], unit["target"]["name"], unit["mode"], tuple(unit["features"]),
               json.dumps(unit["profile"], sort_keys=True), unit["platform"])
        found[key] = unit["pkg_id"]
    return found


def main() -> int:
    workspace = units(WORKSPACE)
    features_built = {}
    for (package, target, mode, features, profile, _), _ in workspace.items():
        features_built.setdefault((package, target, mode, profile), []).append(list(features))
    problems = []
    for what, selection in BUILT_ALONE.items():
        for key in units(selection).keys() - workspace.keys():
            package, target, mode, features, profile, _ = key
            side = "host" if json.loads(profile)["opt_level"] == "0" else "target"
            built = features_built.get((package, target, mode, profile), [])
            problems.append(f"{what}: {package.split('#')[-1]} ({target}, {mode}, {side}) with features {list(features)}; "
                            f"the workspace's build has {built or 'no such unit'}")
    if problems:
        print("check-unified-features: these would be compiled a second time; give workspace-hack/Cargo.toml "
              "the workspace's features for them:", *sorted(set(problems)), sep="\n  ", file=sys.stderr)
        return 1
    print(f"check-unified-features: ok ({', '.join(BUILT_ALONE)} compile nothing beyond the workspace's build)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
