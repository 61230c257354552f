#!/usr/bin/env python3
"""The examples' FMU timed in the Reference FMUs' fmusim (built by hand,
not here) beside the native host and MuJoCo RK4
(python/nudyn_bench/fmusim.py; --help): issue 36's second native host.

    .venv/bin/python scripts/bench_fmusim.py --fmusim PATH [--out DIR] [--quick]
"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "python"))

from nudyn_bench.fmusim import main  # noqa: E402  (needs the path above)

sys.exit(main())
