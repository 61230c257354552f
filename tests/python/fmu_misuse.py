"""Misuse of a nudyn FMU's binary, called directly through ctypes as a
C importer would: NULL and unknown arguments, calls out of sequence,
non-finite and huge values, bad steps, bad resources and URIs, corrupt FMU
states. Each case declares the status the FMI 2.0 standard prescribes for
every call it makes and the words the FMU must log about it.

Every case runs in a process of its own (`python fmu_misuse.py run CASE
...`), so that a crash or a hang is seen by the parent as a signal or a
timeout instead of taking the test runner down; `test_fmu_misuse.py` runs
them all, and checks the misuse table in docs/fmi.md (`table` below): its
crash column is 0 because a case that crashes or hangs fails the suite.

Statuses (FMI 2.0 §2.1.3): fmi2Error for a call the FMU refuses (then the
instance is in the error state, §4.2.4, until fmi2SetFMUstate, fmi2Reset
or fmi2FreeInstance), fmi2Discard for a value out of its range in
fmi2SetXXX (footnote 3) and for a failed doStep, NULL from fmi2Instantiate.
After every case, each instance still alive must read back only finite
values."""

from __future__ import annotations

import ctypes as C
import json
import math
import os
import struct
import sys
from collections import Counter
from pathlib import Path

# nudyn_driver lives outside tests/; this file also runs as a script.
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "python"))
from nudyn_driver.package import FmuPackage  # noqa: E402  (needs the path above)

OK, WARNING, DISCARD, ERROR, FATAL = 0, 1, 2, 3, 4
# fmi2Instantiate has no status: a refusal is a NULL instance.
NULL_INSTANCE = -1
STATUS_NAMES = {OK: "fmi2OK", WARNING: "fmi2Warning", DISCARD: "fmi2Discard", ERROR: "fmi2Error", FATAL: "fmi2Fatal",
                NULL_INSTANCE: "NULL instance"}
CO_SIMULATION, MODEL_EXCHANGE = 1, 0
LAST_SUCCESSFUL_TIME, TERMINATED, DO_STEP_STATUS, PENDING_STATUS = 2, 3, 0, 1
STEP = 0.01

comp = C.c_void_p
vr_array = C.POINTER(C.c_uint)
LOGGER = C.CFUNCTYPE(None, C.c_void_p, C.c_char_p, C.c_int, C.c_char_p, C.c_char_p)
ALLOCATE = C.CFUNCTYPE(C.c_void_p, C.c_size_t, C.c_size_t)
FREE = C.CFUNCTYPE(None, C.c_void_p)
STEP_FINISHED = C.CFUNCTYPE(None, C.c_void_p, C.c_int)


class Callbacks(C.Structure):
    _fields_ = [("logger", LOGGER), ("allocateMemory", ALLOCATE), ("freeMemory", FREE),
                ("stepFinished", STEP_FINISHED), ("componentEnvironment", C.c_void_p)]


# Every exported function with its C signature (fmi2Functions.h).
SIGNATURES = {
    "fmi2GetTypesPlatform": (C.c_char_p, []),
    "fmi2GetVersion": (C.c_char_p, []),
    "fmi2Instantiate": (comp, [C.c_char_p, C.c_int, C.c_char_p, C.c_char_p, C.POINTER(Callbacks), C.c_int, C.c_int]),
    "fmi2FreeInstance": (None, [comp]),
    "fmi2SetDebugLogging": (C.c_int, [comp, C.c_int, C.c_size_t, C.POINTER(C.c_char_p)]),
    "fmi2SetupExperiment": (C.c_int, [comp, C.c_int, C.c_double, C.c_double, C.c_int, C.c_double]),
    "fmi2EnterInitializationMode": (C.c_int, [comp]),
    "fmi2ExitInitializationMode": (C.c_int, [comp]),
    "fmi2Terminate": (C.c_int, [comp]),
    "fmi2Reset": (C.c_int, [comp]),
    "fmi2GetReal": (C.c_int, [comp, vr_array, C.c_size_t, C.POINTER(C.c_double)]),
    "fmi2GetInteger": (C.c_int, [comp, vr_array, C.c_size_t, C.POINTER(C.c_int)]),
    "fmi2GetBoolean": (C.c_int, [comp, vr_array, C.c_size_t, C.POINTER(C.c_int)]),
    "fmi2GetString": (C.c_int, [comp, vr_array, C.c_size_t, C.POINTER(C.c_char_p)]),
    "fmi2SetReal": (C.c_int, [comp, vr_array, C.c_size_t, C.POINTER(C.c_double)]),
    "fmi2SetInteger": (C.c_int, [comp, vr_array, C.c_size_t, C.POINTER(C.c_int)]),
    "fmi2SetBoolean": (C.c_int, [comp, vr_array, C.c_size_t, C.POINTER(C.c_int)]),
    "fmi2SetString": (C.c_int, [comp, vr_array, C.c_size_t, C.POINTER(C.c_char_p)]),
    "fmi2GetFMUstate": (C.c_int, [comp, C.POINTER(C.c_void_p)]),
    "fmi2SetFMUstate": (C.c_int, [comp, C.c_void_p]),
    "fmi2FreeFMUstate": (C.c_int, [comp, C.POINTER(C.c_void_p)]),
    "fmi2SerializedFMUstateSize": (C.c_int, [comp, C.c_void_p, C.POINTER(C.c_size_t)]),
    "fmi2SerializeFMUstate": (C.c_int, [comp, C.c_void_p, C.c_char_p, C.c_size_t]),
    "fmi2DeSerializeFMUstate": (C.c_int, [comp, C.c_char_p, C.c_size_t, C.POINTER(C.c_void_p)]),
    "fmi2GetDirectionalDerivative": (C.c_int, [comp, vr_array, C.c_size_t, vr_array, C.c_size_t,
                                               C.POINTER(C.c_double), C.POINTER(C.c_double)]),
    "fmi2SetRealInputDerivatives": (C.c_int, [comp, vr_array, C.c_size_t, C.POINTER(C.c_int), C.POINTER(C.c_double)]),
    "fmi2GetRealOutputDerivatives": (C.c_int, [comp, vr_array, C.c_size_t, C.POINTER(C.c_int), C.POINTER(C.c_double)]),
    "fmi2DoStep": (C.c_int, [comp, C.c_double, C.c_double, C.c_int]),
    "fmi2CancelStep": (C.c_int, [comp]),
    "fmi2GetStatus": (C.c_int, [comp, C.c_int, C.POINTER(C.c_int)]),
    "fmi2GetRealStatus": (C.c_int, [comp, C.c_int, C.POINTER(C.c_double)]),
    "fmi2GetIntegerStatus": (C.c_int, [comp, C.c_int, C.POINTER(C.c_int)]),
    "fmi2GetBooleanStatus": (C.c_int, [comp, C.c_int, C.POINTER(C.c_int)]),
    "fmi2GetStringStatus": (C.c_int, [comp, C.c_int, C.POINTER(C.c_char_p)]),
    "fmi2EnterEventMode": (C.c_int, [comp]),
    "fmi2NewDiscreteStates": (C.c_int, [comp, C.c_void_p]),
    "fmi2EnterContinuousTimeMode": (C.c_int, [comp]),
    "fmi2CompletedIntegratorStep": (C.c_int, [comp, C.c_int, C.POINTER(C.c_int), C.POINTER(C.c_int)]),
    "fmi2SetTime": (C.c_int, [comp, C.c_double]),
    "fmi2SetContinuousStates": (C.c_int, [comp, C.POINTER(C.c_double), C.c_size_t]),
    "fmi2GetDerivatives": (C.c_int, [comp, C.POINTER(C.c_double), C.c_size_t]),
    "fmi2GetEventIndicators": (C.c_int, [comp, C.POINTER(C.c_double), C.c_size_t]),
    "fmi2GetContinuousStates": (C.c_int, [comp, C.POINTER(C.c_double), C.c_size_t]),
    "fmi2GetNominalsOfContinuousStates": (C.c_int, [comp, C.POINTER(C.c_double), C.c_size_t]),
}

