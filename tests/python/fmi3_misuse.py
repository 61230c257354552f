"""Misuse of an FMI 3.0 FMU's binary through ctypes: every function that
takes a count, called with the count the arrays have (n) and with 0, n−1,
n+1, 2³¹, 2⁴⁰ and 2⁶³, on the plant and the controller. A wrong count is
refused with fmi3Error and a message naming the function, before
anything is read past the arrays or allocated by the count (FMI 3.0
§2.2.6: nValues is the arrays' total size); the instance then goes back
to a saved FMU state (the controller, which has none, is reset). A count
2⁴⁰ used to abort the host ("memory allocation of 8796093022208 bytes
failed").

Run like fmu_misuse.py, one case per process: `python fmi3_misuse.py run
CASE PLANT_DIR CONTROLLER_DIR` (unzipped FMI 3.0 FMUs); its results go
into the misuse table of docs/fmi.md with the FMI 2.0 cases."""

from __future__ import annotations

import ctypes as C
import json
import math
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

from fmu_misuse import ERROR, OK, CaseFailed

HUGE = (2**31, 2**40, 2**63)
GROUP = "FMI 3.0: counts 0, n−1, n+1, 2³¹, 2⁴⁰, 2⁶³"
LOGGER = C.CFUNCTYPE(None, C.c_void_p, C.c_int, C.c_char_p, C.c_char_p)
inst = C.c_void_p
size = C.c_size_t


def wrong_counts(n: int) -> list[int]:
    """0, n−1, n+1 and the huge counts, without n itself."""
    return sorted({k for k in (0, n - 1, n + 1, *HUGE) if k >= 0 and k != n})


class Fmu3:
    """An unzipped FMI 3.0 FMU: its token, binary and variables (name → (value reference, type, size))."""

    def __init__(self, directory: Path):
        self.directory = Path(directory)
        root = ET.parse(self.directory / "modelDescription.xml").getroot()
        self.token = root.get("instantiationToken")
        identifier = root.find("CoSimulation").get("modelIdentifier")
        self.library = self.directory / "binaries" / "x86_64-linux" / f"{identifier}.so"
        self.model_exchange = root.find("ModelExchange") is not None
        self.variables = {}
        for variable in root.find("ModelVariables"):
            dimensions = [int(d.get("start")) for d in variable.iterfind("Dimension")]
            self.variables[variable.get("name")] = (int(variable.get("valueReference")), variable.tag,
                                                    math.prod(dimensions))
        self.categories = [c.get("name").encode() for c in root.iterfind("LogCategories/Category")]

    def vr(self, name: str) -> int:
        return self.variables[name][0]

    def len(self, name: str) -> int:
        return self.variables[name][2]


