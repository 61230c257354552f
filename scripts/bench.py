#!/usr/bin/env python3
"""nudyn's benchmarks against MuJoCo and Pinocchio; see
python/nudyn_bench/cli.py, or run with --help. `bash scripts/bench.sh`
builds first and runs this.

    .venv/bin/python scripts/bench.py [--out docs/bench] [--quick]
"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "python"))

from nudyn_bench.cli import main  # noqa: E402  (needs the path above)

sys.exit(main())
