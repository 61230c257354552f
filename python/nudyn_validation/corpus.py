"""`nudyn-validate --corpus DIR`: every model under DIR, as published and
mounted on a free-flying bus, exported by nudyn and checked against MuJoCo.

For each model entry point (see `entry_points`) and each form, in a process
of its own (a per-job timeout; `--jobs` of them at a time):

  1. MuJoCo loads the file (contacts off, as everywhere in the validation);
     a file it cannot load is reported as such: "files absent" when it
     cannot open a file the model names (a mesh missing from the copy).
     With `strip_absent_meshes`, such a model is run instead without the
     meshes whose files are absent and the geoms made of them
     (`strip_absent_meshes`); its verdict says so, since a body whose mass
     came from those meshes is lighter on both sides than as published.
  2. `nudyn export` writes the FMU; a refusal is reported with the first
     line of nudyn's message.
  3. Single evaluations: at random states (pose, rates and controls drawn
     as the validation scenarios draw them), `nudyn eval`'s qacc against
     `mj_forward`'s, error relative to max(1, |qacc|) per component.
  4. A trajectory: the `actuated` scenario (random ctrl held over each
     communication step), or `tumble` for a model without actuators, with
     MuJoCo's twin beside it (judgement.py).

The verdict of an exported model is "disagrees" when an evaluation misses
EVALUATION_TOLERANCE, else the trajectory's.  It writes corpus.md (the table
and the summary) and corpus.json in the output directory.
"""

from __future__ import annotations

import fnmatch
import json
import os
import re
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

import mujoco
import numpy as np

from nudyn_driver.cli import Nudyn
from nudyn_driver.errors import CommandError, DriverError

from .compare import EXTRA_OUTPUTS, Settings, ValidationError, run_scenarios
from .judgement import DISAGREES
from .mujoco_reference import load_model
from .mujoco_run import MujocoVehicle
from .scenarios import make_scenario, offset_pose, random_ctrl, velocity_scales

# Issue 33's bar on single evaluations: qacc within 1e-9 of max(1, |qacc|).
EVALUATION_TOLERANCE = 1e-9
FORMS = ("published", "bus")

# The bus a model is mounted on in the "bus" form: a 1 m cube of 500 kg.
BUS_NAME = "nudyn_corpus_bus"
BUS_MASS = 500.0
BUS_SIZE = 1.0

# Statuses of a job, besides "exported".
FILES_ABSENT = "files absent"
MUJOCO_REFUSES = "MuJoCo cannot load"
REFUSED = "refused"
FAILED = "failed"
# The trajectory could not be compared: MuJoCo's own run at this step
# blows up too (a model too stiff for the step, as when the FMU failed).
UNSTABLE = "unstable at this step"
TIMED_OUT = "timed out"

# The elements a scene adds without adding anything that moves or acts.
SCENE_ELEMENTS = {
    "include", "asset", "visual", "statistic", "worldbody", "contact", "keyframe", "option", "custom",
    "compiler", "default", "extension",
}


class CorpusError(Exception):
    """A corpus that cannot be run (no such directory, a bad option)."""


# --- which files are models ------------------------------------------------


def _parse(path: Path) -> ET.Element | None:
    try:
        return ET.parse(path).getroot()
    except (ET.ParseError, OSError):
        return None


def _included(path: Path, root: ET.Element, main_dir: Path) -> list[Path]:
    """The files an MJCF file includes, where MuJoCo looks for them: in the
    main model's directory, else beside the including file."""
    found = []
    for include in root.iter("include"):
        name = include.get("file")
        if name:
            candidates = [main_dir / name, path.parent / name]
            found.append(next((c for c in candidates if c.is_file()), candidates[0]).resolve())
    return found


def _joints(root: ET.Element) -> list[ET.Element]:
    return [e for world in root.iter("worldbody") for e in world.iter() if e.tag in ("joint", "freejoint")]