class Harness3:
    """The FMI 3.0 counterpart of fmu_misuse.Harness: `expect` checks each
    call's status and message and records it for the table."""

    def __init__(self, fmu: Fmu3):
        self.fmu = fmu
        self.lib = C.CDLL(str(fmu.library))
        for name in ("fmi3InstantiateCoSimulation", "fmi3InstantiateModelExchange"):
            getattr(self.lib, name).restype = inst
        self.messages: list[str] = []
        self._logger = LOGGER(lambda _env, _status, _category, message: self.messages.append(message.decode()))
        self.calls: list[tuple[str, int]] = []
        self.live: list = []

    def expect(self, status: int, name: str, c, *args, says: tuple[str, ...] = ()):
        before = len(self.messages)
        found = getattr(self.lib, name)(inst(c), *args)
        self.calls.append((name, found))
        new = "\n".join(self.messages[before:])
        if found != status:
            raise CaseFailed(f"{name}{args} returned {found}, expected {status}; log:\n{new}")
        for fragment in (name, *says) if status != OK else says:
            if fragment not in new:
                raise CaseFailed(f"{name}{args}: expected {fragment!r} in the log, got:\n{new}")

    def instantiate(self, model_exchange=False, n_required=0):
        resources = str(self.fmu.directory / "resources").encode() + b"/"
        if model_exchange:
            c = self.lib.fmi3InstantiateModelExchange(b"misuse", self.fmu.token.encode(), resources, False, True,
                                                      None, self._logger)
        else:
            c = self.lib.fmi3InstantiateCoSimulation(b"misuse", self.fmu.token.encode(), resources, False, True,
                                                     False, False, None, size(n_required), None, self._logger, None)
        self.calls.append(("fmi3Instantiate" + ("ModelExchange" if model_exchange else "CoSimulation"),
                           OK if c else -1))
        if not c:
            raise CaseFailed("instantiation failed:\n" + "\n".join(self.messages))
        self.live.append(c)
        return c

    def initialized(self, model_exchange=False):
        c = self.instantiate(model_exchange)
        self.expect(OK, "fmi3EnterInitializationMode", c, C.c_bool(False), C.c_double(0), C.c_double(0),
                    C.c_bool(False), C.c_double(0))
        self.expect(OK, "fmi3ExitInitializationMode", c)
        return c

    def saved(self, c):
        """How the instance goes back to where it is now: its FMU state, or
        (the controller) a reset and the same modes entered again."""
        if "method" in self.fmu.variables:
            state = C.c_void_p()
            self.expect(OK, "fmi3GetFMUState", c, C.byref(state))
            return lambda: self.expect(OK, "fmi3SetFMUState", c, state)

        def again():
            self.expect(OK, "fmi3Reset", c)
            self.expect(OK, "fmi3EnterInitializationMode", c, C.c_bool(False), C.c_double(0), C.c_double(0),
                        C.c_bool(False), C.c_double(0))
            self.expect(OK, "fmi3ExitInitializationMode", c)
        return again

    def refuse_counts(self, c, name: str, make_args, n: int, says=(), right=OK):
        """`name` with every wrong count in place of n: fmi3Error, then back;
        with n itself: `right`."""
        back = self.saved(c)
        for count in wrong_counts(n):
            self.expect(ERROR, name, c, *make_args(count), says=says)
            back()
        self.expect(right, name, c, *make_args(n))
        if right != OK:
            back()

    def finish(self):
        for c in self.live:
            self.lib.fmi3FreeInstance(inst(c))
            self.calls.append(("fmi3FreeInstance", OK))


def array(ctype, values):
    return (ctype * len(values))(*values)


CASES: dict[str, tuple[str, callable]] = {}


def case(function):
    CASES[function.__name__] = (GROUP, function)
    return function


# Each getter and setter of a type with variables: (function, element type,
# what the plant reads or sets, what the controller does, in initialization mode).
VALUE_FUNCTIONS = [
    ("fmi3GetFloat64", C.c_double, "nu", "eps", False),
    ("fmi3SetFloat64", C.c_double, "eps", "nu", False),
    ("fmi3GetInt64", C.c_int64, "method", None, False),
    ("fmi3SetInt64", C.c_int64, "method", None, True),
    ("fmi3GetBoolean", C.c_bool, "energy_projection", None, False),
    ("fmi3SetBoolean", C.c_bool, "energy_projection", None, True),
]


def values_case(function, ctype, plant_variable, controller_variable, in_initialization, controller):
    def run(plant: Harness3, ctrl: Harness3):
        h = ctrl if controller else plant
        variable = controller_variable if controller else plant_variable
        c = h.instantiate()
        h.expect(OK, "fmi3EnterInitializationMode", c, C.c_bool(False), C.c_double(0), C.c_double(0),
                 C.c_bool(False), C.c_double(0))
        if not in_initialization:
            h.expect(OK, "fmi3ExitInitializationMode", c)
        n = h.fmu.len(variable)
        start = {"method": [3], "energy_projection": [False]}.get(variable, [0.0] * n)
        vrs = array(C.c_uint32, [h.fmu.vr(variable)] * 2)  # room for n+1 value references
        values = array(ctype, start + start[:1])  # room for n+1 values
        h.refuse_counts(c, function, lambda k: (vrs, size(1), values, size(k)), n, says=("nValue",))
        h.refuse_counts(c, function, lambda k: (vrs, size(k), values, size(n)), 1, says=("nValue",))
    run.__name__ = f"{function}_counts_{'controller' if controller else 'plant'}"
    case(run)


for _spec in VALUE_FUNCTIONS:
    values_case(*_spec, controller=False)
    if _spec[3]:
        values_case(*_spec, controller=True)


