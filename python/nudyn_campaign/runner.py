"""Running a campaign on Dask: export the FMUs once, send their bytes to
every worker once, fly the missing cases in chunks, and write each chunk's
rows as it finishes (so an interrupted campaign resumes where it stopped).

    from nudyn_campaign import run_campaign
    table = run_campaign("examples/campaigns/detumble.toml", "out/detumble", cases=200)
"""

from __future__ import annotations

import importlib
import logging
import math
import os
import signal
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from nudyn_driver.cli import Nudyn
from nudyn_driver.locations import nudyn_binary
from nudyn_driver.package import FmuPackage

from . import provenance, variables
from . import spec as specs
from .files import OutputError, locked, write_atomically
from .spec import CampaignError
from .metrics import NAMES

# pyarrow, Dask, tqdm and the workers' code (cases.py: MuJoCo, FMPy) are
# imported where they are used: a campaign refused before any case (a bad
# file, --out, target or metric) needs none of them, and its one-line error
# comes in a third of the time.
if TYPE_CHECKING:
    import pyarrow as pa

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
    """The plant FMU (and the controller's, for a closed loop) in out/fmus/,
    or the system file's."""
    if campaign.system:
        return _system_fmus(campaign.system)
    cli = Nudyn(nudyn)
    directory = out / "fmus"
    plant = cli.export(campaign.model, directory / "plant.fmu", outputs=PLANT_OUTPUTS,
                       wrench_inputs=campaign.wrench_bodies)
    controller = None
    if campaign.controller:
        controller = cli.export(campaign.model, directory / "controller.fmu", controller=True,
                                end_effector=campaign.end_effector)
    return Fmus(plant.read_bytes(), controller.read_bytes() if controller else None)


def _system_fmus(path: Path) -> Fmus:
    """The FMUs of a `nudyn system` file, whose plant must have the outputs the metrics read."""
    import zipfile

    from nudyn_driver import ssp

    system = ssp.read(path)
    with zipfile.ZipFile(path) as archive:
        plant, controller = (archive.read(system.sources[name]) for name in ("plant", "controller"))
    with tempfile.TemporaryDirectory() as directory:
        package = ssp.package(system, "plant", Path(directory))
        missing = [name for name in PLANT_OUTPUTS if name not in package.variables and not package.names(name)]
    if missing:
        raise CampaignError(f"campaign.system: the plant of {path.name} has no output {', '.join(missing)}, which the "
                            f"metrics read: write it with `nudyn system ... --outputs {','.join(PLANT_OUTPUTS)}`")
    return Fmus(plant, controller)


def finished_cases(out: Path) -> set[int]:
    """The cases whose rows are already written (in out/parts/)."""
    import pyarrow.parquet as pq

    done: set[int] = set()
    for part in sorted((out / "parts").glob("part-*.parquet")):
        done.update(pq.read_table(part, columns=["case"]).column("case").to_pylist())
    return done


def _table(rows: list[dict], columns: list[str]) -> pa.Table:
    import pyarrow as pa

    return pa.table({column: [row.get(column) for row in rows] for column in columns})


def _write_parquet(table: pa.Table, path: Path) -> None:
    """A file is either absent or complete, and only a regular file is replaced (files.py)."""
    import pyarrow.parquet as pq

    write_atomically(path, lambda temporary: pq.write_table(table, temporary))