def _is_scene(root: ET.Element) -> bool:
    """A scene includes a model and adds only its surroundings: world
    geometry, lights, assets, visuals, contacts, keyframes, options, and
    objects that are fixed or fly free; no joint of another kind, actuator,
    tendon, equality or sensor of its own."""
    if root.find("include") is None:
        return False
    if any(child.tag not in SCENE_ELEMENTS for child in root):
        return False
    return all(j.tag == "freejoint" or j.get("type") == "free" for j in _joints(root))


def _moves(path: Path, root: ET.Element, roots: dict, main_dir: Path, seen=()) -> bool:
    """Whether the file, with what it includes, has a joint."""
    if _joints(root):
        return True
    return any(p not in seen and p in roots and _moves(p, roots[p], roots, main_dir, (*seen, path))
               for p in _included(path, root, main_dir))


def entry_points(directory: Path) -> list[Path]:
    """The models under `directory`, sorted: every XML file whose root is
    <mujoco>, that has a joint (itself or in what it includes) and that no
    other file includes; a scene (`_is_scene`) is not a model of its own:
    the files it includes are."""
    roots = {}
    for path in sorted(directory.rglob("*.xml")):
        root = _parse(path)
        if root is not None and root.tag == "mujoco":
            roots[path.resolve()] = root
    included_by_model = set()
    for path, root in roots.items():
        if not _is_scene(root):
            included_by_model.update(_included(path, root, path.parent))
    return [
        path for path, root in roots.items()
        if path not in included_by_model and not _is_scene(root) and _moves(path, root, roots, path.parent)
    ]


# --- the bus form ----------------------------------------------------------


def _inline_includes(element: ET.Element, main_dir: Path, file_dir: Path) -> None:
    """Replace each <include> below element by the children of its file's
    root, recursively, as MuJoCo merges them."""
    for child in list(element):
        if child.tag != "include":
            _inline_includes(child, main_dir, file_dir)
            continue
        name = child.get("file", "")
        path = main_dir / name if (main_dir / name).is_file() else file_dir / name
        included = ET.parse(path).getroot()
        _inline_includes(included, main_dir, path.parent)
        at = list(element).index(child)
        element.remove(child)
        for k, grandchild in enumerate(list(included)):
            element.insert(at + k, grandchild)


def _free_joints(body: ET.Element) -> list[ET.Element]:
    return [j for j in body if j.tag == "freejoint" or (j.tag == "joint" and j.get("type") == "free")]


def mount_on_bus(model: Path, out: Path) -> Path:
    """Write `out`: the model with everything in its world that moves (its
    bodies and frames, mocap bodies excepted) put under a free-flying bus of
    BUS_MASS kg, their free joints removed (the robot rides the bus).  The
    file stands elsewhere, so includes are merged in and the asset
    directories made absolute; keyframes, sized for the model without the
    bus, are left out."""
    root = ET.parse(model).getroot()
    model_dir = model.resolve().parent
    _inline_includes(root, model_dir, model_dir)
    compilers = root.findall("compiler")
    if not compilers:
        compilers = [ET.Element("compiler")]
        root.insert(0, compilers[0])
    for compiler in compilers:
        for attribute in ("meshdir", "texturedir", "assetdir"):
            value = compiler.get(attribute)
            if value is not None:
                compiler.set(attribute, str(model_dir / value))
    if all(c.get("assetdir") is None for c in compilers):
        compilers[0].set("assetdir", str(model_dir))
    for keyframe in root.findall("keyframe"):
        root.remove(keyframe)

    worlds = root.findall("worldbody")
    if not worlds:
        raise CorpusError(f"{model}: no <worldbody> to mount on a bus")
    half = BUS_SIZE / 2
    inertia = BUS_MASS * BUS_SIZE**2 / 6  # a cube's, about its centre
    bus = ET.Element("body", name=BUS_NAME)
    ET.SubElement(bus, "freejoint", name=BUS_NAME)
    ET.SubElement(bus, "inertial", pos="0 0 0", mass=f"{BUS_MASS:g}", diaginertia=f"{inertia:.17g} " * 2 + f"{inertia:.17g}")
    # The same cube as a geom, for a model whose compiler takes inertia from geoms.
    ET.SubElement(bus, "geom", type="box", size=f"{half:g} {half:g} {half:g}", mass=f"{BUS_MASS:g}",
                  contype="0", conaffinity="0", group="5")
    for world in worlds:
        for child in list(world):
            if child.tag not in ("body", "frame") or child.get("mocap") == "true":
                continue
            world.remove(child)
            bus.append(child)
            for body in [child] if child.tag == "body" else child.findall("body"):
                for joint in _free_joints(body):
                    body.remove(joint)
    worlds[0].append(bus)
    out.parent.mkdir(parents=True, exist_ok=True)
    ET.ElementTree(root).write(out, encoding="unicode")
    return out