@case
def fmi3GetOutputDerivatives_counts(plant: Harness3, _ctrl):
    c = plant.initialized()
    n = plant.fmu.len("theta")
    vrs, orders = array(C.c_uint32, [plant.fmu.vr("theta")] * 2), array(C.c_int32, [1, 1])
    values = (C.c_double * (n + 1))()
    plant.refuse_counts(c, "fmi3GetOutputDerivatives", lambda k: (vrs, size(1), orders, values, size(k)), n,
                        says=("nValue",))
    plant.refuse_counts(c, "fmi3GetOutputDerivatives", lambda k: (vrs, size(k), orders, values, size(n)), 1,
                        says=("nValue",))


# The types nudyn has no variables of: any value reference is refused (none asked: OK), whatever the counts.
NO_VARIABLES = ["fmi3GetFloat32", "fmi3GetInt8", "fmi3GetUInt8", "fmi3GetInt16", "fmi3GetUInt16", "fmi3GetInt32",
                "fmi3GetUInt32", "fmi3GetUInt64", "fmi3GetString", "fmi3SetFloat32", "fmi3SetInt8", "fmi3SetUInt8",
                "fmi3SetInt16", "fmi3SetUInt16", "fmi3SetInt32", "fmi3SetUInt32", "fmi3SetUInt64", "fmi3SetString"]
CLOCK_FUNCTIONS = {"fmi3GetClock": 1, "fmi3SetClock": 1, "fmi3GetIntervalDecimal": 2, "fmi3GetIntervalFraction": 3,
                   "fmi3GetShiftDecimal": 1, "fmi3GetShiftFraction": 2, "fmi3SetIntervalDecimal": 1,
                   "fmi3SetIntervalFraction": 2, "fmi3SetShiftDecimal": 1, "fmi3SetShiftFraction": 2}


@case
def no_variables_of_the_type_counts(plant: Harness3, ctrl: Harness3):
    for h in (plant, ctrl):
        c = h.initialized()
        back = h.saved(c)
        vrs = array(C.c_uint32, [h.fmu.vr("nu")] * 2)
        buffer = (C.c_uint64 * 64)()  # room for whatever one value is, of any type
        calls = [(name, lambda k: (vrs, size(k), buffer, size(k))) for name in NO_VARIABLES]
        calls += [(name, lambda k: (vrs, size(k), None, buffer, size(k))) for name in ("fmi3GetBinary",
                                                                                        "fmi3SetBinary")]
        calls += [(name, lambda k, arrays=arrays: (vrs, size(k), *[buffer] * arrays))
                  for name, arrays in CLOCK_FUNCTIONS.items()]
        for name, make_args in calls:
            for count in wrong_counts(0):
                h.expect(ERROR, name, c, *make_args(count), says=("'nu'",))
                back()
            h.expect(OK, name, c, *make_args(0))


@case
def fmi3SetDebugLogging_counts(plant: Harness3, ctrl: Harness3):
    for h in (plant, ctrl):
        c = h.instantiate()
        names = h.fmu.categories
        categories = array(C.c_char_p, names + names[:1])
        for count in wrong_counts(len(names)):
            status = OK if count < len(names) else ERROR
            h.expect(status, "fmi3SetDebugLogging", c, C.c_bool(True), size(count), categories,
                     says=("nCategories",) if status == ERROR else ())
            if status == ERROR:
                h.expect(OK, "fmi3Reset", c)
        h.expect(OK, "fmi3SetDebugLogging", c, C.c_bool(True), size(len(names)), categories)


@case
def fmi3GetVariableDependencies_counts(plant: Harness3, _ctrl):
    c = plant.initialized()
    der_nu = plant.fmu.vr("der(nu)")
    n = C.c_size_t()
    plant.expect(OK, "fmi3GetNumberOfVariableDependencies", c, C.c_uint32(der_nu), C.byref(n))
    n = n.value
    arrays = [(C.c_size_t * (n + 1))(), (C.c_uint32 * (n + 1))(), (C.c_size_t * (n + 1))(), (C.c_int * (n + 1))()]
    plant.refuse_counts(c, "fmi3GetVariableDependencies", lambda k: (C.c_uint32(der_nu), *arrays, size(k)), n,
                        says=(f"the value references name {n} values",))


