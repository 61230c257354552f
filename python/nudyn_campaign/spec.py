"""The campaign file (TOML): what to fly, how long, and what to disperse.

    [campaign]
    name = "detumble"            # default: the file's name
    model = "../bus_arm7.xml"    # MJCF, relative to this file
    # or: system = "loop.ssp"    # a `nudyn system` file: its plant and controller FMUs,
    #                            # its values, and (unless given) its stop time and step
    seed = 2026                  # campaign seed: case k draws from (seed, k)
    cases = 1000
    duration = 10.0              # s
    step = 0.05                  # communication step, s
    controller = true            # close the loop with nudyn's controller FMU
    end_effector = "hand"        # optional: the controller's pose objective
    wrench_bodies = ["bus"]      # optional: plant inputs xfrc_applied (nudyn export --wrench-inputs)
    settle_threshold = 0.01      # |ν| (√J) below which the vehicle counts as settled
    trajectories = false         # also write each case's trajectory
    metrics = ["mymodule:extra"] # optional: functions(trajectory) -> {name: value}

    [plant]                      # fixed plant parameters (tolerance, method, max_step)
    method = "dop853"

    [controller]                 # fixed controller parameters (c1, c2, targets)
    c2 = 0.0

    [dispersions]                # target = { distribution = parameters }
    "qvel[4:6]" = { normal = [0.0, 0.3] }
    "controller.c1" = { grid = [0.5, 1.0, 2.0, 4.0] }

    [schedules]                  # plant inputs over time: [time, value] pairs,
    "ctrl[1]" = [[0.0, 22.0], [2.0, 0.0]]  # each value held from its time on

Targets: the start values theta[k] and nu[k], or qvel[k] (turned into ν at
the drawn θ); the constant inputs eps[k], ctrl[k], xfrc_applied[k];
plant.NAME and controller.NAME parameters (an array parameter such as
controller.c1 without an index sets every entry). `[a:b]` is the entries a
to b (1-based, inclusive), each drawn on its own. Distributions: uniform
[low, high], normal [mean, sd], choice [values...] (drawn), grid [values...]
(choice and grid also take names: plant.method = { grid = ["rk4", "dop853"] })
(not drawn: case k takes the grids' values in turn, the first grid
fastest, so a grid of G values sweeps every G-th case). Each variable is
dispersed by one key at most (qvel and nu never together). A schedule sets an
input (eps[k], ctrl[k], xfrc_applied[k]) at the communication points from
its times on, the same in every case; before its first time the input
keeps its start value (0, or a dispersed one).

With `system`, the FMUs are the archive's (exported with `--outputs
kinetic_energy,momentum`, which the metrics read), the loop is closed, the
values of its ParameterValues files (.ssv) are fixed parameters of each
FMU under the file's own [plant] and [controller] (set as FMPy's
simulate_ssp sets them, before the dispersions), and its
DefaultExperiment gives duration and step where the file does not; qvel
needs the MJCF (MuJoCo turns it into ν) and is refused, as are the export
options end_effector and wrench_bodies (the archive fixed them).
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

DISTRIBUTIONS = ("uniform", "normal", "choice", "grid")
INPUTS = ("eps", "ctrl", "xfrc_applied")
STATES = ("theta", "nu", "qvel")
_METRIC = re.compile(r"^[A-Za-z_][\w.]*:[A-Za-z_]\w*$")
_TARGET = re.compile(r"^(?:(plant|controller)\.)?([A-Za-z_][A-Za-z0-9_]*)(?:\[(\d+)(?::(\d+))?\])?$")


class CampaignError(ValueError):
    """A campaign file that cannot be run, with the key and what is wrong."""


@dataclass(frozen=True)
class Dispersion:
    """One dispersed quantity: the variables it sets and how it is drawn."""

    key: str  # as written in the file
    scope: str  # "plant" (start values, inputs, parameters) or "controller"
    names: tuple[str, ...]  # the FMU variables it sets ("qvel[k]" for qvel)
    distribution: str
    parameters: tuple[float, ...]


@dataclass
class Campaign:
    path: Path
    name: str
    # The MJCF, or None when the campaign flies a system file.
    model: Path | None
    seed: int
    cases: int
    duration: float
    step: float
    controller: bool = False
    end_effector: str | None = None
    wrench_bodies: tuple[str, ...] = ()
    settle_threshold: float = 0.01
    trajectories: bool = False
    metrics: tuple[str, ...] = ()
    plant_parameters: dict = field(default_factory=dict)
    controller_parameters: dict = field(default_factory=dict)
    dispersions: tuple[Dispersion, ...] = ()
    # Input name -> ((time, value), ...) ascending in time.
    schedules: dict = field(default_factory=dict)
    # The `nudyn system` file flown instead of the MJCF's export, if any.
    system: Path | None = None

    @property
    def source(self) -> Path:
        """The file the vehicle comes from: the system file or the MJCF."""
        return self.system or self.model

    @property
    def steps(self) -> int:
        return round(self.duration / self.step)

    def columns(self) -> list[str]:
        """The drawn values' columns, in draw order."""
        return [dispersion.key for dispersion in self.dispersions]

    def as_dict(self) -> dict:
        """A plain description for the workers (no paths they may not share)."""
        return {
            "name": self.name,
            "duration": self.duration,
            "step": self.step,
            "controller": self.controller,
            "settle_threshold": self.settle_threshold,
            "trajectories": self.trajectories,
            "metrics": list(self.metrics),
            "plant_parameters": dict(self.plant_parameters),
            "controller_parameters": dict(self.controller_parameters),
            "schedules": {name: [list(point) for point in points] for name, points in self.schedules.items()},
        }


