#!/usr/bin/env python3
"""nudyn's stress suite: exports each stress vehicle as an FMU, runs it
through FMPy, and writes a figure per case, stress.md and stress.json.

    .venv/bin/python scripts/stress.py [--long] [--case NAME]... [--out DIR]

The short mode (default, a couple of minutes) is what CI runs; --long runs
the issue's full lengths (10^4 s of tumbling, ...).  Exits with 1 when a
case fails its checks, 2 when the suite cannot run.
"""
import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))

from nudyn_stress.cases import CASES, Context  # noqa: E402  (needs the path above)
from nudyn_driver.errors import DriverError  # noqa: E402
from nudyn_stress.report import write  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--long", action="store_true", help="the full lengths (10^4 s tumbling, ...)")
    parser.add_argument("--case", action="append", choices=list(CASES), help="run only this case (repeatable)")
    parser.add_argument("--out", type=Path, help="output directory (default out/stress or out/stress-long)")
    parser.add_argument("--nudyn", type=Path, default=ROOT / "target" / "release" / "nudyn")
    args = parser.parse_args()
    out = args.out or ROOT / "out" / ("stress-long" if args.long else "stress")
    if not args.nudyn.is_file():
        print(f"nudyn binary not found at {args.nudyn}: run `cargo build --release --workspace`", file=sys.stderr)
        return 2
    ctx = Context(args.nudyn, out, args.long)
    results = []
    for name in args.case or list(CASES):
        start = time.perf_counter()
        try:
            result = CASES[name](ctx)
        except DriverError as e:
            print(e, file=sys.stderr)
            return 2
        results.append(result)
        print(f"{name}: {'pass' if result.passed else 'FAIL'} ({time.perf_counter() - start:.0f} s): {result.verdict}",
              flush=True)
    paths = write(results, out, args.long)
    print(paths["table"].read_text())
    print(f"wrote {paths['table']}, {paths['json']} and a PNG per case in {out}")
    return 0 if all(r.passed for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