@case
def serialized_state_counts(plant: Harness3, ctrl: Harness3):
    c = plant.initialized()
    state = C.c_void_p()
    plant.expect(OK, "fmi3GetFMUState", c, C.byref(state))
    n = C.c_size_t()
    plant.expect(OK, "fmi3SerializedFMUStateSize", c, state, C.byref(n))
    n = n.value
    blob = C.create_string_buffer(n + 1)
    plant.refuse_counts(c, "fmi3SerializeFMUState", lambda k: (state, blob, size(k)), n, says=(f"expected {n}",))
    copy = C.c_void_p()
    plant.refuse_counts(c, "fmi3DeserializeFMUState", lambda k: (blob, size(k), C.byref(copy)), n,
                        says=("serialized",))
    d = ctrl.initialized()
    for count in wrong_counts(n):
        ctrl.expect(ERROR, "fmi3DeserializeFMUState", d, blob, size(count), C.byref(copy), says=("no FMU states",))
        ctrl.expect(OK, "fmi3Reset", d)


@case
def derivative_counts(plant: Harness3, ctrl: Harness3):
    """Value reference and value counts of the partial derivatives that do
    not match: the plant, which provides them, refuses each before reading
    its arrays; the controller, which provides none, before reading any
    argument."""
    for h, says in ((plant, ()), (ctrl, ("directional and adjoint derivatives are not provided",))):
        c = h.initialized()
        back = h.saved(c)
        vrs, seed = array(C.c_uint32, [h.fmu.vr("nu")] * 2), (C.c_double * 64)()
        for name in ("fmi3GetDirectionalDerivative", "fmi3GetAdjointDerivative"):
            for position in range(4):
                for count in (0, 1, 2, *HUGE):
                    counts = [1, 1, 1, 1]
                    counts[position] = count
                    h.expect(ERROR, name, c, vrs, size(counts[0]), vrs, size(counts[1]), seed, size(counts[2]), seed,
                             size(counts[3]), says=says)
                    back()


@case
def model_exchange_counts(plant: Harness3, _ctrl):
    c = plant.instantiate(model_exchange=True)
    plant.expect(OK, "fmi3EnterInitializationMode", c, C.c_bool(False), C.c_double(0), C.c_double(0),
                 C.c_bool(False), C.c_double(0))
    plant.expect(OK, "fmi3ExitInitializationMode", c)
    plant.expect(OK, "fmi3EnterContinuousTimeMode", c)
    nx = C.c_size_t()
    plant.expect(OK, "fmi3GetNumberOfContinuousStates", c, C.byref(nx))
    nx = nx.value
    x = (C.c_double * (nx + 1))()
    plant.expect(OK, "fmi3GetContinuousStates", c, x, size(nx))
    for name in ("fmi3GetContinuousStates", "fmi3SetContinuousStates", "fmi3GetContinuousStateDerivatives",
                 "fmi3GetNominalsOfContinuousStates"):
        plant.refuse_counts(c, name, lambda k: (x, size(k)), nx, says=(f"the FMU has {nx}",))
    plant.refuse_counts(c, "fmi3GetEventIndicators", lambda k: (x, size(k)), 0, says=("but the FMU has 0 event indicators",))


@case
def required_intermediate_variables_counts(plant: Harness3, ctrl: Harness3):
    """nRequiredIntermediateVariables is never read (no intermediate
    updates): any count makes an instance."""
    for h in (plant, ctrl):
        for count in (0, 1, *HUGE):
            h.instantiate(n_required=count)


def run_case(name: str, plant_dir: str, controller_dir: str) -> dict:
    group, function = CASES[name]
    plant, ctrl = Harness3(Fmu3(Path(plant_dir))), Harness3(Fmu3(Path(controller_dir)))
    function(plant, ctrl)
    plant.finish()
    ctrl.finish()
    return {"case": name, "group": group, "calls": plant.calls + ctrl.calls}


if __name__ == "__main__":
    if sys.argv[1:2] != ["run"]:
        print(__doc__)
        sys.exit(2)
    print(json.dumps(run_case(*sys.argv[2:])))
