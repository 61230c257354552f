"""Throughput of nudyn-campaign, measured (not asserted): the detumble
example's first 200 cases on a local cluster of 1 and of 2 workers, and the
same cases flown in a bare loop in this process (one plant and one
controller instance reset between cases, as a worker does, without Dask).

    .venv/bin/python scripts/campaign_throughput.py [--cases 200] [--out out/campaign-throughput]
"""

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))

from nudyn_campaign import load, run_campaign  # noqa: E402
from nudyn_campaign.cases import run_chunk  # noqa: E402
from nudyn_campaign.runner import export  # noqa: E402
from nudyn_campaign.spec import draw  # noqa: E402

CAMPAIGN = ROOT / "examples" / "campaigns" / "detumble.toml"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cases", type=int, default=200)
    p.add_argument("--out", type=Path, default=ROOT / "out" / "campaign-throughput")
    p.add_argument("--nudyn", type=Path, default=ROOT / "target" / "release" / "nudyn")
    args = p.parse_args()
    campaign = load(CAMPAIGN)
    fmus = export(campaign, args.out / "bare", args.nudyn)
    spec = {**campaign.as_dict(), "targets": [(d.key, d.scope, list(d.names)) for d in campaign.dispersions]}
    cases = [(k, draw(campaign, k)) for k in range(args.cases)]
    start = time.perf_counter()
    run_chunk(spec, fmus.plant, fmus.controller, campaign.model.read_text(), cases)
    bare = time.perf_counter() - start
    result = {"cases": args.cases, "bare_loop_seconds": bare}
    for workers in (1, 2):
        out = args.out / f"workers-{workers}"
        for part in (out / "parts").glob("*.parquet"):
            part.unlink()
        start = time.perf_counter()
        run_campaign(CAMPAIGN, out, cases=args.cases, workers=workers, nudyn=args.nudyn, progress=False)
        result[f"workers_{workers}_seconds"] = time.perf_counter() - start
    for key in ("bare_loop", "workers_1", "workers_2"):
        result[f"{key}_cases_per_second"] = args.cases / result[f"{key}_seconds"]
    result["overhead_per_case_ms_1_worker"] = 1e3 * (result["workers_1_seconds"] - bare) / args.cases
    print(json.dumps(result, indent=1))
    (args.out / "throughput.json").write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