# --- a copy without the meshes that are absent ----------------------------

STRIPPED = "absent meshes stripped"


def _mesh_directory(root: ET.Element, model_dir: Path) -> Path:
    """Where MuJoCo looks for mesh files: meshdir, else assetdir, else the
    model's directory (relative ones from the model's directory)."""
    directory = model_dir
    for compiler in root.iter("compiler"):
        value = compiler.get("meshdir") or compiler.get("assetdir")
        if value is not None:
            directory = model_dir / value
    return directory


def strip_absent_meshes(model: Path, out: Path) -> list[str]:
    """Write `out`: the model (includes merged, asset directories made
    absolute) without the <mesh> assets whose files are absent, the geoms
    made of them and the contact pairs naming those geoms.  Returns the
    names of the meshes taken out; nothing is written when there are none."""
    root = ET.parse(model).getroot()
    model_dir = model.resolve().parent
    _inline_includes(root, model_dir, model_dir)
    mesh_dir = _mesh_directory(root, model_dir)
    absent = set()
    for asset in root.iter("asset"):
        for mesh in list(asset.findall("mesh")):
            name = mesh.get("file")
            if name and not (mesh_dir / name).is_file():
                absent.add(mesh.get("name") or Path(name).stem)
                asset.remove(mesh)
    if not absent:
        return []
    removed_geoms = set()
    for parent in list(root.iter()):
        for child in list(parent):
            if child.tag == "geom" and child.get("mesh") in absent:
                removed_geoms.add(child.get("name"))
                parent.remove(child)
    for contact in root.iter("contact"):
        for pair in list(contact.findall("pair")):
            if {pair.get("geom1"), pair.get("geom2")} & (removed_geoms - {None}):
                contact.remove(pair)
    for compiler in root.iter("compiler"):
        for attribute in ("meshdir", "texturedir", "assetdir"):
            value = compiler.get(attribute)
            if value is not None:
                compiler.set(attribute, str(model_dir / value))
    if all(c.get("assetdir") is None for c in root.iter("compiler")):
        compiler = ET.Element("compiler", assetdir=str(model_dir))
        root.insert(0, compiler)
    out.parent.mkdir(parents=True, exist_ok=True)
    ET.ElementTree(root).write(out, encoding="unicode")
    return sorted(absent)


# --- one job ---------------------------------------------------------------


@dataclass
class Row:
    """One (model, form) of the corpus: what happened and the numbers."""

    model: str  # relative to the corpus directory
    form: str
    status: str  # "exported", or why not (FILES_ABSENT, MUJOCO_REFUSES, REFUSED, FAILED, TIMED_OUT)
    message: str = ""  # the first line of the refusal or failure
    nq: int | None = None
    nv: int | None = None
    nu: int | None = None
    evaluation_error: float | None = None
    scenario: str | None = None
    trajectory_error: float | None = None
    twin_divergence: float | None = None
    tolerance: float | None = None
    trajectory_verdict: str | None = None
    verdict: str = ""
    seconds: float | None = None
    stripped_meshes: list[str] | None = None  # the absent meshes taken out (strip_absent_meshes)


