#!/usr/bin/env python3
"""What each adaptive method costs per tolerance on the examples, integrated
natively (python/nudyn_bench/methods.py; --help): the measurements that
choose between them.

    .venv/bin/python scripts/bench_methods.py [--out docs/bench] [--quick]
"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "python"))

from nudyn_bench.methods import main  # noqa: E402  (needs the path above)

sys.exit(main())
