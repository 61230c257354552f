"""FMI 3.0 model exchange declares the switches of the constraint forces as
event indicators (issue 47): the local array `constraint_switch`, listed
under <EventIndicator> in <ModelStructure>. fmi3GetEventIndicators gives
what the FMI 2.0 FMU's fmi2GetEventIndicators gives at the same state (and
what reading the variable gives), and FMPy's model-exchange solver meets
them as state events on the docked servicer (welds, a connect, friction
loss, hinge, slide and ball limits). Before, FMI 3.0 declared none and
returned 0 from fmi3GetNumberOfEventIndicators."""

from __future__ import annotations

import os
import subprocess
from ctypes import c_double

import numpy as np
import pytest
from fmpy import extract, instantiate_fmu, read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

from conftest import ROOT

DOCKED = ROOT / "tests" / "fixtures" / "constraints" / "docked_servicer.xml"


@pytest.fixture(scope="module")
def fmus(cli, nudyn, fmu_library, tmp_path_factory):
    """The docked servicer's FMU in FMI 2.0, FMI 3.0 and FMI 3.0 with scalars."""
    directory = tmp_path_factory.mktemp("indicators")
    scalars = directory / "scalars" / "docked.fmu"
    scalars.parent.mkdir()
    subprocess.run([str(nudyn), "export", str(DOCKED), "-o", str(scalars), "--fmi-version", "3", "--fmi3-scalars"],
                   check=True, capture_output=True, env={**os.environ, "NUDYN_FMU_LIB": str(fmu_library)})
    return {
        "fmi2": cli.export(DOCKED, directory / "fmi2" / "docked.fmu"),
        "fmi3": cli.export(DOCKED, directory / "fmi3" / "docked.fmu", fmi_version=3),
        "scalars": scalars,
    }


def test_the_fmi3_description_lists_constraint_switch_as_event_indicators(fmus):
    fmi2, fmi3 = (read_model_description(str(fmus[v])) for v in ("fmi2", "fmi3"))
    assert fmi2.numberOfEventIndicators > 0
    # FMPy counts the elements of the variables <EventIndicator> names.
    assert fmi3.numberOfEventIndicators == fmi2.numberOfEventIndicators
    [indicator] = [unknown.variable for unknown in fmi3.eventIndicators]
    assert (indicator.name, indicator.causality, indicator.variability, indicator.type) == (
        "constraint_switch", "local", "continuous", "Float64")
    assert indicator.shape == (fmi2.numberOfEventIndicators,)
    # The same variable in FMI 2.0, element by element.
    names = [v.name for v in fmi2.modelVariables if v.name.startswith("constraint_switch[")]
    assert names == [f"constraint_switch[{k + 1}]" for k in range(fmi2.numberOfEventIndicators)]
    assert validate_fmu(str(fmus["fmi3"])) == []
    # With --fmi3-scalars, one <EventIndicator> per element, in order.
    scalars = read_model_description(str(fmus["scalars"]))
    assert [unknown.variable.name for unknown in scalars.eventIndicators] == names
    assert validate_fmu(str(fmus["scalars"])) == []


def start_values(nv: int) -> tuple[list[float], list[float]]:
    """ε and ν of a state off rest, so that rows are active and their forces move."""
    return [0.4 * np.sin(k + 1) for k in range(nv)], [0.05 * np.cos(k) for k in range(nv)]


class ModelExchange:
    """One model-exchange instance of an FMU through FMPy, at the state
    start_values gives, in continuous-time mode after the first event."""

    def __init__(self, fmu, directory):
        self.description = read_model_description(str(fmu))
        self.fmi3 = self.description.fmiVersion.startswith("3")
        self.instance = instantiate_fmu(extract(str(fmu), unzipdir=str(directory)), self.description,
                                        fmi_type="ModelExchange")
        self.vr = {v.name: v.valueReference for v in self.description.modelVariables}
        self.nz = self.description.numberOfEventIndicators
        if self.fmi3:
            self.nx = sum(int(np.prod(u.variable.shape)) for u in self.description.derivatives)
            nv = int(np.prod(next(v.shape for v in self.description.modelVariables if v.name == "nu")))
            eps, nu = start_values(nv)
            self.instance.enterInitializationMode(startTime=0.0)
            self.instance.setFloat64([self.vr["eps"], self.vr["nu"]], eps + nu)
            self.instance.exitInitializationMode()
            self.instance.updateDiscreteStates()
        else:
            self.nx = len(self.description.derivatives)
            nv = sum(name.startswith("nu[") for name in self.vr)
            eps, nu = start_values(nv)
            vrs = [self.vr[f"eps[{k + 1}]"] for k in range(nv)] + [self.vr[f"nu[{k + 1}]"] for k in range(nv)]
            self.instance.setupExperiment(startTime=0.0)
            self.instance.enterInitializationMode()
            self.instance.setReal(vrs, eps + nu)
            self.instance.exitInitializationMode()
            self.instance.newDiscreteStates()
        self.instance.enterContinuousTimeMode()

    def indicators(self) -> np.ndarray:
        z = (c_double * self.nz)()
        self.instance.getEventIndicators(z, self.nz)
        return np.array(z)

    def states(self) -> np.ndarray:
        x = (c_double * self.nx)()
        self.instance.getContinuousStates(x, self.nx)
        return np.array(x)

    def derivatives(self) -> np.ndarray:
        dx = (c_double * self.nx)()
        if self.fmi3:
            self.instance.getContinuousStateDerivatives(dx, self.nx)
        else:
            self.instance.getDerivatives(dx, self.nx)
        return np.array(dx)

    def set_states(self, x):
        self.instance.setContinuousStates((c_double * self.nx)(*x), self.nx)

    def variable(self) -> np.ndarray:
        """constraint_switch read as a variable."""
        if self.fmi3:
            return np.array(self.instance.getFloat64([self.vr["constraint_switch"]], self.nz))
        return np.array(self.instance.getReal([self.vr[f"constraint_switch[{k + 1}]"] for k in range(self.nz)]))


