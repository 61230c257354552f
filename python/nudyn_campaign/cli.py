"""The `nudyn-campaign` command."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from nudyn_driver.errors import DriverError

from .files import OutputError
from .runner import CampaignInterrupted, run_campaign
from .spec import CampaignError


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        prog="nudyn-campaign",
        description="Run a Monte Carlo campaign or parameter sweep of a vehicle's FMU on Dask "
        "(resumes: a rerun of the same campaign flies only the cases not yet in DIR).",
    )
    p.add_argument("campaign", type=Path, help="campaign file (TOML; see docs/campaigns.md)")
    p.add_argument("--out", type=Path, required=True, help="output directory: results.parquet, report.md, plots")
    p.add_argument("--cases", type=int, help="number of cases (default: the file's campaign.cases)")
    p.add_argument("--workers", type=int, help="worker processes of the local cluster (default: one per core)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler, e.g. tcp://10.0.0.5:8786")
    p.add_argument("--nudyn", type=Path, help="the nudyn binary (default $NUDYN_BIN or target/release/nudyn)")
    p.add_argument("--overwrite", action="store_true",
                   help="remove rows in DIR flown from another campaign (other seed, dispersions, FMUs) and start afresh")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = p.parse_args(argv)
    if args.cases is not None and args.cases < 1:
        p.error("--cases must be at least 1")
    if args.workers is not None and args.workers < 1:
        p.error("--workers must be at least 1")
    try:
        table = run_campaign(args.campaign, args.out, cases=args.cases, workers=args.workers,
                             scheduler=args.scheduler, nudyn=args.nudyn, progress=not args.no_progress,
                             overwrite=args.overwrite)
    except (CampaignError, DriverError, CampaignInterrupted, OutputError) as error:
        print(f"nudyn-campaign: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        # The rows of finished chunks are in DIR/parts: a rerun flies the rest.
        print(f"nudyn-campaign: interrupted; rerun to resume ({args.out})", file=sys.stderr)
        return 130
    failed = sum(status != "ok" for status in table.column("status").to_pylist())
    print(f"{table.num_rows} cases ({failed} failed): {args.out / 'results.parquet'}, {args.out / 'report.md'}")
    return 0
