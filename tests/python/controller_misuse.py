"""Misuse of a controller FMU's binary through ctypes, as a C importer calls
it: the FMI layer's checks (call sequence, NULL arguments, value references,
statuses, logging) hold for the controller as for the plant
(fmu_misuse.py), and the controller's own refusals are clear. A controller
has no FMU states (canGetAndSetFMUstate="false"), so an instance leaves
the error state by fmi2Reset here.

Run as `python controller_misuse.py CONTROLLER_DIR PLANT_DIR` (unzipped
FMUs) in a process of its own, so that a crash is seen as a signal; prints
the number of calls checked."""

from __future__ import annotations

import ctypes as C
import json
import math
import sys
from pathlib import Path

from fmu_misuse import (DISCARD, DO_STEP_STATUS, ERROR, LAST_SUCCESSFUL_TIME, OK, PLAIN_ARGUMENTS, STEP, WARNING,
                        CaseFailed, Harness)
from nudyn_driver.package import FmuPackage  # noqa: E402  (on the path fmu_misuse sets)


def initialized(h: Harness, start: dict | None = None):
    c = h.initialized(start=start)
    return c


def recover(h: Harness, c) -> None:
    """fmi2Reset, then initialization again."""
    h.expect(OK, "fmi2Reset", c)
    h.expect(OK, "fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0)
    h.expect(OK, "fmi2EnterInitializationMode", c)
    h.expect(OK, "fmi2ExitInitializationMode", c)


def direct_feedthrough(h: Harness) -> None:
    """ε follows the inputs at once, before and after steps; default c2 = 0, so ε = −c1 ν."""
    c = initialized(h)
    nu = {"nu[4]": 2.0, "nu[9]": -1.0}
    h.set_real(OK, c, nu)
    eps = h.get_real(c, ["eps[4]", "eps[9]", "eps[1]", "c1[4]"])
    if eps != [-2.0 * eps[3], 1.0 * eps[3], 0.0, eps[3]]:
        raise CaseFailed(f"eps = {eps}, expected -c1 nu")
    h.step(c, 0.0)
    h.set_real(OK, c, {"c1[4]": 1.5})  # tunable between steps
    if h.get_real(c, ["eps[4]"]) != [-3.0]:
        raise CaseFailed("a tunable gain set between steps did not act")
    h.step(c, STEP)
    h.expect(OK, "fmi2Terminate", c)


def zero_quaternion_input(h: Harness) -> None:
    """θ with the bus's quaternion all zeros (what a master that starts its
    connections at 0 hands over first) is read as the identity, as MuJoCo
    reads it, with a warning; the same read at the identity is silent."""
    c = initialized(h, start={"c2[1]": 3.0, "c2[5]": 2.0, "nu[4]": 0.5})
    outputs = ["eps[4]", "eps[5]", "eps[8]", "potential"]
    h.set_real(OK, c, {f"theta[{k}]": 0.0 for k in range(4, 8)})
    since = len(h.messages)
    zero = h.get_real(c, outputs, status=WARNING)
    if "theta[4] to theta[7] (joint 'bus_free') is a zero quaternion, read as the identity" not in h.log_text(since):
        raise CaseFailed(f"no warning for a zero quaternion: {h.log_text(since)}")
    h.set_real(OK, c, {"theta[4]": 1.0})
    if h.get_real(c, outputs) != zero:
        raise CaseFailed("a zero quaternion was not read as the identity")
    h.expect(OK, "fmi2Terminate", c)


def refusals(h: Harness) -> None:
    c = initialized(h)
    one = (C.c_double * 1)()
    for vr in (0, 99999, len(h.fmu.reals) + 1):
        h.expect(ERROR, "fmi2GetReal", c, (C.c_uint * 1)(vr), 1, one, says=(f"unknown value reference {vr}",))
        recover(h, c)
    h.expect(ERROR, "fmi2GetReal", c, None, 2, one, says=("vr is NULL",))
    recover(h, c)
    h.expect(ERROR, "fmi2SetReal", c, (C.c_uint * 1)(h.fmu.vr["nu[1]"]), 1, None, says=("value is NULL",))
    recover(h, c)
    for name in ("eps[1]", "potential", "target_error[2]"):
        h.set_real(ERROR, c, {name: 1.0}, says=(name, "calculated output"))
        recover(h, c)
    # Out of range: fmi2Discard, the value is not taken and the instance goes on.
    before = h.get_real(c, ["nu[2]", "c1[2]", "c2[1]"])
    h.set_real(DISCARD, c, {"nu[2]": math.nan}, says=("nu[2] = NaN is not finite",))
    h.set_real(DISCARD, c, {"theta[1]": math.inf}, says=("theta[1] = inf is not finite",))
    h.set_real(DISCARD, c, {"c1[2]": -1.0}, says=("c1[2] = -1 must be non-negative",))
    h.set_real(DISCARD, c, {"c2[1]": -0.5}, says=("c2[1] = -0.5 must be non-negative",))
    if h.get_real(c, ["nu[2]", "c1[2]", "c2[1]"]) != before:
        raise CaseFailed("a refused value was taken")
    h.step(c, 0.0)
    # No Integer or Boolean variables, no derivatives, no FMU states.
    h.expect(ERROR, "fmi2GetInteger", c, (C.c_uint * 1)(0), 1, (C.c_int * 1)(), says=("unknown value reference 0",))
    recover(h, c)
    h.expect(ERROR, "fmi2SetBoolean", c, (C.c_uint * 1)(0), 1, (C.c_int * 1)(), says=("unknown value reference 0",))
    recover(h, c)
    eps1 = (C.c_uint * 1)(h.fmu.vr["eps[1]"])
    h.expect(ERROR, "fmi2GetRealOutputDerivatives", c, eps1, 1, (C.c_int * 1)(1), one, says=("eps[1]", "no output derivative"))
    recover(h, c)
    nu1 = (C.c_uint * 1)(h.fmu.vr["nu[1]"])
    h.expect(ERROR, "fmi2SetRealInputDerivatives", c, nu1, 1, (C.c_int * 1)(1), one, says=("nu[1]", "no input derivative"))
    recover(h, c)
    state = C.c_void_p()
    h.expect(ERROR, "fmi2GetFMUstate", c, C.byref(state), says=("no FMU states",))
    recover(h, c)
    h.expect(ERROR, "fmi2DeSerializeFMUstate", c, b"nudynFMS", 8, C.byref(state), says=("no FMU states",))
    recover(h, c)
    # Steps: wrong communication point, bad sizes.
    h.step(c, 0.0)
    h.step(c, 0.5, ERROR, says=("expected currentCommunicationPoint = 0.01",))
    recover(h, c)
    for size in (0.0, -STEP, math.nan, math.inf):
        h.step(c, 0.0, ERROR, h=size, says=("communicationStepSize",))
        recover(h, c)
    h.step(c, math.nan, ERROR, says=("expected currentCommunicationPoint",))
    recover(h, c)
    value = C.c_double()
    h.expect(OK, "fmi2GetRealStatus", c, LAST_SUCCESSFUL_TIME, C.byref(value))


def sequence(h: Harness) -> None:
    c = h.instantiate()
    h.step(c, 0.0, ERROR, says=("fmi2DoStep may not be called in state instantiated",))
    h.expect(ERROR, "fmi2DoStep", c, 0.0, STEP, 1, says=("state error",))
    h.expect(OK, "fmi2Reset", c)
    h.expect(ERROR, "fmi2GetReal", c, None, 0, None, says=("state instantiated",))
    h.expect(OK, "fmi2Reset", c)
    h.expect(OK, "fmi2EnterInitializationMode", c)
    h.set_real(OK, c, {"target_quaternion[1]": 0.0, "target_quaternion[2]": 0.0,
                       "target_quaternion[3]": 0.0, "target_quaternion[4]": 0.0})
    h.expect(ERROR, "fmi2ExitInitializationMode", c, says=("target quaternion is zero",))
    h.expect(OK, "fmi2Reset", c)
    h.expect(OK, "fmi2SetupExperiment", c, 0, 0.0, 0.0, 1, STEP)
    h.expect(OK, "fmi2EnterInitializationMode", c)
    h.expect(OK, "fmi2ExitInitializationMode", c)
    h.step(c, 0.0)
    h.step(c, STEP, ERROR, says=("passes stopTime",))
    h.expect(ERROR, "fmi2Terminate", c, says=("state error",))
    h.expect(OK, "fmi2Reset", c)
    for name in sorted(PLAIN_ARGUMENTS):  # every function on a freed instance
        d = h.initialized()
        h.free(d)
        h.expect(ERROR, name, d, *PLAIN_ARGUMENTS[name])


def instantiation(h: Harness) -> None:
    h.refused_instantiation("does not match the FMU's resources", guid=b"{00000000-0000-0000-0000-000000000000}")
    h.refused_instantiation("does not match", guid=h.other.guid.encode())
    resource = h.fmu.directory / "resources" / "controller.json"
    original = resource.read_bytes()
    document = json.loads(original)
    document["law"]["objective"]["pose"]["link"] = 10**6
    try:
        for content, says in [(b"{", "is not a nudyn FMU resource"),
                              (json.dumps(document).encode(), "does not hold a consistent control law")]:
            resource.write_bytes(content)
            h.refused_instantiation(says)
    finally:
        resource.write_bytes(original)


def main(argv: list[str]) -> int:
    controller, plant = FmuPackage(Path(argv[0])), FmuPackage(Path(argv[1]))
    h = Harness(controller, plant)
    for case in (direct_feedthrough, zero_quaternion_input, refusals, sequence, instantiation):
        case(h)
    h.finish()
    print(json.dumps({"calls": len(h.calls), "refused": sum(1 for _, s in h.calls if s != OK)}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
