#!/usr/bin/env python3
"""`method = auto` and the default dop853 against MuJoCo, in the native
host and in FMPy, on the examples and 10 random six-body trees
(python/nudyn_bench/auto.py; --help): the measurements of issue 36.

    .venv/bin/python scripts/bench_auto.py [--out docs/bench] [--quick]
"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "python"))

from nudyn_bench.auto import main  # noqa: E402  (needs the path above)

sys.exit(main())
