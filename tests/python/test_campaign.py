"""nudyn-campaign (python/nudyn_campaign) on Dask: the same table on one
worker, on two, and on a real scheduler with two worker processes on
loopback (one killed mid-campaign); failed cases recorded, never lost;
resume after an interruption; any case rerun alone; clear errors for bad
campaign files. Small flights (bus_arm7, 1 s), so the file runs in about a
minute on two cores."""

from __future__ import annotations

import json
import logging
import os
import signal
import stat
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from conftest import EXAMPLES_DIR, ROOT
from nudyn_campaign import CampaignError, CampaignInterrupted, load, run_campaign
from nudyn_campaign.files import OutputError
from nudyn_campaign.runner import consolidate, export
from nudyn_campaign.cases import run_chunk
from nudyn_campaign.spec import draw

CLOSED_LOOP = """
[campaign]
name = "small_detumble"
model = "{model}"
seed = 7
cases = 12
duration = 1.0
step = 0.05
controller = true
settle_threshold = 2.0

[plant]
tolerance = 1e-6

[dispersions]
"qvel[4:6]" = {{ normal = [0.0, 0.3] }}
"qvel[7]" = {{ uniform = [-0.3, 0.3] }}
"controller.c1" = {{ grid = [1.0, 4.0] }}
"""

# Open loop, some cases with a huge held ε: the FMU discards their first step.
WITH_FAILURES = """
[campaign]
model = "{model}"
seed = 3
cases = 16
duration = 0.5
step = 0.05

[dispersions]
"nu[4]" = {{ normal = [0.0, 0.5] }}
"eps[10]" = {{ choice = [0.0, 0.1, 1e300] }}
"""


def write(tmp_path: Path, text: str, name: str = "campaign.toml") -> Path:
    path = tmp_path / name
    path.write_text(text.format(model=ROOT / "examples" / "bus_arm7.xml"))
    return path


def campaign_command(*arguments, env=None) -> subprocess.CompletedProcess:
    """`nudyn-campaign ARGUMENTS` run to its end."""
    return subprocess.run([sys.executable, "-m", "nudyn_campaign", *map(str, arguments)], capture_output=True,
                          text=True, env={**os.environ, "PYTHONPATH": str(ROOT / "python"), **(env or {})})


def one_line_error(proc: subprocess.CompletedProcess, expected: str) -> None:
    """Exit status 2 and one line on stderr, naming what is wrong: no traceback."""
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith("nudyn-campaign: "), proc.stderr
    assert expected in proc.stderr, proc.stderr


def rows(table) -> str:
    """The table's rows, NaN-safe and exact (repr of every float)."""
    return json.dumps(table.to_pylist(), sort_keys=True)


@pytest.fixture(scope="module")
def scheduler():
    """The address of one local Dask cluster (a worker process) for the
    tests whose campaigns are about their rows and files, not about the
    cluster that flies them, as a user's `--scheduler`: a cluster of their
    own each (run_campaign's `workers`) took about 2 CPU-s to start and
    stop. Its worker imports nudyn_campaign from this checkout's python/,
    as run_campaign's own workers do. Its HTTP server takes any free port:
    Dask's default, 8787, held for the module, would make the local
    clusters of the commands run meanwhile warn on stderr that it is taken."""
    from dask.distributed import LocalCluster

    paths = [str(ROOT / "python"), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("PYTHONPATH", os.pathsep.join(dict.fromkeys(paths)))
        cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0",
                               silence_logs=logging.ERROR)
    with cluster:
        yield cluster.scheduler_address


@pytest.fixture(scope="module")
def one_worker(nudyn, scheduler, tmp_path_factory):
    """The closed-loop campaign on the module's cluster (one worker): the
    table the other runs must give."""
    directory = tmp_path_factory.mktemp("campaign")
    path = write(directory, CLOSED_LOOP)
    return path, run_campaign(path, directory / "one", scheduler=scheduler, nudyn=nudyn, progress=False)


def test_every_case_is_a_row_with_its_draws_and_metrics(one_worker):
    path, table = one_worker
    assert table.column("case").to_pylist() == list(range(12))
    assert set(table.column("status").to_pylist()) == {"ok"}
    assert table.column("controller.c1").to_pylist() == [1.0, 4.0] * 6
    campaign = load(path)
    assert table.column("qvel[4:6]").to_pylist()[5] == draw(campaign, 5)["qvel[4:6]"]
    for metric in ("peak_nu", "final_nu", "final_error", "control_effort"):
        assert all(v > 0 for v in table.column(metric).to_pylist()), metric
    # The higher gain damps faster: every c1 = 4 case ends slower than it started by more.
    by_gain = {}
    for row in table.to_pylist():
        by_gain.setdefault(row["controller.c1"], []).append(row["final_nu"] / row["peak_nu"])
    assert max(by_gain[4.0]) < min(by_gain[1.0])
    out = path.parent / "one"
    assert rows(pq.read_table(out / "results.parquet")) == rows(table)
    report = (out / "report.md").read_text()
    assert "12 of 12 cases run: 12 ok" in report and "## Against controller.c1" in report
    assert (out / "metrics.png").stat().st_size > 0 and (out / "controller.c1.png").stat().st_size > 0


def test_two_workers_give_the_same_table(one_worker, nudyn, tmp_path):
    path, table = one_worker
    two = run_campaign(path, tmp_path / "two", workers=2, nudyn=nudyn, progress=False)
    assert rows(two) == rows(table)