# The arguments after the component with which each function is otherwise
# valid: used to call every function with a NULL or freed component.
PLAIN_ARGUMENTS = {
    "fmi2SetDebugLogging": (1, 0, None),
    "fmi2SetupExperiment": (0, 0.0, 0.0, 0, 0.0),
    "fmi2GetReal": (None, 0, None),
    "fmi2GetInteger": (None, 0, None),
    "fmi2GetBoolean": (None, 0, None),
    "fmi2GetString": (None, 0, None),
    "fmi2SetReal": (None, 0, None),
    "fmi2SetInteger": (None, 0, None),
    "fmi2SetBoolean": (None, 0, None),
    "fmi2SetString": (None, 0, None),
    "fmi2GetFMUstate": (C.pointer(C.c_void_p()),),
    "fmi2SetFMUstate": (None,),
    "fmi2FreeFMUstate": (C.pointer(C.c_void_p()),),
    "fmi2SerializedFMUstateSize": (None, C.pointer(C.c_size_t())),
    "fmi2SerializeFMUstate": (None, None, 0),
    "fmi2DeSerializeFMUstate": (None, 0, C.pointer(C.c_void_p())),
    "fmi2GetDirectionalDerivative": (None, 0, None, 0, None, None),
    "fmi2SetRealInputDerivatives": (None, 0, None, None),
    "fmi2GetRealOutputDerivatives": (None, 0, None, None),
    "fmi2DoStep": (0.0, STEP, 1),
    "fmi2CancelStep": (),
    "fmi2GetStatus": (DO_STEP_STATUS, C.pointer(C.c_int())),
    "fmi2GetRealStatus": (LAST_SUCCESSFUL_TIME, C.pointer(C.c_double())),
    "fmi2GetIntegerStatus": (DO_STEP_STATUS, C.pointer(C.c_int())),
    "fmi2GetBooleanStatus": (TERMINATED, C.pointer(C.c_int())),
    "fmi2GetStringStatus": (DO_STEP_STATUS, C.pointer(C.c_char_p())),
    "fmi2EnterInitializationMode": (),
    "fmi2ExitInitializationMode": (),
    "fmi2Terminate": (),
    "fmi2Reset": (),
    "fmi2EnterEventMode": (),
    "fmi2NewDiscreteStates": (C.cast(C.create_string_buffer(32), C.c_void_p),),
    "fmi2EnterContinuousTimeMode": (),
    "fmi2CompletedIntegratorStep": (1, C.pointer(C.c_int()), C.pointer(C.c_int())),
    "fmi2SetTime": (0.0,),
    "fmi2SetContinuousStates": (None, 0),
    "fmi2GetDerivatives": (None, 0),
    "fmi2GetEventIndicators": (None, 0),
    "fmi2GetContinuousStates": (None, 0),
    "fmi2GetNominalsOfContinuousStates": (None, 0),
}
COMPONENT_FUNCTIONS = sorted(PLAIN_ARGUMENTS)


class CaseFailed(AssertionError):
    pass


def library(fmu: FmuPackage) -> Path:
    """The FMU's binary, which the cases load with ctypes."""
    return fmu.directory / "binaries" / "linux64" / f"{fmu.model_identifier}.so"


def resource_uri(fmu: FmuPackage) -> str:
    return (fmu.directory / "resources").as_uri() + "/"