def _client(workers: int | None, scheduler: str | None, scratch: Path):
    """A client of the scheduler, or of a local cluster whose workers keep
    their files under `scratch` (Dask's and, through TMPDIR, the chunks')."""
    import dask.config
    from dask.distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            return Client(scheduler), None
        except (OSError, TimeoutError, ValueError) as error:
            timeout = dask.config.get("distributed.comm.timeouts.connect")
            raise CampaignError(
                f"--scheduler {scheduler}: no Dask scheduler answered: {error} "
                f"(the wait, {timeout}, is DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT)"
            ) from None
    scratch.mkdir(exist_ok=True)  # a TMPDIR that does not exist would be passed over for /tmp
    # Worker processes import nudyn_campaign from the repository's python/.
    paths = [str(PACKAGES), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    os.environ["PYTHONPATH"] = os.pathsep.join(dict.fromkeys(paths))
    # The worker processes ignore SIGINT (a Ctrl-C reaches the whole process
    # group): the driver alone stops on it, and closes them.
    handler = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        # The scheduler's and the workers' Dask folders (temporary-directory) and the workers' own temporary files.
        with dask.config.set({"temporary-directory": str(scratch)}):
            # Its HTTP server on any free port: Dask's default, 8787, is taken by
            # a second campaign or any Dask session running meanwhile, and
            # Dask then warns on stderr (dashboard_address=None still binds it).
            cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                                   dashboard_address=":0", silence_logs=logging.ERROR, env={"TMPDIR": str(scratch)})
    finally:
        signal.signal(signal.SIGINT, handler)
    return Client(cluster), cluster


def _interrupt_quietly(signum, frame) -> None:
    """SIGINT during a run: Dask quiet first, then the interrupt."""
    _quiet_dask()
    raise KeyboardInterrupt


def _quiet_dask() -> None:
    """Dask's complaints about a cluster closed in the middle of its work say nothing more.

    Every logger under these names, not the parents alone: distributed's
    logging config gives some children their own level (tornado.application
    at ERROR), which a parent's level does not override, and a callback of
    the wait Ctrl-C broke logs there."""
    families = ("distributed", "tornado", "asyncio")
    names = [name for name in list(logging.root.manager.loggerDict)
             if any(name == family or name.startswith(family + ".") for family in families)]
    for name in {*families, *names}:
        logging.getLogger(name).setLevel(logging.CRITICAL + 1)


def _quiet_workers(client) -> None:
    """After Ctrl-C, the local cluster's workers quiet too, before it closes.

    Closing it after an interrupt, its scheduler may go before a worker's
    heartbeat, which then logs an error with a traceback on the command's
    stderr (seen on a loaded machine). The workers are the run's own and
    alive (they ignore SIGINT); a user's --scheduler's are left alone."""
    try:
        client.run(_quiet_dask)
    except Exception:  # noqa: BLE001  (the run is ending on the interrupt whatever this finds)
        pass


def prepare_out(out: Path) -> None:
    """OUT as a directory that can be written, or an OutputError naming the path and what is wrong."""
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out}: is a file, not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as error:
        parent = next((p for p in out.parents if p.exists()), None)
        if parent is not None and not parent.is_dir():
            raise OutputError(f"--out {out}: cannot be created: {parent} is a file, not a directory") from None
        raise OutputError(f"--out {out}: cannot be written: {error.strerror or error}") from None


def check_metrics(campaign: specs.Campaign) -> None:
    """Each `module:function` of campaign.metrics imports here, as it must on the workers."""
    for name in campaign.metrics:
        module, _, attribute = name.partition(":")
        try:
            function = getattr(importlib.import_module(module), attribute)
        except ImportError as error:
            raise CampaignError(f"campaign.metrics: '{name}': cannot import {module}: {error}") from None
        except AttributeError:
            raise CampaignError(f"campaign.metrics: '{name}': module {module} has no {attribute}") from None
        if not callable(function):
            raise CampaignError(f"campaign.metrics: '{name}' is not a function")