def _number(value, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise CampaignError(f"{key}: expected a finite number, found {value!r}")
    return float(value)


def _dispersion(key: str, value) -> Dispersion:
    match = _TARGET.match(key)
    if match is None:
        raise CampaignError(
            f"dispersions.{key}: not a target; write theta[k], nu[k], qvel[k], eps[k], ctrl[k], "
            "xfrc_applied[k] (or [a:b]), plant.NAME or controller.NAME"
        )
    scope, base, first, last = match.groups()
    if scope is None and base not in STATES + INPUTS:
        raise CampaignError(f"dispersions.{key}: '{base}' is no start value or input; a parameter needs plant. or controller.")
    if scope is None and first is None:
        raise CampaignError(f"dispersions.{key}: give the entry, e.g. {base}[1] or {base}[1:3]")
    if not isinstance(value, dict) or len(value) != 1:
        raise CampaignError(f"dispersions.{key}: expected one distribution, e.g. {{ uniform = [0, 1] }}, found {value!r}")
    (distribution, parameters), = value.items()
    if distribution not in DISTRIBUTIONS:
        raise CampaignError(f"dispersions.{key}: unknown distribution '{distribution}' (known: {', '.join(DISTRIBUTIONS)})")
    if not isinstance(parameters, list) or not parameters:
        raise CampaignError(f"dispersions.{key}.{distribution}: expected a list of numbers")
    if distribution in ("choice", "grid") and all(isinstance(p, str) for p in parameters):
        # Items of an enumeration, e.g. plant.method = { grid = ["rk4", "dop853"] }.
        parameters = tuple(parameters)
    else:
        parameters = tuple(_number(p, f"dispersions.{key}.{distribution}") for p in parameters)
    if distribution in ("uniform", "normal") and len(parameters) != 2:
        raise CampaignError(f"dispersions.{key}.{distribution}: expected two numbers, found {len(parameters)}")
    if distribution == "uniform" and not parameters[0] <= parameters[1]:
        raise CampaignError(f"dispersions.{key}.uniform: low {parameters[0]} exceeds high {parameters[1]}")
    if distribution == "normal" and parameters[1] < 0:
        raise CampaignError(f"dispersions.{key}.normal: negative standard deviation {parameters[1]}")
    if first is None:
        names = (base,)
    else:
        a, b = int(first), int(last or first)
        if not 1 <= a <= b:
            raise CampaignError(f"dispersions.{key}: entries count from 1 and a range runs upward")
        names = tuple(f"{base}[{k}]" for k in range(a, b + 1))
    return Dispersion(key, scope or "plant", names, distribution, parameters)


def load(path: str | Path) -> Campaign:
    """Reads and checks a campaign file."""
    path = Path(path)
    try:
        document = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise CampaignError(f"no such campaign file: {path}") from None
    except tomllib.TOMLDecodeError as error:
        raise CampaignError(f"{path}: not valid TOML: {error}") from None
    unknown = set(document) - {"campaign", "plant", "controller", "dispersions", "schedules"}
    if unknown:
        raise CampaignError(
            f"unknown section(s) {', '.join(sorted(unknown))} (known: campaign, plant, controller, dispersions, schedules)"
        )
    section = document.get("campaign", {})
    known = {"name", "model", "system", "seed", "cases", "duration", "step", "controller", "end_effector", "wrench_bodies",
             "settle_threshold", "trajectories", "metrics"}
    if set(section) - known:
        raise CampaignError(f"campaign: unknown key(s) {', '.join(sorted(set(section) - known))}")
    system, system_values = _system(path, section)
    required = ("cases",) if system else ("model", "cases", "duration", "step")
    for key in required:
        if key not in section:
            raise CampaignError(f"campaign.{key} is missing")
    model = None
    if not system:
        model = (path.parent / section["model"]).resolve()
        if not model.is_file():
            raise CampaignError(f"campaign.model: no such file {model}")
    cases = section["cases"]
    if not isinstance(cases, int) or cases < 1:
        raise CampaignError(f"campaign.cases: expected a positive integer, found {cases!r}")
    duration = _number(section.get("duration", system_values and system_values.stop_time), "campaign.duration")
    step = _number(section.get("step", system_values and system_values.step), "campaign.step")
    if not (step > 0 and duration > 0 and abs(round(duration / step) * step - duration) <= 1e-9 * duration):
        raise CampaignError(f"campaign.step: {step} must be positive and divide campaign.duration {duration}")
    controller = bool(section.get("controller", False)) or system is not None
    end_effector = section.get("end_effector")
    if end_effector is not None and not controller:
        raise CampaignError("campaign.end_effector needs campaign.controller = true")
    dispersions = tuple(_dispersion(key, value) for key, value in document.get("dispersions", {}).items())
    if not controller and any(d.scope == "controller" for d in dispersions):
        raise CampaignError("dispersions of controller parameters need campaign.controller = true")
    _refuse_overlaps(dispersions)
    if system and any(name.startswith("qvel[") for d in dispersions for name in d.names):
        raise CampaignError("dispersions of qvel need campaign.model (MuJoCo turns qvel into nu): "
                            "with campaign.system, disperse nu")
    metrics = section.get("metrics", [])
    if not isinstance(metrics, list) or not all(isinstance(m, str) and _METRIC.match(m) for m in metrics):
        raise CampaignError(f"campaign.metrics: expected a list of \"module:function\" names, found {metrics!r}")
    for name, values in (("plant", document.get("plant", {})), ("controller", document.get("controller", {}))):
        for key, value in values.items():
            if not isinstance(value, (int, float, str, bool)):
                raise CampaignError(f"{name}.{key}: expected a number, a name or true/false, found {value!r}")
    schedules = {key: _schedule(key, value) for key, value in document.get("schedules", {}).items()}
    return Campaign(
        path=path,
        name=str(section.get("name", path.stem)),
        model=model,
        seed=int(section.get("seed", 0)),
        cases=cases,
        duration=duration,
        step=step,
        controller=controller,
        end_effector=end_effector,
        wrench_bodies=tuple(section.get("wrench_bodies", ())),
        settle_threshold=_number(section.get("settle_threshold", 0.01), "campaign.settle_threshold"),
        trajectories=bool(section.get("trajectories", False)),
        metrics=tuple(metrics),
        # A system's values first, as FMPy's simulate_ssp sets them, then the file's own.
        plant_parameters={**(system_values.values.get("plant", {}) if system_values else {}),
                          **document.get("plant", {})},
        controller_parameters={**(system_values.values.get("controller", {}) if system_values else {}),
                               **document.get("controller", {})},
        dispersions=dispersions,
        schedules=schedules,
        system=system,
    )


def _system(path: Path, section: dict):
    """The system file `campaign.system` names and what it holds, or (None, None)."""
    if "system" not in section:
        return None, None
    from nudyn_driver import ssp
    from nudyn_driver.errors import SystemFileError

    clashes = [key for key in ("model", "controller", "end_effector", "wrench_bodies") if key in section]
    if clashes:
        raise CampaignError(f"campaign.system fixes the vehicle and the loop: remove campaign.{clashes[0]}")
    system = (path.parent / section["system"]).resolve()
    try:
        return system, ssp.read(system)
    except FileNotFoundError:
        raise CampaignError(f"campaign.system: no such file {system}") from None
    except SystemFileError as error:
        raise CampaignError(f"campaign.system: {error}") from None
    except OSError as error:
        raise CampaignError(f"campaign.system: {system} cannot be read: {error.strerror or error}") from None


def _entries(dispersion: Dispersion) -> set[tuple[str, str, int | None]]:
    """The FMU variables a dispersion sets, as (scope, array or parameter
    name, 1-based entry or None for every entry); plant.theta[k] is theta[k]."""
    entries = set()
    for name in dispersion.names:
        base, _, index = name.partition("[")
        entries.add((dispersion.scope, base, int(index[:-1]) if index else None))
    return entries


def _refuse_overlaps(dispersions: tuple[Dispersion, ...]) -> None:
    """Two dispersions that set the same variable would fly one value and
    record both: refused, naming both keys. qvel and nu both set ν (qvel is
    turned into ν at the drawn θ, every entry at once), so they never go
    together."""
    for i, first in enumerate(dispersions):
        for second in dispersions[i + 1 :]:
            bases = {_entries(first).pop()[1], _entries(second).pop()[1]}
            if bases == {"qvel", "nu"} and first.scope == second.scope == "plant":
                raise CampaignError(
                    f"dispersions: '{first.key}' and '{second.key}' both set the start velocity ν "
                    "(qvel is turned into ν, every entry at once): disperse qvel or nu, not both"
                )
            shared = sorted(
                (base, a if a is not None else b)
                for scope, base, a in _entries(first)
                for other_scope, other_base, b in _entries(second)
                if (scope, base) == (other_scope, other_base) and (a is None or b is None or a == b)
            )
            if shared:
                base, index = shared[0]
                what = f"{base}[{index}]" if index is not None else base
                raise CampaignError(
                    f"dispersions: '{first.key}' and '{second.key}' both set {first.scope} variable {what}: "
                    "a case would fly one value and record two; disperse each variable once"
                )


def _schedule(key: str, points) -> tuple[tuple[float, float], ...]:
    match = _TARGET.match(key)
    if match is None or match.group(1) or match.group(2) not in INPUTS or match.group(3) is None or match.group(4):
        raise CampaignError(f"schedules.{key}: a schedule sets one input entry: eps[k], ctrl[k] or xfrc_applied[k]")
    if not isinstance(points, list) or not points or not all(isinstance(p, list) and len(p) == 2 for p in points):
        raise CampaignError(f"schedules.{key}: expected [[time, value], ...], found {points!r}")
    parsed = tuple((_number(t, f"schedules.{key}"), _number(v, f"schedules.{key}")) for t, v in points)
    if any(b[0] <= a[0] for a, b in zip(parsed, parsed[1:])):
        raise CampaignError(f"schedules.{key}: the times must increase")
    return parsed


def draw(campaign: Campaign, case: int) -> dict[str, float | list[float]]:
    """Case `case`'s drawn values by key (a range's values as a list), from
    (campaign seed, case) alone: any case reruns alone to the same numbers."""
    rng = np.random.default_rng([campaign.seed, case])
    grid_index = case
    values: dict = {}
    for dispersion in campaign.dispersions:
        count, p = len(dispersion.names), dispersion.parameters
        if dispersion.distribution == "grid":
            drawn = [p[grid_index % len(p)]] * count
            grid_index //= len(p)
        elif dispersion.distribution == "uniform":
            drawn = rng.uniform(p[0], p[1], count).tolist()
        elif dispersion.distribution == "normal":
            drawn = rng.normal(p[0], p[1], count).tolist()
        else:
            drawn = [p[i] for i in rng.integers(0, len(p), count)]
        values[dispersion.key] = drawn[0] if count == 1 else drawn
    return values
