#!/usr/bin/env python3
"""Time to the accuracy asked through the FMI interface, against MuJoCo's
RK4 (python/nudyn_bench/tolerance.py; --help). `bash scripts/bench.sh`
runs it after bench.py.

    .venv/bin/python scripts/bench_tolerance.py [--out docs/bench] [--quick]
"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "python"))

from nudyn_bench.tolerance import main  # noqa: E402  (needs the path above)

sys.exit(main())