def _first_error_line(stderr: str) -> str:
    """nudyn's error line (its warnings come first), without the
    'nudyn: error: ' prefix."""
    lines = [line.strip() for line in stderr.splitlines() if line.strip()]
    line = next((line for line in lines if line.startswith("nudyn: error: ")), lines[-1] if lines else "")
    return line.removeprefix("nudyn: error: ")


def _mujoco_cannot_open(message: str) -> bool:
    return bool(re.search(r"(?i)error opening file|resource not found|could not open file|no such file", message))


def evaluation_error(nudyn, model_path: Path, model, states: int, seed: int) -> float:
    """The largest |qacc_nudyn − qacc_MuJoCo| / max(1, |qacc_MuJoCo|) over
    `states` random states, each with random controls."""
    rng = np.random.default_rng([seed, 33])  # a stream of its own, apart from the scenarios' draws
    controls = random_ctrl(model, seed)
    data = mujoco.MjData(model)
    requests, expected = [], []
    for k in range(states):
        qpos, qvel, ctrl = offset_pose(model, rng), rng.normal(0.0, velocity_scales(model)), controls(k)
        data.qpos[:], data.qvel[:], data.ctrl[:] = qpos, qvel, ctrl
        mujoco.mj_forward(model, data)
        expected.append(data.qacc.copy())
        request = {"theta": qpos.tolist(), "qvel": qvel.tolist()}
        if model.nu:
            request["ctrl"] = ctrl.tolist()
        requests.append(request)
    answers = nudyn.eval(model_path, requests)
    errors = [
        np.max(np.abs(np.array(a["qacc"]) - e) / np.maximum(1.0, np.abs(e)), initial=0.0)
        for a, e in zip(answers, expected)
    ]
    return float(max(errors))


def mujoco_alone_unstable(path: Path, scenario_name: str, settings) -> str | None:
    """MuJoCo's own run of the scenario (ε = 0, its ctrl), alone: the
    first bad-state warning it raises and when, or None when it runs through."""
    scenario = make_scenario(scenario_name, load_model(path), settings.seed)
    h, substeps = settings.communication_step, settings.mujoco_substeps()
    mj = MujocoVehicle(path, h / substeps)
    mj.set_state(scenario.qpos0, scenario.qvel0)
    zero = np.zeros(mj.model.nv)
    for k in range(settings.communication_steps()):
        mj.advance(zero, substeps, None if scenario.ctrl_law is None else scenario.ctrl_law(k))
        problem = mj.instability()
        if problem or not np.all(np.isfinite(mj.data.qvel)):
            return f"{problem or 'non-finite qvel'} before t = {(k + 1) * h:g} s"
    return None