class Harness:
    """The library, a logger that keeps messages, and helpers that check
    each call's status and message. `calls` records (function, status) for
    the table."""

    def __init__(self, fmu: FmuPackage, other: FmuPackage | None = None):
        self.fmu = fmu
        self.other = other
        self.lib = C.CDLL(str(library(fmu)))
        for name, (restype, argtypes) in SIGNATURES.items():
            function = getattr(self.lib, name)
            function.restype, function.argtypes = restype, argtypes
        self.messages: list[tuple[int, str, str]] = []
        self._logger = LOGGER(self._log)
        self.callbacks = Callbacks(self._logger, ALLOCATE(), FREE(), STEP_FINISHED(), None)
        self.calls: list[tuple[str, int]] = []
        self.live: list[tuple[int, FmuPackage]] = []

    def _log(self, _env, _name, status, category, message):
        self.messages.append((status, category.decode(), message.decode(errors="replace")))

    def log_text(self, since: int = 0) -> str:
        return "\n".join(f"[{s}] {c}: {m}" for s, c, m in self.messages[since:])

    def call(self, name: str, *args):
        return getattr(self.lib, name)(*args)

    def expect(self, status: int, name: str, c, *args, says: tuple[str, ...] = ()):
        """Calls `name(c, *args)`, which must return `status`; a status
        other than OK on a live instance must be logged, naming the function
        and containing every fragment of `says`."""
        before = len(self.messages)
        found = self.call(name, c, *args)
        self.calls.append((name, found))
        new = self.log_text(before)
        if found != status:
            raise CaseFailed(f"{name} returned {STATUS_NAMES.get(found, found)}, expected "
                             f"{STATUS_NAMES[status]}; log:\n{new}")
        if status != OK and self.is_live(c):
            if name not in new:
                raise CaseFailed(f"{name} returned {STATUS_NAMES[status]} without a message naming it; log:\n{new}")
        for fragment in says:
            if fragment not in new:
                raise CaseFailed(f"{name}: expected {fragment!r} in the log, got:\n{new}")
        return found

    def is_live(self, c) -> bool:
        return any(c == live for live, _ in self.live)

    # --- instances ------------------------------------------------------------

    def instantiate(self, fmu: FmuPackage | None = None, *, guid=None, uri=None, name=b"misuse", kind=CO_SIMULATION,
                    callbacks="default", logging_on=0):
        fmu = fmu or self.fmu
        guid = fmu.guid.encode() if guid is None else guid
        uri = resource_uri(fmu).encode() if uri is None else uri
        callbacks = C.pointer(self.callbacks) if callbacks == "default" else callbacks
        c = self.lib.fmi2Instantiate(name, kind, guid, uri, callbacks, 0, logging_on)
        if c:
            self.live.append((c, fmu))
        return c

    def refused_instantiation(self, *says: str, **kwargs):
        """fmi2Instantiate must return NULL and log `says` (§2.1.5)."""
        before = len(self.messages)
        c = self.instantiate(**kwargs)
        self.calls.append(("fmi2Instantiate", NULL_INSTANCE if not c else OK))
        if c:
            raise CaseFailed("fmi2Instantiate returned an instance, expected NULL")
        for fragment in says:
            if fragment not in self.log_text(before):
                raise CaseFailed(f"fmi2Instantiate: expected {fragment!r} in the log, got:\n{self.log_text(before)}")

    def initialized(self, fmu: FmuPackage | None = None, start: dict | None = None):
        c = self.instantiate(fmu)
        if not c:
            raise CaseFailed(f"fmi2Instantiate failed:\n{self.log_text()}")
        self.expect(OK, "fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0)
        self.expect(OK, "fmi2EnterInitializationMode", c)
        if start:
            self.set_real(OK, c, start)
        self.expect(OK, "fmi2ExitInitializationMode", c)
        return c

    def free(self, c):
        self.lib.fmi2FreeInstance(c)
        self.calls.append(("fmi2FreeInstance", OK))
        self.live = [(live, fmu) for live, fmu in self.live if live != c]

    # --- values ------------------------------------------------------------

    def fmu_of(self, c) -> FmuPackage:
        return next(fmu for live, fmu in self.live if live == c)

    def set_real(self, status, c, values: dict, says=()):
        fmu = self.fmu_of(c)
        vrs = (C.c_uint * len(values))(*[fmu.vr[n] if isinstance(n, str) else n for n in values])
        reals = (C.c_double * len(values))(*values.values())
        return self.expect(status, "fmi2SetReal", c, vrs, len(values), reals, says=says)

    def get_real(self, c, names=None, status=OK):
        fmu = self.fmu_of(c)
        names = fmu.reals if names is None else names
        vrs = (C.c_uint * len(names))(*[fmu.vr[n] for n in names])
        values = (C.c_double * len(names))()
        self.expect(status, "fmi2GetReal", c, vrs, len(names), values)
        return list(values)

    def last_successful_time(self, c) -> float:
        value = C.c_double()
        self.expect(OK, "fmi2GetRealStatus", c, LAST_SUCCESSFUL_TIME, C.byref(value))
        return value.value

    def step(self, c, time: float, status=OK, h=STEP, says=()):
        return self.expect(status, "fmi2DoStep", c, time, h, 1, says=says)

    def get_state(self, c):
        state = C.c_void_p()
        self.expect(OK, "fmi2GetFMUstate", c, C.byref(state))
        return state

    def serialize(self, c, state) -> bytes:
        size = C.c_size_t()
        self.expect(OK, "fmi2SerializedFMUstateSize", c, state, C.byref(size))
        buffer = C.create_string_buffer(size.value)
        self.expect(OK, "fmi2SerializeFMUstate", c, state, buffer, size.value)
        return buffer.raw

    def deserialize(self, status, c, blob: bytes, says=()):
        state = C.c_void_p()
        self.expect(status, "fmi2DeSerializeFMUstate", c, blob, len(blob), C.byref(state), says=says)
        return state

    def finish(self):
        """No instance still alive may hold a non-finite value."""
        for c, fmu in list(self.live):
            values = (C.c_double * len(fmu.reals))()
            vrs = (C.c_uint * len(fmu.reals))(*[fmu.vr[n] for n in fmu.reals])
            if self.lib.fmi2GetReal(c, vrs, len(fmu.reals), values) == OK:
                bad = [(n, v) for n, v in zip(fmu.reals, values) if not math.isfinite(v)]
                if bad:
                    raise CaseFailed(f"non-finite outputs: {bad[:5]}")
            self.free(c)


# --- the cases -------------------------------------------------------------------

CASES: dict[str, tuple[str, callable]] = {}


def case(group: str):
    def register(function):
        CASES[function.__name__] = (group, function)
        return function
    return register


def null_component_case(name: str):
    def run(h: Harness):
        if name == "fmi2FreeInstance":
            h.lib.fmi2FreeInstance(None)
            h.calls.append((name, OK))
        else:
            h.expect(ERROR, name, None, *PLAIN_ARGUMENTS[name])
    run.__name__ = f"null_component_{name}"
    case("NULL component: every function")(run)


for _name in COMPONENT_FUNCTIONS + ["fmi2FreeInstance"]:
    null_component_case(_name)


def freed_component_case(name: str):
    def run(h: Harness):
        c = h.initialized()
        h.free(c)
        if name == "fmi2FreeInstance":
            h.lib.fmi2FreeInstance(c)  # a double free must be harmless
            h.calls.append((name, OK))
        else:
            h.expect(ERROR, name, c, *PLAIN_ARGUMENTS[name])
    run.__name__ = f"freed_component_{name}"
    case("freed instance: every function")(run)


for _name in COMPONENT_FUNCTIONS + ["fmi2FreeInstance"]:
    freed_component_case(_name)


@case("never an instance")
def garbage_component(h: Harness):
    junk = C.create_string_buffer(b"\xff" * 256)
    h.expect(ERROR, "fmi2DoStep", C.cast(junk, C.c_void_p), 0.0, STEP, 1)
    h.lib.fmi2FreeInstance(C.cast(junk, C.c_void_p))
    h.calls.append(("fmi2FreeInstance", OK))


@case("NULL arrays")
def null_arrays(h: Harness):
    c = h.initialized()
    saved = h.get_state(c)
    value = (C.c_double * 2)()
    vrs = (C.c_uint * 2)(h.fmu.vr["theta[1]"], h.fmu.vr["nu[1]"])
    order = (C.c_int * 2)(1, 1)
    calls = [
        ("fmi2GetReal", (None, 2, value), "vr is NULL"),
        ("fmi2GetReal", (vrs, 2, None), "value is NULL"),
        ("fmi2SetReal", (None, 1, value), "vr is NULL"),
        ("fmi2SetReal", (vrs, 1, None), "value is NULL"),
        ("fmi2GetInteger", (None, 1, None), "vr is NULL"),
        ("fmi2SetInteger", (None, 1, None), "vr is NULL"),
        ("fmi2GetBoolean", (None, 1, None), "vr is NULL"),
        ("fmi2SetString", (None, 1, None), "vr is NULL"),
        ("fmi2SetRealInputDerivatives", ((C.c_uint * 1)(h.fmu.vr["eps[1]"]), 1, None, value), "order is NULL"),
        ("fmi2GetRealOutputDerivatives", (vrs, 2, order, None), "value is NULL"),
        ("fmi2GetFMUstate", (None,), "FMUstate is NULL"),
        ("fmi2SetFMUstate", (None,), "FMUstate is NULL"),
        ("fmi2SerializedFMUstateSize", (saved, None), "size is NULL"),
        ("fmi2SerializeFMUstate", (saved, None, 1), "expected"),
        ("fmi2DeSerializeFMUstate", (None, 10, C.pointer(C.c_void_p())), "serializedState is NULL"),
        ("fmi2DeSerializeFMUstate", (b"x", 1, None), "FMUstate is NULL"),
        ("fmi2GetStatus", (DO_STEP_STATUS, None), "value is NULL"),
        ("fmi2GetRealStatus", (LAST_SUCCESSFUL_TIME, None), "value is NULL"),
        ("fmi2GetBooleanStatus", (TERMINATED, None), "value is NULL"),
        ("fmi2SetDebugLogging", (1, 2, None), "categories is NULL"),
    ]
    for name, args, says in calls:
        h.expect(ERROR, name, c, *args, says=(says,))
        h.expect(OK, "fmi2SetFMUstate", c, saved)
    # Empty arrays may be NULL.
    h.expect(OK, "fmi2GetReal", c, None, 0, None)
    h.expect(OK, "fmi2SetReal", c, None, 0, None)
    h.expect(OK, "fmi2FreeFMUstate", c, None)


@case("NULL arguments of fmi2Instantiate")
def null_instantiate_arguments(h: Harness):
    h.refused_instantiation("instanceName is NULL", name=None)
    h.refused_instantiation("fmuGUID is NULL", guid=C.c_char_p())
    h.refused_instantiation("fmuResourceLocation is NULL", uri=C.c_char_p())
    h.refused_instantiation(callbacks=None)  # no logger to tell


@case("NULL arguments of fmi2Instantiate")
def null_logger_still_works(h: Harness):
    """A NULL logger is allowed: messages are dropped, nothing crashes."""
    quiet = Callbacks(LOGGER(), ALLOCATE(), FREE(), STEP_FINISHED(), None)
    c = h.instantiate(callbacks=C.pointer(quiet))
    assert c, "instantiation with a NULL logger"
    h.calls.append(("fmi2Instantiate", OK))
    status = h.lib.fmi2DoStep(c, 0.0, STEP, 1)
    h.calls.append(("fmi2DoStep", status))
    assert status == ERROR, f"fmi2DoStep before initialization returned {status}"
    h.expect(OK, "fmi2Reset", c)


@case("wrong lengths")
def serialized_buffer_sizes(h: Harness):
    c = h.initialized()
    saved = h.get_state(c)
    size = len(h.serialize(c, saved))
    for wrong in (0, 1, size - 1, size + 1, 2**62):
        buffer = C.create_string_buffer(max(1, min(wrong, size + 1)))
        h.expect(ERROR, "fmi2SerializeFMUstate", c, saved, buffer, wrong, says=(f"expected {size}",))
        h.expect(OK, "fmi2SetFMUstate", c, saved)
    categories = (C.c_char_p * 1)(b"logNoSuchThing")
    h.expect(ERROR, "fmi2SetDebugLogging", c, 1, 1, categories, says=("unknown log category 'logNoSuchThing'",))


@case("unknown value references")
def unknown_value_references(h: Harness):
    c = h.initialized()
    saved = h.get_state(c)
    one = (C.c_double * 1)()
    integer = (C.c_int * 1)(1)
    boolean = (C.c_int * 1)()
    string = (C.c_char_p * 1)(b"x")
    for vr in (99999, 2**32 - 1, len(h.fmu.reals) + 1):
        vrs = (C.c_uint * 1)(vr)
        for name, values in [("fmi2GetReal", one), ("fmi2SetReal", one)]:
            h.expect(ERROR, name, c, vrs, 1, values, says=(f"unknown value reference {vr}",))
            h.expect(OK, "fmi2SetFMUstate", c, saved)
    for name, vr, values in [("fmi2GetInteger", 5, integer), ("fmi2SetInteger", 1, integer),
                             ("fmi2GetBoolean", 1, boolean), ("fmi2SetBoolean", 1, boolean),
                             ("fmi2GetString", 0, string), ("fmi2SetString", 0, string)]:
        h.expect(ERROR, name, c, (C.c_uint * 1)(vr), 1, values, says=(f"unknown value reference {vr}",))
        h.expect(OK, "fmi2SetFMUstate", c, saved)


@case("derivatives of the wrong variable or order")
def derivative_misuse(h: Harness):
    c = h.initialized()
    saved = h.get_state(c)
    value = (C.c_double * 1)(1.0)
    theta, eps = (C.c_uint * 1)(h.fmu.vr["theta[1]"]), (C.c_uint * 1)(h.fmu.vr["eps[1]"])
    h.expect(ERROR, "fmi2SetRealInputDerivatives", c, theta, 1, (C.c_int * 1)(1), value, says=("theta[1]",))
    h.expect(OK, "fmi2SetFMUstate", c, saved)
    h.expect(ERROR, "fmi2SetRealInputDerivatives", c, eps, 1, (C.c_int * 1)(2), value, says=("order 2",))
    h.expect(OK, "fmi2SetFMUstate", c, saved)
    h.expect(ERROR, "fmi2SetRealInputDerivatives", c, eps, 1, (C.c_int * 1)(1), (C.c_double * 1)(math.nan),
             says=("der(eps[1]) = NaN",))
    h.expect(OK, "fmi2SetFMUstate", c, saved)
    h.expect(ERROR, "fmi2GetRealOutputDerivatives", c, eps, 1, (C.c_int * 1)(1), value, says=("eps[1]",))
    h.expect(OK, "fmi2SetFMUstate", c, saved)
    h.expect(ERROR, "fmi2GetRealOutputDerivatives", c, theta, 1, (C.c_int * 1)(0), value, says=("order 0",))
    h.expect(OK, "fmi2SetFMUstate", c, saved)
    h.expect(ERROR, "fmi2GetDirectionalDerivative", c, None, 1, None, 1, None, None, says=("NULL",))


# --- calls out of sequence (§4.2.4) ------------------------------------------------

@case("out of sequence")
def step_before_initialization(h: Harness):
    c = h.instantiate()
    h.step(c, 0.0, ERROR, says=("fmi2DoStep may not be called in state instantiated",))
    h.expect(ERROR, "fmi2DoStep", c, 0.0, STEP, 1, says=("state error",))
    h.expect(OK, "fmi2Reset", c)
    h.expect(OK, "fmi2EnterInitializationMode", c)
    h.step(c, 0.0, ERROR, says=("state initializationMode",))


@case("out of sequence")
def initialization_calls_out_of_order(h: Harness):
    c = h.instantiate()
    h.expect(ERROR, "fmi2ExitInitializationMode", c, says=("state instantiated",))
    h.expect(OK, "fmi2Reset", c)
    h.expect(OK, "fmi2EnterInitializationMode", c)
    h.expect(ERROR, "fmi2EnterInitializationMode", c, says=("state initializationMode",))
    h.expect(OK, "fmi2Reset", c)
    h.expect(OK, "fmi2EnterInitializationMode", c)
    h.expect(ERROR, "fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0, says=("state initializationMode",))
    h.expect(OK, "fmi2Reset", c)
    h.expect(ERROR, "fmi2GetReal", c, None, 0, None, says=("state instantiated",))


@case("out of sequence")
def set_output_or_fixed_parameter_after_initialization(h: Harness):
    c = h.initialized()
    saved = h.get_state(c)
    for name in ("theta[1]", "nu[1]", "tolerance", "max_step"):
        h.set_real(ERROR, c, {name: 0.5}, says=(name, "after initialization"))
        h.expect(OK, "fmi2SetFMUstate", c, saved)
    h.set_real(ERROR, c, {"kinetic_energy": 1.0}, says=("calculated output",))
    h.expect(OK, "fmi2SetFMUstate", c, saved)
    h.expect(ERROR, "fmi2SetInteger", c, (C.c_uint * 1)(0), 1, (C.c_int * 1)(1), says=("method", "after initialization"))


@case("out of sequence")
def calls_after_an_error(h: Harness):
    """After fmi2Error only reading, FMU states, reset and free remain (§2.1.3, §4.2.4)."""
    c = h.initialized()
    saved = h.get_state(c)
    h.step(c, 0.0)
    before = h.get_real(c)
    h.step(c, 0.5, ERROR, says=("expected currentCommunicationPoint",))
    h.step(c, STEP, ERROR, says=("state error",))
    h.set_real(ERROR, c, {"eps[1]": 1.0}, says=("state error",))
    h.expect(ERROR, "fmi2Terminate", c, says=("state error",))
    h.expect(ERROR, "fmi2GetStatus", c, DO_STEP_STATUS, C.pointer(C.c_int()), says=("state error",))
    assert h.get_real(c) == before, "values stay readable and unchanged in the error state"
    h.expect(OK, "fmi2SetFMUstate", c, saved)
    h.step(c, 0.0)
    h.step(c, 0.5, ERROR)
    h.expect(OK, "fmi2Reset", c)
    h.expect(OK, "fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0)


@case("out of sequence")
def terminate_twice_and_after(h: Harness):
    c = h.initialized()
    h.step(c, 0.0)
    final = h.get_real(c)
    h.expect(OK, "fmi2Terminate", c)
    h.expect(ERROR, "fmi2Terminate", c, says=("fmi2Terminate may not be called in state terminated",))
    assert h.get_real(c) == final
    h.expect(OK, "fmi2Reset", c)
    h.expect(ERROR, "fmi2Terminate", c, says=("state instantiated",))
    h.expect(OK, "fmi2Reset", c)
    h.expect(OK, "fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0)
    h.expect(OK, "fmi2EnterInitializationMode", c)
    h.expect(OK, "fmi2ExitInitializationMode", c)
    h.expect(OK, "fmi2Terminate", c)
    h.step(c, STEP, ERROR, says=("state terminated",))


@case("out of sequence")
def sensors_read_before_initialization(h: Harness):
    """sensordata is calculated: refused before initialization mode, and
    at a start state the dynamics cannot evaluate it says why; once the
    state is valid the same read works and gives finite values."""
    c = h.instantiate()
    sensors = h.fmu_of(c).names("sensordata")
    assert len(sensors) == 30, "the servicer's sensors"
    h.get_real(c, sensors, status=ERROR)
    assert "state instantiated" in h.log_text(), h.log_text()
    h.expect(OK, "fmi2Reset", c)
    h.expect(OK, "fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0)
    h.expect(OK, "fmi2EnterInitializationMode", c)
    # theta[4..7] is the bus's quaternion: zero, no rotation to measure.
    h.set_real(OK, c, {f"theta[{k}]": 0.0 for k in range(4, 8)})
    since = len(h.messages)
    h.get_real(c, sensors, status=ERROR)
    assert "zero quaternion" in h.log_text(since), h.log_text(since)
    h.expect(OK, "fmi2Reset", c)
    h.expect(OK, "fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0)
    h.expect(OK, "fmi2EnterInitializationMode", c)
    values = h.get_real(c, sensors)
    assert all(math.isfinite(v) for v in values) and values[0] == 1.0, values
    h.expect(OK, "fmi2ExitInitializationMode", c)
    h.step(c, 0.0)
    assert all(math.isfinite(v) for v in h.get_real(c, sensors))


@case("out of sequence")
def cancel_step_and_status_queries(h: Harness):
    c = h.initialized()
    saved = h.get_state(c)
    h.expect(ERROR, "fmi2CancelStep", c, says=("fmi2CancelStep may not be called",))
    h.expect(OK, "fmi2SetFMUstate", c, saved)
    for name, kind, value in [("fmi2GetStatus", PENDING_STATUS, C.pointer(C.c_int())),
                              ("fmi2GetRealStatus", DO_STEP_STATUS, C.pointer(C.c_double())),
                              ("fmi2GetIntegerStatus", DO_STEP_STATUS, C.pointer(C.c_int())),
                              ("fmi2GetBooleanStatus", DO_STEP_STATUS, C.pointer(C.c_int())),
                              ("fmi2GetStringStatus", PENDING_STATUS, C.pointer(C.c_char_p())),
                              ("fmi2GetStatus", 1234, C.pointer(C.c_int()))]:
        h.expect(DISCARD, name, c, kind, value, says=("not available",))
    h.step(c, 0.0)


# --- values out of range -----------------------------------------------------------

@case("NaN, ±Inf in ε, ctrl and parameters")
def non_finite_inputs_are_discarded(h: Harness):
    c = h.initialized()
    before = h.get_real(c)
    for value in (math.nan, math.inf, -math.inf):
        h.set_real(DISCARD, c, {"eps[1]": value}, says=("eps[1]", "is not finite"))
        h.set_real(DISCARD, c, {"eps[2]": 0.5, "eps[3]": value}, says=("eps[3]",))
        h.set_real(DISCARD, c, {"ctrl[1]": value}, says=("ctrl[1]", "is not finite"))
        h.set_real(DISCARD, c, {"ctrl[9]": 0.1, "ctrl[15]": value}, says=("ctrl[15]",))
    assert h.get_real(c) == before, "a discarded value is not taken, not even partly"
    h.step(c, 0.0)


@case("NaN, ±Inf in ε, ctrl and parameters")
def out_of_range_ctrl_is_clamped(h: Harness):
    """A control beyond its ctrlrange, however large, is taken and clamped
    as MuJoCo clamps d.ctrl: the step is the one at the range's end."""
    clamped = h.initialized()
    h.set_real(OK, clamped, {"ctrl[1]": 1e300, "ctrl[9]": -1e300, "ctrl[14]": 1e300})
    h.step(clamped, 0.0)
    at_limits = h.initialized()
    h.set_real(OK, at_limits, {"ctrl[1]": 22.0, "ctrl[9]": -0.2, "ctrl[14]": 0.2})
    h.step(at_limits, 0.0)
    states = h.fmu.names("theta") + h.fmu.names("nu")
    assert h.get_real(clamped, states) == h.get_real(at_limits, states)
    assert all(math.isfinite(x) for x in h.get_real(clamped))


@case("NaN, ±Inf in ε, ctrl and parameters")
def parameters_out_of_range_are_discarded(h: Harness):
    c = h.instantiate()
    for name, value, says in [("max_step", -1e-3, "must be non-negative"), ("tolerance", 0.0, "must be positive"),
                              ("tolerance", math.nan, "not finite"), ("theta[8]", math.inf, "not finite"),
                              ("nu[1]", -math.inf, "not finite")]:
        h.set_real(DISCARD, c, {name: value}, says=(name if name != "max_step" else "max_step", says))
    h.expect(DISCARD, "fmi2SetInteger", c, (C.c_uint * 1)(0), 1, (C.c_int * 1)(8), says=("method = 8",))
    h.expect(OK, "fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0)
    h.expect(OK, "fmi2EnterInitializationMode", c)
    h.expect(OK, "fmi2ExitInitializationMode", c)
    h.step(c, 0.0)


@case("NaN, ±Inf in ε, ctrl and parameters")
def setup_experiment_out_of_range(h: Harness):
    c = h.instantiate()
    for args, says in [((0, 0.0, math.nan, 0, 0.0), "startTime = NaN"),
                       ((0, 0.0, 0.0, 1, -1.0), "stopTime = -1 is before startTime = 0"),
                       ((0, 0.0, 0.0, 1, math.inf), "stopTime = inf is not finite"),
                       ((1, -1e-6, 0.0, 0, 0.0), "tolerance")]:
        h.expect(ERROR, "fmi2SetupExperiment", c, *args, says=(says,))
        h.expect(OK, "fmi2Reset", c)


@case("huge ε: the step is discarded")
def huge_eps_discards_the_step(h: Harness):
    """1e300 is a valid value, so fmi2SetReal takes it; the step that
    overflows is fmi2Discard (§4.2.2) and the outputs stay finite, at the
    last successful time (at most the requested end)."""
    c = h.initialized()
    h.step(c, 0.0)
    h.set_real(OK, c, {"eps[1]": 1e300, "eps[2]": -1e300, "eps[7]": 1e300})
    h.step(c, STEP, DISCARD, says=("stopped at t = ", "is not finite"))
    t = h.last_successful_time(c)
    assert STEP <= t <= 2 * STEP, f"LastSuccessfulTime = {t}"
    assert all(math.isfinite(x) for x in h.get_real(c))
    terminated = C.c_int()
    h.expect(OK, "fmi2GetBooleanStatus", c, TERMINATED, C.byref(terminated))
    h.step(c, t, ERROR, says=("stepFailed",))


@case("huge ε: the step is discarded")
def huge_initial_state(h: Harness):
    """A finite start so large that what is computed from it overflows: the
    overflowed outputs are refused (fmi2Error, the buffer untouched), the
    state itself stays readable, and the step is discarded."""
    c = h.instantiate()
    h.expect(OK, "fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0)
    h.expect(OK, "fmi2EnterInitializationMode", c)
    # The shoulder's two dofs (the servicer's 7 to 9 are its wheels).
    h.set_real(OK, c, {"nu[10]": 1e300, "nu[11]": -1e300})
    h.expect(OK, "fmi2ExitInitializationMode", c)
    saved = h.get_state(c)
    energy = (C.c_double * 1)(-1.0)
    h.expect(ERROR, "fmi2GetReal", c, (C.c_uint * 1)(h.fmu.vr["kinetic_energy"]), 1, energy,
             says=("kinetic_energy = inf is not finite",))
    assert energy[0] == -1.0, "nothing is written into the buffer"
    h.expect(OK, "fmi2SetFMUstate", c, saved)
    rate = (C.c_double * 1)(-1.0)
    h.expect(ERROR, "fmi2GetRealOutputDerivatives", c, (C.c_uint * 1)(h.fmu.vr["nu[10]"]), 1, (C.c_int * 1)(1), rate,
             says=("der(nu[10])", "not finite"))
    assert rate[0] == -1.0
    h.expect(OK, "fmi2SetFMUstate", c, saved)
    h.get_real(c, h.fmu.names("theta") + h.fmu.names("nu"))
    h.step(c, 0.0, DISCARD, says=("failed",))
    h.expect(OK, "fmi2Reset", c)


@case("zero, negative, non-finite or huge step")
def bad_step_sizes(h: Harness):
    """With max_step bounding the steps, 1e300 s would need 1e302 of them: refused up front."""
    c = h.initialized(start={"max_step": 0.01})
    saved = h.get_state(c)
    for step in (0.0, -STEP, -0.0, math.nan, math.inf, -math.inf):
        h.step(c, 0.0, ERROR, h=step, says=("communicationStepSize",))
        h.expect(OK, "fmi2SetFMUstate", c, saved)
    h.step(c, 0.0, ERROR, h=1e300, says=("internal steps", "a larger max_step or a shorter communication step"))
    h.expect(OK, "fmi2SetFMUstate", c, saved)
    h.step(c, 0.0)


@case("zero, negative, non-finite or huge step")
def tiny_max_step(h: Harness):
    """max_step = 1e-300 is positive, so it is taken; a step that would need
    1e298 internal steps is refused instead of hanging."""
    c = h.instantiate()
    h.set_real(OK, c, {"max_step": 1e-300})
    h.expect(OK, "fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0)
    h.expect(OK, "fmi2EnterInitializationMode", c)
    h.expect(OK, "fmi2ExitInitializationMode", c)
    h.step(c, 0.0, ERROR, says=("internal steps",))


@case("long communication steps")
def long_step_at_rest(h: Harness):
    """One step of 1010 s of a vehicle at rest (as FMPy's simulate_fmu with a
    huge stop time asks for): work asked for, done, not refused, in steps
    the error control lets grow; with max_step = 0.01 s it would need 101 000
    internal steps, more than one doStep may take, refused up front."""
    c = h.initialized()
    h.step(c, 0.0, OK, h=1010.0)
    bounded = h.initialized(start={"max_step": 0.01})
    h.step(bounded, 0.0, ERROR, h=1010.0, says=("1.01e5 internal steps", "a larger max_step"))
    assert h.get_real(c, ["nu[1]"]) == [0.0]


@case("long communication steps")
def error_control_step_limit(h: Harness):
    """A tumble at 300 rad/s with tolerance 1e-12 holds the error control's
    steps far below max_step: after 100 000 attempted steps it is discarded,
    with the reason and what lets it through."""
    c = h.instantiate()
    h.set_real(OK, c, {"tolerance": 1e-12, "max_step": 1e3})
    h.expect(OK, "fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0)
    h.expect(OK, "fmi2EnterInitializationMode", c)
    h.set_real(OK, c, {"nu[4]": 300.0, "nu[5]": -200.0, "nu[7]": 100.0})
    h.expect(OK, "fmi2ExitInitializationMode", c)
    h.step(c, 0.0, DISCARD, h=1e3, says=("100000 internal steps reached only", "too fast or stiff for tolerance 1e-12",
                                         "a looser tolerance, or shorter intervals"))
    assert 0.0 < h.last_successful_time(c) < 1e3


@case("model exchange out of sequence or with wrong arrays")
def model_exchange_misuse(h: Harness):
    """The model-exchange state machine (FMI 2.0 §3.2.3), the lengths of
    the state arrays, a NaN state (fmi2Discard: a host's integration blew
    up; the states stay), and functions of the other interface."""
    nx = len(h.fmu.names("theta")) + len(h.fmu.names("nu"))
    x, dx = (C.c_double * nx)(), (C.c_double * nx)()
    c = h.instantiate(kind=MODEL_EXCHANGE)
    h.expect(ERROR, "fmi2GetDerivatives", c, dx, nx, says=("may not be called in state instantiated",))
    h.expect(OK, "fmi2Reset", c)
    h.expect(OK, "fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0)
    h.expect(OK, "fmi2EnterInitializationMode", c)
    h.set_real(OK, c, {"nu[4]": 0.5})
    h.expect(OK, "fmi2ExitInitializationMode", c)
    in_event_mode = h.get_state(c)
    for name, args, says in [
        ("fmi2SetContinuousStates", (x, nx), "may not be called in state eventMode"),
        ("fmi2DoStep", (0.0, STEP, 1), "is a co-simulation function, but this instance was instantiated for model exchange"),
        ("fmi2CompletedIntegratorStep", (1, C.pointer(C.c_int()), C.pointer(C.c_int())),
         "may not be called in state eventMode"),
    ]:
        h.expect(ERROR, name, c, *args, says=(says,))
        h.expect(OK, "fmi2SetFMUstate", c, in_event_mode)
    h.expect(OK, "fmi2EnterContinuousTimeMode", c)
    in_continuous_time = h.get_state(c)
    h.expect(OK, "fmi2GetContinuousStates", c, x, nx)
    for name, n, says in [("fmi2GetContinuousStates", nx - 1, f"has {nx - 1} entries, but the FMU has {nx}"),
                          ("fmi2GetDerivatives", nx + 1, f"has {nx + 1} entries"),
                          ("fmi2GetNominalsOfContinuousStates", 0, f"has 0 entries, but the FMU has {nx}"),
                          ("fmi2GetEventIndicators", 1, "but the FMU has 0 event indicators"),
                          ("fmi2SetContinuousStates", nx, "x is NULL")]:
        h.expect(ERROR, name, c, None if name == "fmi2SetContinuousStates" else dx, n, says=(says,))
        h.expect(OK, "fmi2SetFMUstate", c, in_continuous_time)
    h.expect(ERROR, "fmi2SetTime", c, math.nan, says=("time = NaN is not finite",))
    h.expect(OK, "fmi2SetFMUstate", c, in_continuous_time)
    bad = (C.c_double * nx)(*x)
    bad[3] = math.nan
    h.expect(DISCARD, "fmi2SetContinuousStates", c, bad, nx, says=("x[3] = NaN is not finite",))
    after = (C.c_double * nx)()
    h.expect(OK, "fmi2GetContinuousStates", c, after, nx)
    assert list(after) == list(x), "a refused state changes nothing"
    h.expect(OK, "fmi2SetTime", c, 0.5)
    h.expect(OK, "fmi2GetDerivatives", c, dx, nx)
    assert all(math.isfinite(d) for d in dx)
    enter_event, terminate = C.c_int(7), C.c_int(7)
    h.expect(OK, "fmi2CompletedIntegratorStep", c, 1, C.byref(enter_event), C.byref(terminate))
    assert (enter_event.value, terminate.value) == (0, 0)
    cs = h.initialized()
    h.expect(ERROR, "fmi2SetTime", cs, 0.0,
             says=("is a model exchange function, but this instance was instantiated for co-simulation",))


@case("communication point that does not match")
def communication_point_mismatch(h: Harness):
    c = h.initialized()
    saved = h.get_state(c)
    h.step(c, 0.0)
    after_one = h.get_state(c)
    for time in (0.0, 0.5, -STEP, math.nan, math.inf, 2 * STEP):
        h.step(c, time, ERROR, says=("expected currentCommunicationPoint = 0.01",))
        h.expect(OK, "fmi2SetFMUstate", c, after_one)
    h.expect(OK, "fmi2SetFMUstate", c, saved)
    h.step(c, 0.0)


@case("communication point that does not match")
def step_past_stop_time(h: Harness):
    c = h.instantiate()
    h.expect(OK, "fmi2SetupExperiment", c, 0, 0.0, 0.0, 1, STEP)
    h.expect(OK, "fmi2EnterInitializationMode", c)
    h.expect(OK, "fmi2ExitInitializationMode", c)
    h.step(c, 0.0)
    h.step(c, STEP, ERROR, says=("passes stopTime",))


# --- instantiation -------------------------------------------------------------------

@case("GUID mismatch or wrong FMU type")
def guid_mismatch(h: Harness):
    h.refused_instantiation("does not match the FMU's resources", guid=b"{00000000-0000-0000-0000-000000000000}")
    h.refused_instantiation("does not match", guid=b"")
    h.refused_instantiation("does not match", guid=h.other.guid.encode())


@case("GUID mismatch or wrong FMU type")
def unknown_fmu_type(h: Harness):
    h.refused_instantiation("neither fmi2ModelExchange (0) nor fmi2CoSimulation (1)", kind=77)
    h.refused_instantiation("neither fmi2ModelExchange (0) nor fmi2CoSimulation (1)", kind=-1)


def with_resource(h: Harness, content: bytes | None, tmp: Path) -> bytes:
    """A resources directory holding `content` as model.json (none if None)."""
    resources = tmp / "resources"
    resources.mkdir(parents=True)
    if content is not None:
        (resources / "model.json").write_bytes(content)
    return (resources.as_uri() + "/").encode()


def scratch(name: str) -> Path:
    directory = Path(os.environ["MISUSE_SCRATCH"]) / name
    directory.mkdir(parents=True)
    return directory


@case("missing or corrupt resources")
def missing_resources(h: Harness):
    tmp = scratch("missing")
    h.refused_instantiation("cannot read the compiled model", uri=with_resource(h, None, tmp))
    h.refused_instantiation("cannot read", uri=(tmp / "nonexistent").as_uri().encode())
    (tmp / "dir" / "model.json").mkdir(parents=True)  # a directory where the file should be
    h.refused_instantiation("cannot read", uri=((tmp / "dir").as_uri() + "/").encode())


@case("missing or corrupt resources")
def corrupt_resources(h: Harness):
    original = (h.fmu.directory / "resources" / "model.json").read_bytes()
    document = json.loads(original)
    wrong_nv = json.loads(original)
    wrong_nv["model"]["nv"] = 10**15
    bad_parent = json.loads(original)
    bad_parent["model"]["links"][0]["parent"] = 5
    negative_mass = json.loads(original)
    negative_mass["model"]["links"][1]["mass"] = -1.0
    # Physically impossible links: the loader checks the physics, not only the numbers.
    asymmetric_inertia = json.loads(original)
    asymmetric_inertia["model"]["links"][3]["rotational_inertia"][1] = 0.5
    skewed_rotation = json.loads(original)
    skewed_rotation["model"]["links"][3]["x_tree"]["rot"][1] = 0.3
    zero_axis = json.loads(original)
    zero_axis["model"]["links"][3]["axis"] = [0.0, 0.0, 0.0]
    document["format"] = 99
    variants = [
        (b"", "is not a nudyn FMU resource"),
        (original[: len(original) // 2], "is not a nudyn FMU resource"),
        (b"\x00\xff" * 100, "is not a nudyn FMU resource"),
        (b"[]", "is not a nudyn FMU resource"),
        (json.dumps(document).encode(), "resource format 99"),
        (json.dumps(wrong_nv).encode(), "nv is 1000000000000000"),
        (json.dumps(bad_parent).encode(), "link 0 has parent 5"),
        (json.dumps(negative_mass).encode(), "mass of link 1 is -1: must be finite and non-negative"),
        (json.dumps(asymmetric_inertia).encode(), "inertia of link 3 is not symmetric"),
        (json.dumps(skewed_rotation).encode(), "x_tree of link 3 is not a rotation"),
        (json.dumps(zero_axis).encode(), "the axis of link 3 has length 0"),
        (original.replace(b"{", b"{ ", 1), "does not match the FMU's resources"),
    ]
    for k, (content, says) in enumerate(variants):
        h.refused_instantiation(says, uri=with_resource(h, content, scratch(f"corrupt{k}")))


@case("odd resource URIs")
def odd_resource_uris(h: Harness):
    for uri, says in [(b"", "is not a file: URI"), (b"http://example.invalid/r/", "is not a file: URI"),
                      (b"/just/a/path", "is not a file: URI"), (b"file://server/share/", "names host 'server'"),
                      (b"file:relative/dir", "no absolute path"), (b"file:///tmp/%zz/", "malformed percent-encoding"),
                      (b"file:///tmp/%", "malformed percent-encoding"), (b"file:///tmp/%C3%28/", "cannot read"),
                      (b"file:" + b"/x" * 5000, "cannot read"), (b"file:///\xff\xfe/", "cannot read")]:
        h.refused_instantiation(says, uri=uri)


@case("odd resource URIs")
def equivalent_resource_uris_work(h: Harness):
    """The forms importers write for the same directory are all accepted."""
    tmp = scratch("odd dir%")
    resources = tmp / "resources"
    resources.mkdir()
    (resources / "model.json").write_bytes((h.fmu.directory / "resources" / "model.json").read_bytes())
    path = str(resources)
    encoded = path.replace("%", "%25").replace(" ", "%20")
    for uri in (f"file://{encoded}/", f"file://{encoded}", f"file:{encoded}", f"file://localhost{encoded}/",
                f"FILE://{encoded}/"):
        c = h.instantiate(uri=uri.encode())
        assert c, f"{uri} refused:\n{h.log_text()}"
        h.calls.append(("fmi2Instantiate", OK))
        h.free(c)


# --- FMU state faults ----------------------------------------------------------------

def fnv1a(data: bytes) -> int:
    value = 0xCBF29CE484222325
    for byte in data:
        value = ((value ^ byte) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return value


def run_and_compare(h: Harness, c, reference: list[float], steps_from: float):
    """Two more steps from `steps_from` must give `reference` bit for bit."""
    h.step(c, steps_from)
    h.step(c, steps_from + STEP)
    assert h.get_real(c) == reference, "the instance's future changed"


def state_fault_case(name: str, blobs, says: str):
    """Each bad blob is refused with fmi2Error; the instance keeps its values
    and, once a saved state is set again, its future: two more steps are
    bit-identical to an instance that never saw the blobs."""
    def run(h: Harness):
        start = {"nu[7]": 0.3, "nu[4]": -0.2, "eps[8]": 0.5}
        reference = h.initialized(start=start)
        for t in (0.0, STEP, 2 * STEP):
            h.step(reference, t)
        expected = h.get_real(reference)
        c = h.initialized(start=start)
        h.step(c, 0.0)
        saved = h.get_state(c)
        good = h.serialize(c, saved)
        before = h.get_real(c)
        for blob in blobs(h, good):
            h.deserialize(ERROR, c, blob, says=(says,))
            assert h.get_real(c) == before
            h.expect(OK, "fmi2SetFMUstate", c, saved)
        run_and_compare(h, c, expected, STEP)
    run.__name__ = f"serialized_state_{name}"
    case("corrupt, truncated or foreign FMU states")(run)


def with_checksum(blob: bytes) -> bytes:
    return blob[:-8] + struct.pack("<Q", fnv1a(blob[:-8]))


def header_length(h: Harness) -> int:
    return 8 + 4 + 4 + len(h.fmu.guid) + 4 + 4 + 4  # magic, version, GUID, nq, nv, nu


state_fault_case("truncated_at_every_length", lambda h, good: [good[:n] for n in range(len(good))], "truncated")
state_fault_case("extended", lambda h, good: [good + b"\0", good + good], "expected")
state_fault_case("every_byte_flipped", lambda h, good: [good[:k] + bytes([good[k] ^ 0x5A]) + good[k + 1:]
                                                          for k in range(len(good))], "serialized")
state_fault_case("of_another_fmu", lambda h, good: [other_fmu_blob(h)], "belongs to the FMU with GUID")
state_fault_case("of_another_format_version", lambda h, good: [good[:8] + struct.pack("<I", 1) + good[12:]],
                 "format version 1")
state_fault_case("not_a_state", lambda h, good: [b"", b"PK\x03\x04", b"nudynFMS", os.urandom(len(good))],
                 "serialized")
state_fault_case("forged_with_nan", lambda h, good: [with_checksum(good[:-16] + struct.pack("<d", math.nan) + good[-8:])],
                 "must be finite")
state_fault_case("forged_state_machine_state",
                 lambda h, good: [with_checksum(good[:header_length(h)] + bytes([k]) + good[header_length(h) + 1:])
                                  for k in (6, 9, 255)], "state machine state")
state_fault_case("forged_model_exchange_state",
                 lambda h, good: [with_checksum(good[:header_length(h)] + bytes([k]) + good[header_length(h) + 1:])
                                  for k in (7, 8)], "of the other interface")


def other_fmu_blob(h: Harness) -> bytes:
    other = h.initialized(h.other)
    blob = h.serialize(other, h.get_state(other))
    return blob


@case("FMU state pointers")
def state_pointer_misuse(h: Harness):
    c, d = h.initialized(), h.initialized()
    saved = h.get_state(c)
    h.expect(ERROR, "fmi2SetFMUstate", d, saved, says=("not a live FMU state of this instance",))
    h.expect(OK, "fmi2Reset", d)
    copy = C.c_void_p(saved.value)
    h.expect(OK, "fmi2FreeFMUstate", c, C.byref(copy))
    assert copy.value is None, "fmi2FreeFMUstate sets the pointer to NULL"
    h.expect(ERROR, "fmi2FreeFMUstate", c, C.byref(saved), says=("not a live FMU state",))
    h.expect(OK, "fmi2Reset", c)
    h.expect(ERROR, "fmi2SetFMUstate", c, saved, says=("not a live FMU state",))
    h.expect(OK, "fmi2Reset", c)
    junk = C.create_string_buffer(64)
    h.expect(ERROR, "fmi2SerializedFMUstateSize", c, C.cast(junk, C.c_void_p), C.pointer(C.c_size_t()),
             says=("not a live FMU state",))
    h.expect(OK, "fmi2Reset", c)
    overwritten = C.c_void_p(C.addressof(junk))
    h.expect(ERROR, "fmi2GetFMUstate", c, C.byref(overwritten), says=("not a live FMU state",))
    h.expect(OK, "fmi2Reset", c)
    h.get_state(c)  # left for fmi2FreeInstance to free


# --- running -------------------------------------------------------------------------

def run_case(name: str, fmu_dir: str, other_dir: str) -> dict:
    group, function = CASES[name]
    h = Harness(FmuPackage(Path(fmu_dir)), FmuPackage(Path(other_dir)))
    function(h)
    h.finish()
    return {"case": name, "group": group, "calls": h.calls}


def status_name(function: str, status: int) -> str:
    """fmi2Error for an FMI 2.0 function, fmi3Error for an FMI 3.0 one."""
    name = STATUS_NAMES[status]
    return name.replace("fmi2", "fmi3") if function.startswith("fmi3") else name


def table(results: list[dict]) -> str:
    """The misuse table of docs/fmi.md: per group, the cases, the calls they made, and
    the statuses of those the FMU refused (fmi2FreeInstance, which returns
    nothing, counts as fmi2OK)."""
    rows: dict[str, dict] = {}
    for result in results:
        row = rows.setdefault(result["group"], {"cases": 0, "calls": 0, "refusals": Counter()})
        row["cases"] += 1
        row["calls"] += len(result["calls"])
        row["refusals"].update(status_name(f, s) for f, s in result["calls"] if s != OK)

    def statuses(counter: Counter) -> str:
        return ", ".join(f"{count} {status}" for status, count in sorted(counter.items())) or "none"

    lines = ["| misuse | cases | calls | refused with | crashes or hangs |", "|---|---|---|---|---|"]
    for name, row in rows.items():
        lines.append(f"| {name} | {row['cases']} | {row['calls']} | {statuses(row['refusals'])} | 0 |")
    total = sum((row["refusals"] for row in rows.values()), Counter())
    cases, calls = sum(r["cases"] for r in rows.values()), sum(r["calls"] for r in rows.values())
    lines.append(f"| **all** | {cases} | {calls} | {statuses(total)} | **0** |")
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    if argv[:1] == ["run"]:
        _, name, fmu_dir, other_dir = argv
        print(json.dumps(run_case(name, fmu_dir, other_dir)))
        return 0
    print(__doc__)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