def test_any_case_reruns_alone_to_the_same_numbers(one_worker, nudyn, tmp_path):
    path, table = one_worker
    campaign = load(path)
    fmus = export(campaign, tmp_path, nudyn)
    spec = {**campaign.as_dict(), "targets": [(d.key, d.scope, list(d.names)) for d in campaign.dispersions]}
    (alone,) = run_chunk(spec, fmus.plant, fmus.controller, campaign.model.read_text(), [(9, draw(campaign, 9))])
    assert json.dumps(alone, sort_keys=True) == json.dumps(table.to_pylist()[9], sort_keys=True)


def test_failed_cases_are_recorded_and_the_rest_complete(nudyn, scheduler, tmp_path):
    table = run_campaign(write(tmp_path, WITH_FAILURES), tmp_path / "out", scheduler=scheduler, nudyn=nudyn,
                         progress=False)
    assert table.num_rows == 16
    huge = [row for row in table.to_pylist() if row["eps[10]"] == 1e300]
    fine = [row for row in table.to_pylist() if row["eps[10]"] != 1e300]
    assert huge and fine
    assert all(row["status"] == "discard" and "fmi2DoStep" in row["message"] for row in huge), huge[0]
    assert all(row["status"] == "ok" and row["message"] == "" for row in fine)
    assert "## Failed cases" in (tmp_path / "out" / "report.md").read_text()


def test_an_interrupted_campaign_resumes_with_the_missing_cases_only(one_worker, nudyn, scheduler, tmp_path):
    path, table = one_worker
    out = tmp_path / "resumed"
    with pytest.raises(CampaignInterrupted):
        run_campaign(path, out, scheduler=scheduler, nudyn=nudyn, progress=False, stop_after_chunks=1)
    parts = sorted((out / "parts").glob("part-*.parquet"))
    assert len(parts) == 1
    first = {part: part.stat().st_mtime_ns for part in parts}
    done = pq.read_table(parts[0]).num_rows
    assert 0 < done < 12
    resumed = run_campaign(path, out, scheduler=scheduler, nudyn=nudyn, progress=False)
    assert rows(resumed) == rows(table)
    # The finished part was not run again.
    assert all(part.stat().st_mtime_ns == mtime for part, mtime in first.items())
    assert len(list((out / "parts").glob("part-*.parquet"))) > 1


def _dask(*arguments, env) -> subprocess.Popen:
    return subprocess.Popen([str(Path(sys.executable).parent / "dask"), *arguments], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)