def run_job(model: Path, form: str, corpus: Path, out: Path, nudyn_path: Path, settings, states: int,
            strip: bool = False) -> Row:
    """Steps 1–4 of the module doc for one model in one form; with `strip`,
    a model whose mesh files are absent runs without them."""
    started = time.perf_counter()
    row = Row(model=str(model.relative_to(corpus)), form=form, status=FAILED)
    work = out / "models" / row.model.removesuffix(".xml") / form
    work.mkdir(parents=True, exist_ok=True)

    def done(status: str, message: str = "", verdict: str | None = None) -> Row:
        row.status, row.message, row.verdict = status, message, verdict or status
        if row.stripped_meshes:
            row.verdict += f", {STRIPPED}"
        row.seconds = time.perf_counter() - started
        return row

    if strip:
        stripped = work / f"{model.stem}.stripped.xml"
        row.stripped_meshes = strip_absent_meshes(model, stripped) or None
        if row.stripped_meshes:
            model = stripped
    try:
        path = mount_on_bus(model, work / model.name) if form == "bus" else model
    except (ET.ParseError, OSError, CorpusError) as e:
        return done(FAILED, f"cannot mount on a bus: {e}")
    try:
        mj_model = load_model(path)
    except ValueError as e:
        message = str(e).strip().splitlines()[0] if str(e).strip() else repr(e)
        return done(FILES_ABSENT if _mujoco_cannot_open(message) else MUJOCO_REFUSES, message)
    row.nq, row.nv, row.nu = mj_model.nq, mj_model.nv, mj_model.nu
    nudyn = Nudyn(nudyn_path)
    fmu = work / f"{model.stem}.fmu"
    try:
        nudyn.export(path, fmu, outputs=EXTRA_OUTPUTS)
    except CommandError as e:
        # The model column names the file: the message from its line on.
        return done(REFUSED, re.sub(r"^cannot import .*?\.xml: ", "", _first_error_line(e.stderr)))
    try:
        row.evaluation_error = evaluation_error(nudyn, path, mj_model, states, settings.seed)
    except DriverError as e:
        return done(FAILED, f"nudyn eval: {_first_error_line(getattr(e, 'stderr', str(e)))}")
    row.scenario = "actuated" if mj_model.nu else "tumble"
    try:
        validation = run_scenarios(path, fmu, [row.scenario], settings)
    except (ValidationError, DriverError) as e:
        message = f"trajectory: {str(e).splitlines()[0]}"
        mujoco_problem = mujoco_alone_unstable(path, row.scenario, settings)
        if mujoco_problem:
            return done("exported", f"{message}; MuJoCo alone: {mujoco_problem}", verdict=UNSTABLE)
        return done("exported", f"{message}; MuJoCo alone runs", verdict=DISAGREES)
    summary = validation.results[0].summary()
    row.trajectory_error = max(summary["max_theta_error"], summary["max_nu_error"], summary["max_sensordata_error"],
                               summary["max_act_error"])
    row.twin_divergence = summary["max_twin_divergence"]
    row.tolerance = summary["tolerance"]
    row.trajectory_verdict = summary["verdict"]
    if row.evaluation_error > EVALUATION_TOLERANCE:
        return done("exported", verdict=DISAGREES)
    return done("exported", verdict=row.trajectory_verdict)


# --- the whole corpus ------------------------------------------------------


def _job_command(model: Path, form: str, corpus: Path, out: Path, nudyn: Path, settings, states: int,
                 strip: bool, row_file: Path) -> list[str]:
    return [
        sys.executable, "-m", "nudyn_validation.corpus", str(model), form, str(corpus), str(out), str(nudyn),
        str(row_file),
        json.dumps(run_settings(settings, states, strip)),
    ]


