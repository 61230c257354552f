"""Running a campaign on Dask: export the FMUs once, send their bytes to
every worker once, fly the missing cases in chunks, and write each chunk's
rows as it finishes (so an interrupted campaign resumes where it stopped).

    from nudyn_campaign import run_campaign
    table = run_campaign("examples/campaigns/detumble.toml", "out/detumble", cases=200)
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
from tqdm import tqdm

from nudyn_driver.cli import Nudyn
from nudyn_driver.locations import nudyn_binary

from . import spec as specs
from .cases import run_chunk
from .files import write_atomically
from .metrics import NAMES

# The folder holding these packages: python/ of a checkout, site-packages of the wheel.
PACKAGES = Path(__file__).resolve().parents[1]
# The plant's outputs the metrics read besides theta and nu.
PLANT_OUTPUTS = ("kinetic_energy", "momentum")


class CampaignInterrupted(RuntimeError):
    """The campaign stopped before every case ran (`stop_after_chunks`)."""


@dataclass
class Fmus:
    plant: bytes
    controller: bytes | None


def export(campaign: specs.Campaign, out: Path, nudyn: Path) -> Fmus:
    """The plant FMU (and the controller's, for a closed loop) in out/fmus/."""
    cli = Nudyn(nudyn)
    directory = out / "fmus"
    plant = cli.export(campaign.model, directory / "plant.fmu", outputs=PLANT_OUTPUTS,
                       wrench_inputs=campaign.wrench_bodies)
    controller = None
    if campaign.controller:
        controller = cli.export(campaign.model, directory / "controller.fmu", controller=True,
                                end_effector=campaign.end_effector)
    return Fmus(plant.read_bytes(), controller.read_bytes() if controller else None)


def finished_cases(out: Path) -> set[int]:
    """The cases whose rows are already written (in out/parts/)."""
    done: set[int] = set()
    for part in sorted((out / "parts").glob("part-*.parquet")):
        done.update(pq.read_table(part, columns=["case"]).column("case").to_pylist())
    return done


def _table(rows: list[dict], columns: list[str]) -> pa.Table:
    return pa.table({column: [row.get(column) for row in rows] for column in columns})


def _write_parquet(table: pa.Table, path: Path) -> None:
    """A file is either absent or complete, and only a regular file is replaced (files.py)."""
    write_atomically(path, lambda temporary: pq.write_table(table, temporary))


def _client(workers: int | None, scheduler: str | None):
    from dask.distributed import Client, LocalCluster

    if scheduler is not None:
        return Client(scheduler), None
    # Worker processes import nudyn_campaign from the repository's python/.
    paths = [str(PACKAGES), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    os.environ["PYTHONPATH"] = os.pathsep.join(dict.fromkeys(paths))
    cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                           dashboard_address=None)
    return Client(cluster), cluster


def run_campaign(
    campaign_path: str | Path,
    out: str | Path,
    *,
    cases: int | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    nudyn: str | Path | None = None,
    progress: bool = True,
    stop_after_chunks: int | None = None,
) -> pa.Table:
    """Runs (or resumes) the campaign; returns the results table, also
    written to OUT/results.parquet with the report beside it."""
    campaign = specs.load(campaign_path)
    if cases is not None:
        campaign.cases = cases
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    nudyn = Path(nudyn or nudyn_binary())
    fmus = export(campaign, out, nudyn)
    done = finished_cases(out)
    missing = [k for k in range(campaign.cases) if k not in done]
    worker_spec = {
        **campaign.as_dict(),
        "targets": [(d.key, d.scope, list(d.names)) for d in campaign.dispersions],
    }
    columns = ["case", *campaign.columns(), *NAMES]
    if missing:
        client, cluster = _client(workers, scheduler)
        try:
            _run(client, campaign, worker_spec, fmus, missing, out, progress, stop_after_chunks, len(done))
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    return consolidate(campaign, out, columns)


def _run(client, campaign, worker_spec, fmus, missing, out, progress, stop_after_chunks, already) -> None:
    from dask.distributed import as_completed

    workers = max(1, len(client.scheduler_info().get("workers", {})))
    size = max(1, min(50, math.ceil(len(missing) / (4 * workers))))
    chunks = [missing[i : i + size] for i in range(0, len(missing), size)]
    mjcf = campaign.model.read_text()
    plant = client.scatter(fmus.plant, broadcast=True, hash=False)
    controller = client.scatter(fmus.controller, broadcast=True, hash=False) if fmus.controller else None
    futures = [
        client.submit(run_chunk, worker_spec, plant, controller, mjcf,
                      [(k, specs.draw(campaign, k)) for k in chunk], pure=False)
        for chunk in chunks
    ]
    failed, written, started = 0, 0, time.perf_counter()
    bar = tqdm(total=campaign.cases, initial=already, unit="case", disable=not progress, desc=campaign.name)
    try:
        for future in as_completed(futures):
            rows = future.result()
            for row in rows:
                trajectory = row.pop("_trajectory", None)
                if trajectory is not None:
                    _write_parquet(pa.table(trajectory), out / "trajectories" / f"case-{row['case']:06d}.parquet")
            columns = list(dict.fromkeys(key for row in rows for key in row))
            _write_parquet(_table(rows, columns), out / "parts" / f"part-{rows[0]['case']:06d}.parquet")
            failed += sum(row["status"] != "ok" for row in rows)
            bar.update(len(rows))
            bar.set_postfix(failed=failed, rate=f"{bar.n - already:.0f}/{time.perf_counter() - started:.1f}s")
            written += 1
            if stop_after_chunks is not None and written >= stop_after_chunks:
                for pending in futures:
                    pending.cancel()
                raise CampaignInterrupted(f"stopped after {written} chunk(s), as asked")
    finally:
        bar.close()


def consolidate(campaign: specs.Campaign, out: Path, columns: list[str]) -> pa.Table:
    """Every written part, in case order, as OUT/results.parquet."""
    parts = [pq.read_table(part) for part in sorted((out / "parts").glob("part-*.parquet"))]
    table = pa.concat_tables(parts, promote_options="default") if parts else pa.table({c: [] for c in columns})
    # A rerun with fewer --cases keeps the finished parts but reports only its own cases.
    table = table.filter(pc.less(table["case"], campaign.cases)) if parts else table
    table = table.sort_by("case")
    _write_parquet(table, out / "results.parquet")
    from .report import write_report

    write_report(campaign, table, out)
    return table