def test_a_real_scheduler_with_a_worker_killed_mid_campaign(one_worker, nudyn, tmp_path):
    """`dask scheduler` and two `dask worker` processes on loopback: the
    campaign through --scheduler gives the same table; with one worker
    killed mid-chunk once the first chunks are in, every case is still
    there. The killed worker's extracted FMUs (3 to 8 MB each) are in its
    Dask folder, not in the temporary directory, and the next worker
    started on that folder purges them (they were left in /tmp on every
    such kill)."""
    path, table = one_worker
    env = {**os.environ, "PYTHONPATH": str(ROOT / "python")}
    temporary, local = tmp_path / "tmp", tmp_path / "dask"
    temporary.mkdir()
    worker_env = {**env, "TMPDIR": str(temporary)}

    def chunk_folders(worker: str) -> list:
        """The chunk folders in the worker's Dask folders (each
        dask-scratch-space/worker-*/, beside its worker-*.dirlock file), read
        while the worker may be removing them: a folder gone meanwhile is
        not listed."""
        found = []
        for scratch in (local / worker / "dask-scratch-space").glob("worker-*"):
            try:
                found += [entry for entry in scratch.iterdir() if entry.name.startswith("nudyn-campaign-")]
            except (FileNotFoundError, NotADirectoryError):
                pass
        return found

    def worker(name: str) -> subprocess.Popen:
        return _dask("worker", address, "--nthreads", "1", "--no-dashboard", "--name", name,
                     "--local-directory", str(local / name), env=worker_env)
    scheduler_file = tmp_path / "scheduler.json"
    processes = [_dask("scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                       "--scheduler-file", str(scheduler_file), env=env)]
    try:
        for _ in range(600):
            if scheduler_file.exists() and scheduler_file.stat().st_size:
                break
            time.sleep(0.1)
        address = json.loads(scheduler_file.read_text())["address"]
        workers = [worker(f"w{k}") for k in range(2)]
        processes += workers
        same = run_campaign(path, tmp_path / "cluster", scheduler=address, nudyn=nudyn, progress=False)
        assert rows(same) == rows(table)

        # A longer campaign; kill a worker once the first chunks are written.
        out = tmp_path / "killed"
        cli = subprocess.Popen([sys.executable, "-m", "nudyn_campaign", str(path), "--out", str(out), "--cases", "60",
                                "--scheduler", address, "--no-progress", "--nudyn", str(nudyn)],
                               env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for _ in range(600):
            if len(list((out / "parts").glob("part-*.parquet"))) >= 2 and chunk_folders("w0") or cli.poll() is not None:
                break
            time.sleep(0.05)
        os.killpg(workers[0].pid, signal.SIGKILL)
        stdout, stderr = cli.communicate(timeout=600)
        assert cli.returncode == 0, stderr[-3000:]
        killed = pq.read_table(out / "results.parquet")
        assert killed.column("case").to_pylist() == list(range(60))
        assert set(killed.column("status").to_pylist()) == {"ok"}
        assert rows(killed.slice(0, 12)) == rows(table)

        assert chunk_folders("w0"), "the worker was killed mid-chunk"
        assert list(temporary.iterdir()) == []
        processes.append(worker("w0"))
        for _ in range(600):
            if not chunk_folders("w0"):
                break
            time.sleep(0.1)
        assert chunk_folders("w0") == []
    finally:
        for process in processes:
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()


@pytest.mark.parametrize(
    "text, expected",
    [
        ("[campaign]\nmodel = '{model}'\ncases = 2\nduration = 1.0\n", "campaign.step is missing"),
        ("[campaign]\nmodel = '{model}'\ncases = 2\nduration = 1.0\nstep = 0.3\n", "must be positive and divide"),
        ("[campaign]\nmodel = 'nope.xml'\ncases = 2\nduration = 1.0\nstep = 0.5\n", "campaign.model: no such file"),
        ("[campaign]\nmodel = '{model}'\ncases = 2\nduration = 1.0\nstep = 0.5\nspeed = 3\n", "unknown key(s) speed"),
        ("[campaign]\nmodel = '{model}'\ncases = 2\nduration = 1.0\nstep = 0.5\n[dispersions]\n'omega[1]' = {{ normal = [0, 1] }}\n",
         "'omega' is no start value or input"),
        ("[campaign]\nmodel = '{model}'\ncases = 2\nduration = 1.0\nstep = 0.5\n[dispersions]\n'nu[1]' = {{ gauss = [0, 1] }}\n",
         "unknown distribution 'gauss'"),
        ("[campaign]\nmodel = '{model}'\ncases = 2\nduration = 1.0\nstep = 0.5\n[dispersions]\n'nu[1]' = {{ uniform = [2, 1] }}\n",
         "low 2.0 exceeds high 1.0"),
        ("[campaign]\nmodel = '{model}'\ncases = 2\nduration = 1.0\nstep = 0.5\n[dispersions]\n'controller.c1' = {{ grid = [1] }}\n",
         "need campaign.controller = true"),
        # Overlapping dispersions would record a value the flight never used.
        ("[campaign]\nmodel = '{model}'\ncases = 2\nduration = 1.0\nstep = 0.5\n[dispersions]\n"
         "'nu[1:3]' = {{ normal = [0, 1] }}\n'nu[2]' = {{ normal = [5, 1] }}\n",
         "'nu[1:3]' and 'nu[2]' both set plant variable nu[2]"),
        ("[campaign]\nmodel = '{model}'\ncases = 2\nduration = 1.0\nstep = 0.5\n[dispersions]\n"
         "'nu[1]' = {{ normal = [0, 1] }}\n'qvel[1]' = {{ normal = [5, 1] }}\n",
         "'nu[1]' and 'qvel[1]' both set the start velocity ν"),
        ("[campaign]\nmodel = '{model}'\ncases = 2\nduration = 1.0\nstep = 0.5\ncontroller = true\n[dispersions]\n"
         "'controller.c1' = {{ grid = [1, 2] }}\n'controller.c1[3]' = {{ uniform = [0, 1] }}\n",
         "'controller.c1' and 'controller.c1[3]' both set controller variable c1[3]"),
        ("[campaign]\nmodel = '{model}'\ncases = 2\nduration = 1.0\nstep = 0.5\n[dispersions]\n"
         "'theta[2]' = {{ normal = [0, 1] }}\n'plant.theta[2]' = {{ normal = [5, 1] }}\n",
         "'theta[2]' and 'plant.theta[2]' both set plant variable theta[2]"),
        ("[campaign]\nmodel = '{model}'\ncases = 2\nduration = 1.0\nstep = 0.5\nmetrics = ['no_colon']\n",
         "campaign.metrics: expected a list of \"module:function\" names"),
    ],
)
def test_bad_campaign_files_are_clear_errors(text, expected, tmp_path):
    path = write(tmp_path, text)
    with pytest.raises(CampaignError, match=None) as error:
        load(path)
    assert expected in str(error.value), str(error.value)
    proc = campaign_command(path, "--out", tmp_path / "o")
    assert proc.returncode == 2 and expected in proc.stderr, proc.stderr


def test_a_metric_of_the_users_own(nudyn, tmp_path, monkeypatch):
    (tmp_path / "my_metrics.py").write_text(
        "import numpy as np\n"
        "def spin(flight):\n"
        "    n = flight.reached\n"
        "    return {'max_base_spin': float(np.max(np.abs(flight.nu[:n, 3:6])))}\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]))
    text = WITH_FAILURES.replace("step = 0.05", "step = 0.05\nmetrics = [\"my_metrics:spin\"]").replace("1e300", "0.2")
    table = run_campaign(write(tmp_path, text), tmp_path / "out", cases=4, workers=1, nudyn=nudyn, progress=False)
    spins = table.column("max_base_spin").to_pylist()
    assert len(spins) == 4 and all(s >= abs(n) for s, n in zip(spins, table.column("nu[4]").to_pylist()))


SERVICER_BURNS = """
[campaign]
model = "{servicer}"
seed = 11
cases = 4
duration = 3.0
step = 0.05

[dispersions]
"ctrl[9]" = {{ uniform = [-0.2, 0.2] }}
"nu[4]" = {{ normal = [0.0, 0.1] }}

[schedules]
# The four aft thrusters at full thrust for 2 s, then off.
"ctrl[1]" = [[0.0, 22.0], [2.0, 0.0]]
"ctrl[2]" = [[0.0, 22.0], [2.0, 0.0]]
"ctrl[3]" = [[0.0, 22.0], [2.0, 0.0]]
"ctrl[4]" = [[0.0, 22.0], [2.0, 0.0]]
"""


def test_input_schedules_and_the_impulse_per_actuator(nudyn, scheduler, tmp_path):
    path = tmp_path / "burns.toml"
    path.write_text(SERVICER_BURNS.format(servicer=ROOT / "examples" / "servicer.xml"))
    table = run_campaign(path, tmp_path / "out", scheduler=scheduler, nudyn=nudyn, progress=False)
    assert set(table.column("status").to_pylist()) == {"ok"}
    for row in table.to_pylist():
        impulse = row["impulse"]
        assert len(impulse) == 15
        # 22 N for 2 s on each aft thruster; the fore ones never fired.
        assert impulse[:4] == pytest.approx([44.0] * 4, rel=1e-12) and impulse[4:8] == [0.0] * 4
        # The wheel's dispersed torque, held for 3 s.
        assert impulse[8] == pytest.approx(abs(row["ctrl[9]"]) * 3.0, rel=1e-12)
    with pytest.raises(CampaignError, match="the times must increase"):
        bad = tmp_path / "bad.toml"
        bad.write_text(SERVICER_BURNS.format(servicer=ROOT / "examples" / "servicer.xml").replace("[2.0, 0.0]]", "[0.0, 0.0]]", 1))
        load(bad)


def test_trajectories_are_written_per_case_when_asked(nudyn, scheduler, tmp_path):
    text = WITH_FAILURES.replace("step = 0.05", "step = 0.05\ntrajectories = true")
    table = run_campaign(write(tmp_path, text), tmp_path / "out", cases=5, scheduler=scheduler, nudyn=nudyn,
                         progress=False)
    for row in table.to_pylist():
        trajectory = pq.read_table(tmp_path / "out" / "trajectories" / f"case-{row['case']:06d}.parquet")
        assert trajectory.column_names[:2] == ["time", "nu[1]"] and "nu[13]" in trajectory.column_names
        # A flight that ran has its 11 samples; a discarded one stops at its start.
        assert trajectory.num_rows == (11 if row["status"] == "ok" else 1), row
        assert trajectory.column("nu[4]").to_pylist()[0] == row["nu[4]"]


def test_the_integration_method_is_a_dispersion_too(nudyn, scheduler, tmp_path):
    text = WITH_FAILURES.replace("1e300", "0.2") + '"plant.method" = {{ grid = ["rk4", "dop853"] }}\n'
    table = run_campaign(write(tmp_path, text), tmp_path / "out", cases=4, scheduler=scheduler, nudyn=nudyn,
                         progress=False)
    assert table.column("plant.method").to_pylist() == ["rk4", "dop853"] * 2
    assert set(table.column("status").to_pylist()) == {"ok"}
    with pytest.raises(CampaignError, match="expected a finite number"):
        load(write(tmp_path, WITH_FAILURES + '"plant.tolerance" = {{ uniform = ["a", "b"] }}\n', "bad.toml"))


def test_only_a_regular_file_or_a_new_path_is_replaced(tmp_path):
    """The results are written as `nudyn export` writes an FMU
    (nudyn_campaign/files.py): a FIFO in their place is refused and stays a
    FIFO (opening it to write would have waited for a reader for ever), a
    symbolic link is written through, and no temporary file is left."""
    campaign = load(write(tmp_path, CLOSED_LOOP))
    out = tmp_path / "out"
    out.mkdir()
    fifo = out / "results.parquet"
    os.mkfifo(fifo)
    with pytest.raises(OutputError, match=f"{fifo} is a FIFO, not a regular file"):
        consolidate(campaign, out, ["case"])
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    fifo.unlink()
    elsewhere = tmp_path / "elsewhere.md"
    elsewhere.write_text("old")
    (out / "report.md").symlink_to(elsewhere)
    assert consolidate(campaign, out, ["case"]).num_rows == 0
    assert (out / "report.md").is_symlink() and elsewhere.read_text().startswith("# Campaign small_detumble")
    assert sorted(p.name for p in out.iterdir()) == ["metrics.png", "report.md", "results.parquet"]


# Open loop, short and small: what the resume and refusal tests fly.
SHORT = """
[campaign]
model = "{model}"
seed = 3
cases = 4
duration = 0.2
step = 0.05

[dispersions]
"nu[4]" = {{ normal = [0.0, 0.5] }}
"""


def test_a_rerun_resumes_only_rows_flown_from_the_same_campaign(nudyn, scheduler, tmp_path):
    """OUT/campaign.json records what the rows were flown from: a rerun
    with another seed, another dispersion or another plant FMU is refused
    with what differs (it used to report the old rows as the new campaign's,
    or end in a KeyError), and leaves the rows alone; --overwrite starts
    afresh; the same campaign with more cases resumes."""
    path = write(tmp_path, SHORT)
    out = tmp_path / "out"
    first = run_campaign(path, out, scheduler=scheduler, nudyn=nudyn, progress=False)
    parts = {part: part.stat().st_mtime_ns for part in (out / "parts").glob("part-*.parquet")}
    changes = [
        (SHORT.replace("seed = 3", "seed = 4"), "seed: 3 → 4"),
        (SHORT.replace('"nu[4]"', '"nu[5]"'), 'dispersions.nu[4]: {"normal": [0.0, 0.5]} → none; dispersions.nu[5]: none →'),
        (SHORT.replace("0.5]", "0.7]"), 'dispersions.nu[4]: {"normal": [0.0, 0.5]} → {"normal": [0.0, 0.7]}'),
        (SHORT.replace("step = 0.05", 'step = 0.05\nwrench_bodies = ["bus"]'), "plant FMU: "),
    ]
    for text, expected in changes:
        changed = write(tmp_path, text, "changed.toml")
        with pytest.raises(CampaignError, match="holds the rows of another campaign") as error:
            run_campaign(changed, out, scheduler=scheduler, nudyn=nudyn, progress=False)
        assert expected in str(error.value) and "--overwrite" in str(error.value), str(error.value)
        one_line_error(campaign_command(changed, "--out", out), expected)
    assert {part: part.stat().st_mtime_ns for part in (out / "parts").glob("part-*.parquet")} == parts
    assert rows(pq.read_table(out / "results.parquet")) == rows(first)

    reseeded = write(tmp_path, SHORT.replace("seed = 3", "seed = 4"), "reseeded.toml")
    afresh = run_campaign(reseeded, out, scheduler=scheduler, nudyn=nudyn, progress=False, overwrite=True)
    assert afresh.column("nu[4]").to_pylist() == [draw(load(reseeded), k)["nu[4]"] for k in range(4)]
    assert afresh.column("nu[4]").to_pylist() != first.column("nu[4]").to_pylist()
    assert "campaign seed 4" in (out / "report.md").read_text()
    more = run_campaign(reseeded, out, cases=6, scheduler=scheduler, nudyn=nudyn, progress=False)
    assert rows(more.slice(0, 4)) == rows(afresh) and more.num_rows == 6

    # Rows from before the record existed are not taken for anyone's.
    (out / "campaign.json").unlink()
    with pytest.raises(CampaignError, match="no record of what they were flown from"):
        run_campaign(reseeded, out, scheduler=scheduler, nudyn=nudyn, progress=False)


@pytest.mark.parametrize(
    "dispersion, expected",
    [
        ('"theta[99]" = {{ normal = [0, 1] }}', "dispersions.theta[99]: the plant FMU has theta[1] to theta[14] only"),
        ('"qvel[14]" = {{ normal = [0, 1] }}', "dispersions.qvel[14]: the plant FMU has qvel[1] to qvel[13] only"),
        ('"plant.tolerance" = {{ grid = ["tight", "loose"] }}',
         "dispersions.plant.tolerance: plant variable 'tolerance' takes a number (Real), not the names 'tight', 'loose'"),
        ('"plant.method" = {{ grid = ["rk4", "euler"] }}', "the plant FMU has no method 'euler' (it has rk4,"),
        ('"plant.kinetic_energy" = {{ uniform = [0, 1] }}', "the plant FMU computes 'kinetic_energy' (an output)"),
        ('"plant.gain" = {{ uniform = [0, 1] }}', "dispersions.plant.gain: the plant FMU has no variable 'gain'"),
        ('"nu[4]" = {{ normal = [0, 1] }}\n[schedules]\n"eps[99]" = [[0.0, 1.0]]',
         "schedules.eps[99]: the plant FMU has eps[1] to eps[13] only"),
        ('"nu[4]" = {{ normal = [0, 1] }}\n[plant]\nmax_steps = 10', "plant.max_steps: the plant FMU has no variable 'max_steps'"),
        ('"nu[4]" = {{ normal = [0, 1] }}\n[controller]\nc1 = 1.0', "controller.c1: [controller] needs campaign.controller = true"),
    ],
)
def test_targets_the_fmu_cannot_take_are_refused_before_any_case(dispersion, expected, nudyn, tmp_path):
    """Checked against the exported FMU's variables: theta[99] crashed the
    driver with an IndexError from inside a Dask task, names on a number
    ended in a traceback."""
    path = write(tmp_path, SHORT.partition("[dispersions]")[0] + "[dispersions]\n" + dispersion + "\n")
    with pytest.raises(CampaignError) as error:
        run_campaign(path, tmp_path / "out", workers=1, nudyn=nudyn, progress=False)
    assert expected in str(error.value), str(error.value)
    one_line_error(campaign_command(path, "--out", tmp_path / "out", "--nudyn", nudyn), expected)
    assert not (tmp_path / "out" / "parts").exists()


def test_bad_outputs_metrics_schedulers_and_worker_counts_are_one_line_errors(nudyn, tmp_path):
    path = write(tmp_path, SHORT)
    a_file = tmp_path / "a_file"
    a_file.write_text("")
    for out, expected in [
        (a_file, f"--out {a_file}: is a file, not a directory"),
        (a_file / "sub" / "dir", f"--out {a_file / 'sub' / 'dir'}: cannot be created: {a_file} is a file"),
        (Path("/proc/self/nudyn-campaign"), "--out /proc/self/nudyn-campaign: cannot be written: No such file or directory"),
    ]:
        one_line_error(campaign_command(path, "--out", out, "--nudyn", nudyn), expected)
    assert a_file.read_text() == ""

    missing = write(tmp_path, SHORT.replace("step = 0.05", 'step = 0.05\nmetrics = ["no_such_module:spin"]'), "m.toml")
    one_line_error(campaign_command(missing, "--out", tmp_path / "m", "--nudyn", nudyn),
                   "campaign.metrics: 'no_such_module:spin': cannot import no_such_module")

    # Nothing listens on a port just closed; Dask waits the configured connect timeout, then gives up. The
    # message names the wait in effect, and the run ends before Dask's default wait (30 s) would (the bound
    # was 20 s, which the command's start alone exceeded on a loaded machine).
    import socket

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    started = time.perf_counter()
    proc = campaign_command(path, "--out", tmp_path / "s", "--nudyn", nudyn, "--scheduler", f"tcp://127.0.0.1:{port}",
                            env={"DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "1s"})
    one_line_error(proc, f"--scheduler tcp://127.0.0.1:{port}: no Dask scheduler answered")
    assert "(the wait, 1s, is DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT)" in proc.stderr, proc.stderr
    assert time.perf_counter() - started < 28

    proc = campaign_command(path, "--out", tmp_path / "w", "--workers", "0")
    assert proc.returncode == 2 and "--workers must be at least 1" in proc.stderr, proc.stderr
    with pytest.raises(CampaignError, match="--workers: expected at least 1 worker process, found 0"):
        run_campaign(path, tmp_path / "w", workers=0, nudyn=nudyn, progress=False)


def test_a_campaign_beside_another_dask_session_says_nothing_on_stderr(nudyn, tmp_path):
    """Port 8787 (Dask's default for its HTTP server) held by another
    process, as by a second campaign or a user's own Dask session: the
    command's own cluster takes another port, and stderr stays empty."""
    import socket

    holder = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        holder.bind(("", 8787))
        holder.listen()
    except OSError:
        pass  # another process holds it already, which is the case under test
    with holder:
        path = write(tmp_path, SHORT)
        proc = subprocess.run([sys.executable, "-m", "nudyn_campaign", str(path), "--out", str(tmp_path / "out"),
                               "--workers", "1", "--no-progress", "--nudyn", str(nudyn)], capture_output=True,
                              text=True, timeout=300, env={**os.environ, "PYTHONPATH": str(ROOT / "python")})
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr


def test_ctrl_c_ends_with_how_to_resume_and_the_rerun_completes(nudyn, scheduler, tmp_path):
    """SIGINT to the command's process group (what Ctrl-C in a terminal
    sends, to the Dask workers too) once the first chunk is written: one
    line, status 130, no traceback from the driver or the workers; the
    rerun flies the rest. The interrupted run leaves nothing in the
    temporary directory (the workers' FMUs, Dask's folders)."""
    path = write(tmp_path, SHORT.replace("cases = 4", "cases = 80").replace("duration = 0.2", "duration = 1.0"))
    out = tmp_path / "out"
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    command = [sys.executable, "-m", "nudyn_campaign", str(path), "--out", str(out), "--workers", "2",
               "--no-progress", "--nudyn", str(nudyn)]
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT / "python"), "TMPDIR": str(temporary)})
    for _ in range(1200):
        if list((out / "parts").glob("part-*.parquet")) or proc.poll() is not None:
            break
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert stderr == f"nudyn-campaign: interrupted; rerun to resume ({out})\n", stderr
    assert len(list((out / "parts").glob("part-*.parquet"))) < 8
    assert list(temporary.iterdir()) == []
    done = run_campaign(path, out, scheduler=scheduler, nudyn=nudyn, progress=False)
    assert done.column("case").to_pylist() == list(range(80))


def test_once_interrupted_the_local_clusters_workers_are_quiet_before_it_closes(nudyn, scheduler, tmp_path,
                                                                                 monkeypatch):
    """The Ctrl-C test above, made deterministic for another race it lost
    on a loaded machine: closing the cluster after the interrupt, its
    scheduler went before a worker's heartbeat, which logged an error and
    its traceback on the command's stderr. Here the module's cluster stands
    for the run's own, and the interrupt comes during the run: by the time
    the cluster closes, no worker's Dask logger writes an error."""
    from dask.distributed import Client

    from nudyn_campaign import runner

    def worker_levels():
        return {name: logging.getLogger(name).level for name in list(logging.root.manager.loggerDict)}

    def worker_errors_written():
        return logging.getLogger("distributed.worker").isEnabledFor(logging.ERROR)

    with Client(scheduler) as observer:
        saved = observer.run(worker_levels)
        at_close = {}

        class OwnCluster:
            def close(self):
                at_close.update(observer.run(worker_errors_written))

        def interrupted(*arguments):
            raise KeyboardInterrupt

        monkeypatch.setattr(runner, "_client", lambda workers, address, scratch: (Client(scheduler), OwnCluster()))
        monkeypatch.setattr(runner, "_run", interrupted)
        try:
            assert observer.run(worker_errors_written) and set(saved)
            with pytest.raises(KeyboardInterrupt):
                run_campaign(write(tmp_path, SHORT), tmp_path / "out", workers=1, nudyn=nudyn, progress=False)
            assert at_close and not any(at_close.values()), at_close
        finally:
            def restore(levels):
                for name, level in levels.items():
                    logging.getLogger(name).setLevel(level)

            for worker, levels in saved.items():
                observer.run(restore, levels, workers=[worker])


def test_once_interrupted_no_dask_logger_writes_even_the_ones_with_their_own_level():
    """The Ctrl-C test above, made deterministic for one race it lost in CI:
    the interrupt broke distributed's wait, whose cancel callback then failed
    and logged through tornado.application, a logger distributed's config
    gives its own level (ERROR), so quieting 'tornado' alone let it print."""
    import logging

    import distributed  # noqa: F401  (its logging config sets those levels)
    from nudyn_campaign.runner import _quiet_dask

    children = ["tornado.application", "distributed.client", "distributed.utils", "asyncio"]
    assert logging.getLogger("tornado.application").level == logging.ERROR
    saved = {name: logging.getLogger(name).level for name in [*children, "tornado", "distributed"]}
    try:
        _quiet_dask()
        for name in children:
            assert not logging.getLogger(name).isEnabledFor(logging.CRITICAL), name
        assert logging.getLogger("nudyn_campaign").isEnabledFor(logging.ERROR)
    finally:
        for name, level in saved.items():
            logging.getLogger(name).setLevel(level)


SYSTEM_CAMPAIGN = """
[campaign]
SOURCE
cases = 4
seed = 7
[plant]
method = "rk4"
[dispersions]
"nu[4:6]" = {{ normal = [0.0, 0.3] }}
"controller.c2" = {{ grid = [0.0, 1.0] }}
"""


def test_a_system_file_is_flown_as_its_mjcf_with_the_same_values(nudyn, scheduler, tmp_path):
    """`campaign.system`: the archive's FMUs, its controller values and its
    experiment, with the same rows as the MJCF's campaign given the same
    values by hand (and different rows without them: the values count)."""
    ssp_file = tmp_path / "loop.ssp"
    subprocess.run([str(nudyn), "system", str(EXAMPLES_DIR / "bus_arm7.xml"), "-o", str(ssp_file), "--stop", "3",
                    "--step", "0.1", "--outputs", "kinetic_energy,momentum", "--set", "controller.c1=2"],
                   check=True, capture_output=True)
    system = run_campaign(write(tmp_path, SYSTEM_CAMPAIGN.replace("SOURCE", 'system = "loop.ssp"')), tmp_path / "system",
                          scheduler=scheduler, nudyn=nudyn, progress=False)
    by_hand = SYSTEM_CAMPAIGN.replace("SOURCE", 'model = "{model}"\ncontroller = true\nduration = 3.0\nstep = 0.1')
    by_hand += "[controller]\nc1 = 2.0\n"
    mjcf = run_campaign(write(tmp_path, by_hand, "by_hand.toml"), tmp_path / "mjcf", scheduler=scheduler, nudyn=nudyn,
                        progress=False)
    default_gain = run_campaign(write(tmp_path, by_hand.replace("c1 = 2.0", "c1 = 5.0"), "default.toml"),
                                tmp_path / "default", scheduler=scheduler, nudyn=nudyn, progress=False)
    assert set(system.column("status").to_pylist()) == {"ok"}
    for column in ("final_nu", "peak_nu", "energy_drift", "nu[4:6]", "controller.c2"):
        assert system.column(column).to_pylist() == mjcf.column(column).to_pylist(), column
    assert system.column("final_nu").to_pylist() != default_gain.column("final_nu").to_pylist()


@pytest.mark.parametrize("line, expected", [
    ('system = "loop.ssp"\nend_effector = "hand"', "campaign.system fixes the vehicle and the loop: remove campaign.end_effector"),
    ('system = "missing.ssp"', "campaign.system: no such file"),
])
def test_bad_system_campaigns_are_clear_errors(line, expected, tmp_path):
    (tmp_path / "loop.ssp").write_bytes(b"")
    with pytest.raises(CampaignError, match=expected):
        load(write(tmp_path, f"[campaign]\n{line}\ncases = 2\n"))


def test_a_second_campaign_into_a_folder_in_use_is_refused(nudyn, tmp_path):
    """Two runs into one --out used to mix silently (a seed-2 run with
    --overwrite removed and relabelled the rows of a seed-1 run still
    flying). The first run holds the folder's lock until it ends: the
    second, started while the first is held stopped with the lock, is
    refused with one line naming the folder; the first completes with its
    own rows."""
    path = write(tmp_path, SHORT.replace("cases = 4", "cases = 16"))
    reseeded = write(tmp_path, SHORT.replace("seed = 3", "seed = 4"), "reseeded.toml")
    out = tmp_path / "out"
    first = subprocess.Popen([sys.executable, "-m", "nudyn_campaign", str(path), "--out", str(out), "--workers", "1",
                              "--no-progress", "--nudyn", str(nudyn)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True, env={**os.environ, "PYTHONPATH": str(ROOT / "python")})
    try:
        # campaign.json is written with the lock held.
        for _ in range(1200):
            if (out / "campaign.json").exists() or first.poll() is not None:
                break
            time.sleep(0.05)
        os.kill(first.pid, signal.SIGSTOP)
        try:
            second = campaign_command(reseeded, "--out", out, "--overwrite", "--workers", "1", "--nudyn", nudyn)
        finally:
            os.kill(first.pid, signal.SIGCONT)
        one_line_error(second, f"--out {out}: another nudyn-campaign is writing into this folder")
        _, stderr = first.communicate(timeout=300)
    finally:
        if first.poll() is None:
            first.kill()
            first.wait()
    assert first.returncode == 0, stderr
    table = pq.read_table(out / "results.parquet")
    assert table.column("nu[4]").to_pylist() == [draw(load(path), k)["nu[4]"] for k in range(16)]
    assert "campaign seed 3" in (out / "report.md").read_text()


def test_a_first_run_does_not_replace_files_no_campaign_wrote(nudyn, scheduler, tmp_path):
    """An --out with no campaign.json that holds a file a run writes (the
    user's own report.md) is refused, the file left as it was; other files
    are no concern of the run and stay; --overwrite replaces them."""
    path = write(tmp_path, SHORT)
    out = tmp_path / "out"
    out.mkdir()
    (out / "report.md").write_text("my own notes")
    (out / "notes.txt").write_text("kept")
    expected = f"{out} holds report.md and no campaign.json: no campaign wrote them, and this one would replace them"
    with pytest.raises(CampaignError) as error:
        run_campaign(path, out, scheduler=scheduler, nudyn=nudyn, progress=False)
    assert expected in str(error.value), str(error.value)
    one_line_error(campaign_command(path, "--out", out, "--nudyn", nudyn), expected)
    assert (out / "report.md").read_text() == "my own notes"
    assert sorted(p.name for p in out.iterdir()) == [".nudyn-campaign.lock", "notes.txt", "report.md"]

    table = run_campaign(path, out, scheduler=scheduler, nudyn=nudyn, progress=False, overwrite=True)
    assert table.num_rows == 4
    assert (out / "report.md").read_text().startswith("# Campaign campaign")
    assert (out / "notes.txt").read_text() == "kept"
    # Written by the campaign now: a rerun resumes.
    assert rows(run_campaign(path, out, scheduler=scheduler, nudyn=nudyn, progress=False)) == rows(table)


def test_a_campaign_leaves_nothing_in_the_temporary_directory(nudyn, tmp_path):
    """The workers' extracted FMUs (3 to 8 MB each) and the MJCF copy the
    qvel conversion loads, Dask's worker folders: all removed by the end of
    the run (TMPDIR, for the command and its workers, a fresh folder)."""
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    path = write(tmp_path, CLOSED_LOOP)
    proc = campaign_command(path, "--out", tmp_path / "out", "--cases", "4", "--workers", "2", "--no-progress",
                            "--nudyn", nudyn, env={"TMPDIR": str(temporary)})
    assert proc.returncode == 0, proc.stderr
    assert pq.read_table(tmp_path / "out" / "results.parquet").num_rows == 4
    assert list(temporary.iterdir()) == []


@pytest.fixture(scope="module")
def loop_ssp(nudyn, tmp_path_factory) -> Path:
    """A `nudyn system` file a campaign flies: bus_arm7 with the metrics' outputs."""
    path = tmp_path_factory.mktemp("system") / "loop.ssp"
    subprocess.run([str(nudyn), "system", str(EXAMPLES_DIR / "bus_arm7.xml"), "-o", str(path), "--stop", "0.5",
                    "--step", "0.05", "--outputs", "kinetic_energy,momentum", "--set", "plant.nu[4]=0.5",
                    "--set", "plant.theta[8]=0.1", "--set", "controller.c1=0", "--set", "controller.c2=0"],
                   check=True, capture_output=True)
    return path


def rewritten(source: Path, target: Path, entries: dict) -> Path:
    """`source`'s archive with `entries` (name → new bytes, or None to leave it out) changed, as `target`."""
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as new:
        for name in old.namelist():
            content = entries.get(name, old.read(name))
            if content is not None:
                new.writestr(name, content)
    return target


def _ssd(path: Path) -> bytes:
    with zipfile.ZipFile(path) as archive:
        return archive.read("SystemStructure.ssd")


@pytest.mark.parametrize("broken, expected", [
    ("not a zip", "not a zip archive (an SSP file is one)"),
    ("a component not a zip", "resources/plant.fmu, the FMU of component plant, is not a zip archive (an FMU is one)"),
    ("a missing entry", "no entry resources/controller.fmu (the FMU of component controller)"),
    ("no component named plant",
     "no component named plant (its components: vehicle, controller); a nudyn system file has a plant and a controller"),
    ("a truncated SSD", "SystemStructure.ssd is not well-formed XML: "),
])
def test_a_malformed_system_file_is_one_line_naming_it(loop_ssp, nudyn, tmp_path, broken, expected):
    """Each of these ended in a Python traceback (BadZipFile, KeyError,
    ParseError) and exit status 1."""
    target = tmp_path / "loop.ssp"
    if broken == "not a zip":
        target.write_bytes(b"PK but not really a zip archive")
    elif broken == "a component not a zip":
        rewritten(loop_ssp, target, {"resources/plant.fmu": b"not an FMU"})
    elif broken == "a missing entry":
        rewritten(loop_ssp, target, {"resources/controller.fmu": None})
    elif broken == "no component named plant":
        rewritten(loop_ssp, target, {"SystemStructure.ssd": _ssd(loop_ssp).replace(b'Component name="plant"',
                                                                                    b'Component name="vehicle"')})
    else:
        ssd = _ssd(loop_ssp)
        rewritten(loop_ssp, target, {"SystemStructure.ssd": ssd[: len(ssd) // 2]})
    path = write(tmp_path, '[campaign]\nsystem = "loop.ssp"\ncases = 2\n')
    proc = campaign_command(path, "--out", tmp_path / "out", "--nudyn", nudyn)
    one_line_error(proc, f"campaign.system: {target}: {expected}")
    assert not (tmp_path / "out" / "parts").exists()


def test_a_system_files_plant_values_are_flown_as_fmpy_sets_them(loop_ssp, nudyn, scheduler, tmp_path):
    """The plant's .ssv values are start values FMPy's simulate_ssp sets on
    the plant before its initialization: the campaign flies them too (it
    used to fly the plant FMU's own start values, which a .ssv edited or
    written by another tool than nudyn need not match). The controller's
    gains are 0, so that its ε is 0 in both masters' orders and the two
    trajectories are the plant's alone."""
    from fmpy.ssp.simulation import simulate_ssp
    from fmpy.ssp.ssd import ParameterSet, read_ssd

    plant_values = (b'<ssv:Parameter name="nu[4]"><ssv:Real value="0.25"/></ssv:Parameter>\n'
                    b'    <ssv:Parameter name="theta[8]"><ssv:Real value="0.3"/></ssv:Parameter>')
    with zipfile.ZipFile(loop_ssp) as archive:
        ssv = archive.read("resources/plant.ssv")
    start, end = ssv.index(b"<ssv:Parameter "), ssv.rindex(b"</ssv:Parameter>") + len(b"</ssv:Parameter>")
    edited = rewritten(loop_ssp, tmp_path / "edited.ssp", {"resources/plant.ssv": ssv[:start] + plant_values + ssv[end:]})

    # FMPy's own reading of the bindings, as one ParameterSet with the component's prefix.
    parameters = ParameterSet(name="values")
    for component in read_ssd(str(edited)).system.elements:
        for binding in component.parameterBindings:
            for parameter_set in binding.parameterValues:
                for parameter in parameter_set.parameters:
                    parameter.name = f"{component.name}.{parameter.name}"
                    parameters.parameters.append(parameter)
    assert {p.name: p.value for p in parameters.parameters if p.name.startswith("plant.")} == {
        "plant.nu[4]": "0.25", "plant.theta[8]": "0.3"}
    fmpy = simulate_ssp(str(edited), stop_time=0.5, step_size=0.05, parameter_set=parameters)

    path = write(tmp_path, '[campaign]\nsystem = "edited.ssp"\ncases = 1\ntrajectories = true\n')
    table = run_campaign(path, tmp_path / "out", scheduler=scheduler, nudyn=nudyn, progress=False)
    assert table.column("status").to_pylist() == ["ok"]
    trajectory = pq.read_table(tmp_path / "out" / "trajectories" / "case-000000.parquet")
    # FMPy's row k holds the outputs after the step from t_k.
    for k in range(1, 14):
        flown = np.array(trajectory.column(f"nu[{k}]").to_pylist()[1:])
        assert np.abs(flown - fmpy[f"plant.nu[{k}]"][: len(flown)]).max() < 1e-12, k
    assert trajectory.column("nu[4]").to_pylist()[0] == 0.25