def _run_in_process(model: Path, form: str, corpus: Path, out: Path, nudyn: Path, settings, states: int,
                    strip: bool, timeout: float) -> Row:
    """One job in a child process (a crash or a hang costs that job only)."""
    package_root = str(Path(__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([package_root, os.environ.get("PYTHONPATH", "")])}
    name = str(model.relative_to(corpus))
    # The row comes back in a file: MuJoCo prints its warnings on stdout.
    row_file = out / "models" / name.removesuffix(".xml") / f"{form}.json"
    row_file.unlink(missing_ok=True)
    try:
        proc = subprocess.run(_job_command(model, form, corpus, out, nudyn, settings, states, strip, row_file),
                              capture_output=True, text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        return Row(model=name, form=form, status=TIMED_OUT, message=f"after {timeout:g} s", verdict=TIMED_OUT)
    if proc.returncode != 0 or not row_file.is_file():
        last = (proc.stderr.strip().splitlines() or [f"exit status {proc.returncode}"])[-1]
        return Row(model=name, form=form, status=FAILED, message=last, verdict=FAILED)
    return Row(**json.loads(row_file.read_text()))


def refusal_cause(message: str) -> str:
    """A refusal's message without its files, lines, names and numbers: what
    groups refusals of the same feature.  'cannot import a.xml: line 3: <fixed
    name="t">: not supported: tendons' gives '<fixed>: not supported: tendons'."""
    text = re.sub(r"^cannot import [^:]*: (?:[^:]*\.xml: )?", "", message)
    text = re.sub(r"\bline \d+: ", "", text)
    text = re.sub(r"<(\w+)[^>]*>", r"<\1>", text)
    text = re.sub(r"'[^']*'", "'…'", text)
    return re.sub(r"(?<![\w.])-?\d+(?:\.\d+)?(?:e-?\d+)?(?![\w.])", "N", text)


def run_settings(settings, states: int, strip: bool = False) -> dict:
    """What a row's numbers depend on besides the model and the binaries."""
    return {"duration": settings.duration, "communication_step": settings.communication_step,
            "mujoco_step": settings.mujoco_step, "seed": settings.seed, "twins": settings.twins, "states": states,
            "strip_absent_meshes": strip}


def previous_rows(out: Path, settings, states: int, strip: bool = False) -> dict[tuple[str, str], Row]:
    """The rows of out/corpus.json run with the same settings, except those
    that failed or timed out: what --resume keeps."""
    path = out / "corpus.json"
    if not path.is_file():
        return {}
    previous = json.loads(path.read_text())
    if previous.get("settings") != run_settings(settings, states, strip):
        raise CorpusError(f"{path} was run with other settings ({previous.get('settings')}): "
                          "rerun without --resume, or with the same settings")
    return {(r["model"], r["form"]): Row(**r) for r in previous["rows"] if r["verdict"] not in (FAILED, TIMED_OUT)}


def run_corpus(corpus: Path, out: Path, nudyn: Path, settings, *, jobs: int = 1, timeout: float = 600.0,
               states: int = 10, forms=FORMS, exclude=(), resume: bool = False, strip_absent_meshes: bool = False,
               progress=print) -> list[Row]:
    """Every entry point of the corpus in every form; the rows in model
    order.  With `resume`, the rows of the last report in `out` are kept
    (previous_rows) and only the others run."""
    if not corpus.is_dir():
        raise CorpusError(f"no such directory: {corpus}")
    corpus = corpus.resolve()
    models = [m for m in entry_points(corpus)
              if not any(fnmatch.fnmatch(str(m.relative_to(corpus)), pattern) for pattern in exclude)]
    if not models:
        raise CorpusError(f"no MJCF model under {corpus}")
    out.mkdir(parents=True, exist_ok=True)
    tasks = [(m, f) for m in models for f in forms]
    kept = previous_rows(out, settings, states, strip_absent_meshes) if resume else {}
    rows: dict[tuple[Path, str], Row] = {
        t: kept[str(t[0].relative_to(corpus)), t[1]] for t in tasks if (str(t[0].relative_to(corpus)), t[1]) in kept
    }
    progress(f"corpus: {len(models)} models, {len(tasks)} jobs ({len(rows)} kept from the last run), "
             f"{jobs} at a time")

    def one(task):
        try:
            row = _run_in_process(*task, corpus, out.resolve(), nudyn.resolve(), settings, states,
                                  strip_absent_meshes, timeout)
        except Exception as e:  # noqa: BLE001  (one job's surprise must not lose the others' rows)
            row = Row(model=str(task[0].relative_to(corpus)), form=task[1], status=FAILED, message=repr(e),
                      verdict=FAILED)
        rows[task] = row
        progress(f"[{len(rows)}/{len(tasks)}] {row.model} ({row.form}): {row.verdict}"
                 + (f" — {row.message}" if row.message else ""))
        return row

    with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        list(pool.map(one, [t for t in tasks if t not in rows]))
    return [rows[t] for t in tasks]


# --- the report ------------------------------------------------------------


def _markdown_text(text: str) -> str:
    """Text shown as written in a markdown table: element tags are not HTML."""
    return text.replace("&", "&amp;").replace("<", "&lt;").replace("|", "\\|")


def _number(x: float | None) -> str:
    return "—" if x is None else f"{x:.1e}"


def summary(rows: list[Row]) -> dict:
    """Counts of verdicts by form, and refusals grouped by cause."""
    forms = sorted({r.form for r in rows}, key=lambda f: FORMS.index(f) if f in FORMS else len(FORMS))
    verdicts = {form: dict(Counter(r.verdict for r in rows if r.form == form).most_common()) for form in forms}
    causes = {form: dict(Counter(refusal_cause(r.message) for r in rows if r.form == form and r.status == REFUSED)
                         .most_common()) for form in forms}
    return {"models": len({r.model for r in rows}), "verdicts": verdicts, "refusals": causes}


def markdown(rows: list[Row], settings, corpus: Path) -> str:
    s = summary(rows)
    lines = [
        f"# Corpus report: {corpus}",
        "",
        f"{s['models']} models, each as published and mounted on a free-flying {BUS_MASS:g} kg bus. "
        f"Evaluations: qacc of `nudyn eval` against `mj_forward` at random states, max error relative to "
        f"max(1, |qacc|) (bar {EVALUATION_TOLERANCE:g}). Trajectory: {settings.duration:g} s, RK4 at "
        f"{settings.mujoco_step:g} s on both sides, communication step {settings.communication_step:g} s, "
        "random ctrl (`actuated`) or free motion (`tumble`); error: max θ, ν or sensordata difference; "
        f"twins: MuJoCo's own run from qvel moved by ±1e-13 ({settings.twins} of them, the largest divergence counts).",
        "",
        "## Summary",
        "",
        "| verdict | " + " | ".join(s["verdicts"]) + " |",
        "|---|" + "---|" * len(s["verdicts"]),
    ]
    names = sorted({v for counts in s["verdicts"].values() for v in counts})
    for name in names:
        lines.append(f"| {name} | " + " | ".join(str(s["verdicts"][f].get(name, 0)) for f in s["verdicts"]) + " |")
    for form, causes in s["refusals"].items():
        if causes:
            lines += ["", f"Refusals ({form}), by cause:", ""]
            lines += [f"- {count} × {_markdown_text(cause)}" for cause, count in causes.items()]
    lines += [
        "",
        "## Every model",
        "",
        "| model | form | nv | exported | evaluation error | trajectory | trajectory error | twin divergence | verdict |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        exported = "yes" if r.status == "exported" else _markdown_text(f"{r.status}: {r.message}")
        lines.append(
            f"| {r.model} | {r.form} | {r.nv if r.nv is not None else '—'} | {exported} | "
            f"{_number(r.evaluation_error)} | {r.scenario or '—'} | {_number(r.trajectory_error)} | "
            f"{_number(r.twin_divergence)} | {r.verdict} |"
        )
    return "\n".join(lines) + "\n"


def write_report(rows: list[Row], settings, states: int, corpus: Path, out: Path,
                 strip: bool = False) -> dict[str, Path]:
    paths = {"table": out / "corpus.md", "json": out / "corpus.json"}
    paths["table"].write_text(markdown(rows, settings, corpus))
    numbers = {"corpus": str(corpus), "settings": run_settings(settings, states, strip), "summary": summary(rows),
               "rows": [asdict(r) for r in rows]}
    paths["json"].write_text(json.dumps(numbers, indent=1) + "\n")
    return paths


def _job_main(argv: list[str]) -> int:
    """The child process of one job: writes its Row as JSON to the file named."""
    model, form, corpus, out, nudyn, row_file, options = argv
    options = json.loads(options)
    states, strip = options.pop("states"), options.pop("strip_absent_meshes")
    row = run_job(Path(model), form, Path(corpus), Path(out), Path(nudyn), Settings(**options), states, strip)
    Path(row_file).parent.mkdir(parents=True, exist_ok=True)
    Path(row_file).write_text(json.dumps(asdict(row)) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(_job_main(sys.argv[1:]))
