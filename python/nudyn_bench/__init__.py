"""nudyn's benchmarks against MuJoCo and Pinocchio: `scripts/bench.py`."""