def _packages(fmus: Fmus, scratch: Path) -> tuple[FmuPackage, FmuPackage | None]:
    """The FMUs unzipped into `scratch`, for their variables."""
    packages = []
    for kind, fmu in (("plant", fmus.plant), ("controller", fmus.controller)):
        if fmu is None:
            packages.append(None)
            continue
        archive = scratch / f"{kind}.fmu"
        archive.write_bytes(fmu)
        packages.append(FmuPackage.unzip(archive, scratch / kind))
    return packages[0], packages[1]


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
    overwrite: bool = False,
) -> pa.Table:
    """Runs (or resumes) the campaign; returns the results table, also
    written to OUT/results.parquet with the report beside it. A rerun
    resumes only rows flown from the same campaign (provenance.py);
    `overwrite` removes rows of another and starts afresh."""
    campaign = specs.load(campaign_path)
    if cases is not None:
        if cases < 1:
            raise CampaignError(f"--cases: expected at least 1 case, found {cases}")
        campaign.cases = cases
    if workers is not None and workers < 1:
        raise CampaignError(f"--workers: expected at least 1 worker process, found {workers}")
    check_metrics(campaign)
    out = Path(out)
    prepare_out(out)
    nudyn = Path(nudyn or nudyn_binary())
    # The scratch folder holds the local cluster's worker folders too, so
    # that nothing is left in the temporary directory, however the run ends.
    with locked(out), tempfile.TemporaryDirectory(prefix="nudyn-campaign-", ignore_cleanup_errors=True) as scratch:
        return _run_locked(campaign, out, nudyn, Path(scratch), workers, scheduler, progress, stop_after_chunks,
                           overwrite)


def _run_locked(campaign, out, nudyn, scratch, workers, scheduler, progress, stop_after_chunks, overwrite) -> pa.Table:
    """run_campaign's work, with OUT locked and `scratch` its temporary folder."""
    fmus = export(campaign, scratch, nudyn)
    variables.check(campaign, *_packages(fmus, scratch))
    provenance.resume_or_start(out, provenance.flown_from(campaign, fmus.plant, fmus.controller), overwrite,
                               provenance.replaced_files(campaign, out))
    for name, fmu in (("plant.fmu", fmus.plant), ("controller.fmu", fmus.controller)):
        if fmu is not None:
            write_atomically(out / "fmus" / name, lambda temporary, fmu=fmu: temporary.write_bytes(fmu))
    done = finished_cases(out)
    missing = [k for k in range(campaign.cases) if k not in done]
    worker_spec = {
        **campaign.as_dict(),
        "targets": [(d.key, d.scope, list(d.names)) for d in campaign.dispersions],
    }
    columns = ["case", *campaign.columns(), *NAMES]
    if missing:
        client, cluster = _client(workers, scheduler, scratch / "workers")
        # Dask's loop thread logs its own complaint about the wait that
        # Ctrl-C breaks, racing the KeyboardInterrupt: quiet it before the
        # interrupt is raised, in the signal handler itself.
        # (Python takes signal handlers in the main thread only.)
        main_thread = threading.current_thread() is threading.main_thread()
        interrupt = signal.signal(signal.SIGINT, _interrupt_quietly) if main_thread else None
        try:
            _run(client, campaign, worker_spec, fmus, missing, out, progress, stop_after_chunks, len(done))
        except KeyboardInterrupt:
            if cluster is not None:
                _quiet_workers(client)
            raise
        finally:
            if main_thread:
                signal.signal(signal.SIGINT, interrupt)
            client.close()
            if cluster is not None:
                cluster.close()
    return consolidate(campaign, out, columns)


def _run(client, campaign, worker_spec, fmus, missing, out, progress, stop_after_chunks, already) -> None:
    import pyarrow as pa
    from dask.distributed import as_completed
    from tqdm import tqdm

    from .cases import run_chunk

    workers = max(1, len(client.scheduler_info().get("workers", {})))
    size = max(1, min(50, math.ceil(len(missing) / (4 * workers))))
    chunks = [missing[i : i + size] for i in range(0, len(missing), size)]
    mjcf = campaign.model.read_text() if campaign.model else None
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
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    parts = [pq.read_table(part) for part in sorted((out / "parts").glob("part-*.parquet"))]
    table = pa.concat_tables(parts, promote_options="default") if parts else pa.table({c: [] for c in columns})
    # A rerun with fewer --cases keeps the finished parts but reports only its own cases.
    table = table.filter(pc.less(table["case"], campaign.cases)) if parts else table
    table = table.sort_by("case")
    _write_parquet(table, out / "results.parquet")
    from .report import write_report

    write_report(campaign, table, out)
    return table
