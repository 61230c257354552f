"""Instances of an exported FMU driven through FMPy, set up by variable
name, with every message they log kept.

FMPy raises FMICallException for a status worse than fmi2Warning;
`status_of` turns that back into the status for callers to whom a refused
call or a discarded step is a result (the stress suite), not a failure."""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Iterable, Mapping

import numpy as np
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2Discard,
    fmi2LastSuccessfulTime,
    fmi2OK,
    fmi2Terminated,
    fmi2True,
)

from .errors import DriverError
from .package import FmuPackage

STATUS_NAMES = {0: "fmi2OK", 1: "fmi2Warning", 2: "fmi2Discard", 3: "fmi2Error", 4: "fmi2Fatal", 5: "fmi2Pending"}


def status_of(call: Callable, *args, **kwargs) -> int:
    """The status FMPy raised from `call(...)` (fmi2Discard or worse), or
    fmi2OK if it went through (fmi2Warning included: FMPy raises nothing)."""
    try:
        call(*args, **kwargs)
    except FMICallException as refused:
        return refused.status
    return fmi2OK


class Log:
    """FMPy callbacks whose logger keeps every message an instance logs, as
    (status, category, message). With loggingOn, each fmi2DoStep also logs
    its integration statistics (logStepStatistics, one JSON object)."""

    HELD_TOLERANCE = re.compile(r"held to (\S+) per second")

    def __init__(self):
        self.messages: list[tuple[int, str, str]] = []
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(self._log)
        # nudyn's FMUs allocate nothing through the importer
        # (canNotUseMemoryManagementFunctions), so these are never called.
        self.callbacks.allocateMemory = fmi2CallbackFunctions._fields_[1][1](lambda n, size: None)
        self.callbacks.freeMemory = fmi2CallbackFunctions._fields_[2][1](lambda p: None)

    def _log(self, _env, _name, status, category, message):
        self.messages.append((status, category.decode(), message.decode(errors="replace")))

    def text(self) -> str:
        return "\n".join(f"[{s}] {c}: {m}" for s, c, m in self.messages)

    def last_problem(self) -> str:
        """The last message that is not a logCalls trace ("" if none): what
        the FMU said about the call it refused or the step it discarded."""
        return next((m for _, c, m in reversed(self.messages) if c != "logCalls"), "")

    def step_statistics(self) -> list[dict[str, int]]:
        """Each doStep's statistics, in order: {"accepted", "rejected",
        "jacobians", "exact_jacobians", "evaluations", "locating"}."""
        return [json.loads(message) for _, category, message in self.messages if category == "logStepStatistics"]

    def internal_steps(self) -> tuple[int, int]:
        """(taken, rejected) internal steps over every doStep logged."""
        statistics = self.step_statistics()
        return sum(s["accepted"] for s in statistics), sum(s["rejected"] for s in statistics)

    def evaluations(self) -> int:
        """The evaluations of the rates over every doStep logged."""
        return sum(s["evaluations"] for s in self.step_statistics())

    def method_choices(self) -> list[str]:
        """What `method = auto` chose and where it moved up, in order."""
        return [message for _, category, message in self.messages if category == "logMethodChoice"]

    def held_tolerance(self) -> float | None:
        """The per-second tolerance the FMU last said it held instead of the
        one asked for (round-off in the rates), if it said so: a warning, or
        within 20 times the one asked a logMethodChoice note."""
        held = [self.HELD_TOLERANCE.search(m) for _, c, m in self.messages
                if c in ("logStatusWarning", "logMethodChoice")]
        held = [h for h in held if h]
        return float(held[-1].group(1)) if held else None


Value = float | int | bool | str
# (value references, values) by the type of FMI setter that takes them.
Groups = dict[str, tuple[list[int], list[Value]]]