def test_fmi3_event_indicators_are_fmi2s_at_the_same_state(fmus, tmp_path):
    fmi2 = ModelExchange(fmus["fmi2"], tmp_path / "fmi2")
    fmi3 = ModelExchange(fmus["fmi3"], tmp_path / "fmi3")
    assert fmi3.instance.getNumberOfEventIndicators() == fmi2.nz
    np.testing.assert_array_equal(fmi3.states(), fmi2.states())
    x = fmi2.states()
    # At the event's state, then a step of Euler along the motion with the mode held.
    for h in (0.0, 0.02, 0.05):
        moved = x + h * fmi2.derivatives() if h else x
        fmi2.set_states(moved)
        fmi3.set_states(moved)
        z2, z3 = fmi2.indicators(), fmi3.indicators()
        assert np.all(np.isfinite(z2)) and np.any(z2 != 1.0), z2
        np.testing.assert_array_equal(z3, z2)
        np.testing.assert_array_equal(fmi3.variable(), z3)
        np.testing.assert_array_equal(fmi2.variable(), z2)
        np.testing.assert_array_equal(fmi3.derivatives(), fmi2.derivatives())


def test_fmpy_model_exchange_meets_the_fmi3_event_indicators(fmus):
    """FMPy's model exchange of the FMI 3.0 FMU records state events and
    ends within its tolerance of the FMU's own co-simulation at 1e-11."""
    fmu = str(fmus["fmi3"])
    description = read_model_description(fmu)
    nv = int(np.prod([v for v in description.modelVariables if v.name == "nu"][0].shape))
    eps = {"eps": [0.3 * np.sin(k) for k in range(nv)]}
    outputs = ["theta", "nu"]
    reference = simulate_fmu(fmu, fmi_type="CoSimulation", stop_time=1, output_interval=0.05,
                             start_values={**eps, "tolerance": 1e-11}, output=outputs)

    def end_state(result):
        return np.concatenate([np.ravel(result[-1][name]) for name in outputs])

    end = end_state(reference)
    run = simulate_fmu(fmu, fmi_type="ModelExchange", stop_time=1, output_interval=0.05, start_values=eps,
                       relative_tolerance=1e-8, output=outputs, record_events=True)
    assert len(run) > 21, "FMPy recorded no state event"
    error = np.max(np.abs(end_state(run) - end) / (1 + np.abs(end)))
    assert error < 1e-4, error


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
def test_an_event_that_sets_the_mode_says_the_states_changed(fmus, cli, version, tmp_path):
    """At an event the FMU sets the constraint mode anew, and the derivatives
    may jump there: it reports valuesOfContinuousStatesChanged (the states
    read back unchanged), since hosts such as fmusim restart their
    integrator only on that flag (carried across the jump, CVODE missed the
    docked servicer's next switch and ended 8.4e-5 off at rtol 1e-8).
    A vehicle without constraints has no mode, and says nothing changed."""
    def flags_at_an_event(fmu, directory):
        me = ModelExchange(fmu, directory)
        before = me.states()
        me.instance.enterEventMode()
        if me.fmi3:
            _, _, nominals, values, _, _ = me.instance.updateDiscreteStates()
        else:
            _, _, nominals, values, _, _ = me.instance.newDiscreteStates()
        me.instance.enterContinuousTimeMode()
        np.testing.assert_array_equal(me.states(), before)
        return bool(nominals), bool(values)

    assert flags_at_an_event(fmus[version], tmp_path / "docked") == (False, True)
    free = cli.export(ROOT / "examples" / "bus_arm7.xml", tmp_path / "free" / "bus_arm7.fmu",
                      fmi_version=3 if version == "fmi3" else 2)
    assert flags_at_an_event(free, tmp_path / "bus_arm7") == (False, False)