class Instance:
    """One FMU2Slave of a package, instantiated and initialized.

    Before fmi2EnterInitializationMode it sets `start` by variable name
    (parameters and start values; an Enumeration takes its item's name) and
    the initial θ and ν (initial="exact"); a value the FMU refuses there is a
    DriverError with the FMU's words, and the instance is freed. `logging_on`
    is fmi2Instantiate's loggingOn: every log category, logCalls and
    logStepStatistics included (which count each fmi2DoStep's internal steps). `time` is the
    communication point of the next step. `fmu` is FMPy's FMU2Slave, for the
    FMI calls this class does not wrap; every failing call after
    initialization raises FMPy's FMICallException."""

    def __init__(
        self,
        package: FmuPackage,
        *,
        name: str = "nudyn",
        start: Mapping[str, Value] | None = None,
        theta: Iterable[float] | None = None,
        nu: Iterable[float] | None = None,
        experiment_tolerance: float | None = None,
        stop_time: float | None = None,
        logging_on: bool = False,
    ):
        self.package = package
        values = dict(start or {})
        if theta is not None:
            values.update(zip(package.names("theta"), map(float, theta)))
        if nu is not None:
            values.update(zip(package.names("nu"), map(float, nu)))
        initial = self._grouped(values)
        self.log = Log()
        self.fmu = FMU2Slave(
            guid=package.guid,
            unzipDirectory=str(package.directory),
            modelIdentifier=package.model_identifier,
            instanceName=name,
        )
        self.fmu.instantiate(callbacks=self.log.callbacks, loggingOn=logging_on)
        self.name, self.experiment_tolerance, self.stop_time = name, experiment_tolerance, stop_time
        try:
            self._initialize(initial)
        except DriverError:
            # The caller never gets this instance, so it cannot free it.
            self.fmu.freeInstance()
            raise

    def _initialize(self, initial: Groups) -> None:
        try:
            self.fmu.setupExperiment(tolerance=self.experiment_tolerance, startTime=0.0, stopTime=self.stop_time)
            self._set_grouped(initial)
            self.fmu.enterInitializationMode()
            self.fmu.exitInitializationMode()
        except FMICallException as refused:
            raise DriverError(f"{self.name}: {refused} {self.log.last_problem()}".rstrip()) from None
        self.time = 0.0

    def reset(
        self,
        start: Mapping[str, Value] | None = None,
        theta: Iterable[float] | None = None,
        nu: Iterable[float] | None = None,
    ) -> None:
        """fmi2Reset, then a fresh initialization with these values, as at
        construction: one instance serves many runs (no re-instantiation,
        no re-extraction). A refused value is a DriverError; the instance
        stays usable for the next reset."""
        values = dict(start or {})
        if theta is not None:
            values.update(zip(self.package.names("theta"), map(float, theta)))
        if nu is not None:
            values.update(zip(self.package.names("nu"), map(float, nu)))
        initial = self._grouped(values)
        self.fmu.reset()
        self._initialize(initial)

    def __enter__(self) -> Instance:
        return self

    def __exit__(self, *_exception) -> None:
        self.close()

    def set(self, values: Mapping[str, Value]) -> None:
        """Sets variables by name: the Reals in one fmi2SetReal, then the
        Integers and Enumerations, then the Booleans."""
        self._set_grouped(self._grouped(values))

    def _grouped(self, values: Mapping[str, Value]) -> Groups:
        """`values` by setter, enumeration items by value. Unknown names and
        items raise here, before any FMI call."""
        groups: Groups = {"Real": ([], []), "Integer": ([], []), "Boolean": ([], [])}
        for name, value in values.items():
            kind = self.package.variable(name).type
            if kind == "Enumeration":
                kind = "Integer"  # FMI 2.0 sets an Enumeration with fmi2SetInteger
                if isinstance(value, str):
                    value = self.package.enumeration_value(name, value)
            refs, group = groups[kind]
            refs.append(self.package.vr[name])
            group.append(value)
        return groups

    def _set_grouped(self, groups: Groups) -> None:
        setters = {"Real": self.fmu.setReal, "Integer": self.fmu.setInteger, "Boolean": self.fmu.setBoolean}
        for kind, (refs, group) in groups.items():
            if refs:
                setters[kind](refs, group)

    def get(self, names: Iterable[str]) -> np.ndarray:
        """The Real variables called `names`."""
        return np.array(self.fmu.getReal([self.package.vr[name] for name in names]))

    def real(self, name: str) -> float:
        return self.fmu.getReal([self.package.vr[name]])[0]

    def array(self, prefix: str) -> np.ndarray:
        """The Real array variable prefix[1..]."""
        return np.array(self.fmu.getReal(self.package.refs(prefix)))

    def set_array(self, prefix: str, values: Iterable[float]) -> None:
        self.fmu.setReal(self.package.refs(prefix), list(map(float, values)))

    def all_reals(self) -> np.ndarray:
        return self.get(self.package.reals)

    def step(self, size: float, communication_point: float | None = None) -> int:
        """One fmi2DoStep of `size` from `communication_point`, by default
        `time` (where the last step ended); a master that counts its points
        as k·h passes them, so that its steps do not depend on round-off
        accumulated in `time`. Returns the status (fmi2OK or fmi2Warning)
        and sets `time` to the step's end. A discarded step raises, with
        `time` where the integration stopped (fmi2LastSuccessfulTime); any
        other refusal leaves `time` as it was."""
        start = self.time if communication_point is None else communication_point
        try:
            status = self.fmu.fmi2DoStep(self.fmu.component, start, size, fmi2True)
        except FMICallException as refused:
            if refused.status == fmi2Discard:
                self.time = self.last_successful_time()
            raise
        self.time = start + size
        return status

    def last_successful_time(self) -> float:
        return self.fmu.getRealStatus(fmi2LastSuccessfulTime)

    def terminated(self) -> bool:
        return bool(self.fmu.getBooleanStatus(fmi2Terminated))

    def close(self) -> None:
        """fmi2Terminate, then fmi2FreeInstance (legal in every state, so
        also after a refused terminate, whose message stays in the log)."""
        status_of(self.fmu.terminate)
        self.fmu.freeInstance()
