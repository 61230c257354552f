//! The argument checks every component shares, between the FMI layer's
//! pointer and state checks and the component's own methods: value
//! references, when a variable may be set and to what (from the contract's
//! [`Kind`](nudyn_contract::variable::Kind)), what the capability flags
//! allow, experiment and communication-step arguments.
//!
//! Every function checks all its arguments before the component changes
//! anything, so a refused call leaves the instance as it was.

use nudyn_contract::variable::{Causality, Kind, Range};

use crate::component::{CallError, Component, StepError, StepReport, Variable};

/// Relative tolerance on currentCommunicationPoint against the instance's
/// time: masters compute communication points in their own way (FMPy: start + n·h).
const TIME_TOLERANCE: f64 = 1e-9;

fn real_variable(component: &dyn Component, vr: u32) -> Result<Variable, CallError> {
    component.real_variable(vr).ok_or(CallError::UnknownValueReference { vr, kind: "Real" })
}

fn real_kind(component: &dyn Component, vr: u32) -> Result<Kind, CallError> {
    component.real_kind(vr).ok_or(CallError::UnknownValueReference { vr, kind: "Real" })
}

/// fmi2SetReal. `initialized`: after fmi2ExitInitializationMode. NaN and
/// ±Inf, and finite values outside a variable's range, are out of range.
pub fn set_real(
    component: &mut dyn Component,
    vrs: &[u32],
    values: &[f64],
    initialized: bool,
) -> Result<(), CallError> {
    for (&vr, &value) in vrs.iter().zip(values) {
        let kind = real_kind(component, vr)?;
        let name = || real_variable(component, vr).map(|variable| variable.name);
        if let Some(when) = kind.refuses_set(initialized) {
            return Err(CallError::NotSettable { name: name()?, vr, when });
        }
        if !value.is_finite() {
            return Err(CallError::NonFinite { name: name()?, value });
        }
        if !kind.accepts(value) {
            let must = if kind.range == Range::Positive { "positive" } else { "non-negative" };
            return Err(CallError::OutOfRange { name: name()?, value, must });
        }
    }
    component.set_reals(vrs, values);
    Ok(())
}

/// fmi2GetReal. Every value is computed and checked before any is written:
/// a value that overflowed (½|ν|² of a huge ν) is refused, never handed
/// out, and the importer's buffer is left as it was. Returns the warning
/// the call completes with, if any.
pub fn get_real(component: &mut dyn Component, vrs: &[u32], values: &mut [f64]) -> Result<Option<String>, CallError> {
    for &vr in vrs {
        real_kind(component, vr)?;
    }
    let warning = component.prepare_reals(vrs)?;
    // Checked before any is written: a refused call leaves the host's buffer as it was.
    if let Some((vr, value)) = vrs.iter().map(|&vr| (vr, component.real_value(vr))).find(|(_, v)| !v.is_finite()) {
        return Err(CallError::NonFiniteOutput { name: real_variable(component, vr)?.name, value });
    }
    for (value, &vr) in values.iter_mut().zip(vrs) {
        *value = component.real_value(vr);
    }
    Ok(warning)
}

/// Refuses a derivative of an order other than 1, the only one served.
fn first_order(name: &str, order: i32) -> Result<(), CallError> {
    if order == 1 { Ok(()) } else { Err(CallError::DerivativeOrder { name: name.to_string(), order }) }
}

/// fmi2SetRealInputDerivatives: dε/dt of inputs, with canInterpolateInputs.
pub fn set_input_derivatives(
    component: &mut dyn Component,
    vrs: &[u32],
    orders: &[i32],
    values: &[f64],
) -> Result<(), CallError> {
    let served = component.capabilities().can_interpolate_inputs;
    for ((&vr, &order), &value) in vrs.iter().zip(orders).zip(values) {
        let Variable { name, kind } = real_variable(component, vr)?;
        if !served || kind.causality != Causality::Input {
            return Err(CallError::NoDerivative { name, vr, what: "input" });
        }
        first_order(&name, order)?;
        if !value.is_finite() {
            return Err(CallError::NonFinite { name: format!("der({name})"), value });
        }
    }
    if vrs.is_empty() {
        return Ok(());
    }
    component.set_input_derivatives(vrs, values)
}

/// fmi2GetRealOutputDerivatives: the time derivatives of the state outputs
/// (those whose start the master may choose: θ and ν), with
/// maxOutputDerivativeOrder ≥ 1. Checked like fmi2GetReal's values.
pub fn get_output_derivatives(
    component: &mut dyn Component,
    vrs: &[u32],
    orders: &[i32],
    values: &mut [f64],
) -> Result<(), CallError> {
    let served = component.capabilities().max_output_derivative_order >= 1;
    for (&vr, &order) in vrs.iter().zip(orders) {
        let Variable { name, kind } = real_variable(component, vr)?;
        if !served || kind.causality != Causality::Output || !kind.exact_start {
            return Err(CallError::NoDerivative { name, vr, what: "output" });
        }
        first_order(&name, order)?;
    }
    if vrs.is_empty() {
        return Ok(());
    }
    component.prepare_output_derivatives()?;
    let derivatives = vrs.iter().map(|&vr| (vr, component.output_derivative(vr)));
    if let Some((vr, value)) = derivatives.clone().find(|(_, v)| !v.is_finite()) {
        let name = format!("der({})", real_variable(component, vr)?.name);
        return Err(CallError::NonFiniteOutput { name, value });
    }
    for (value, (_, derivative)) in values.iter_mut().zip(derivatives) {
        *value = derivative;
    }
    Ok(())
}

/// Refuses the FMU-state functions of a component that does not declare canGetAndSetFMUstate.
pub fn fmu_states(component: &dyn Component) -> Result<(), CallError> {
    if component.capabilities().can_get_and_set_fmu_state { Ok(()) } else { Err(CallError::NoFmuState) }
}

/// fmi2SetupExperiment: refuses arguments no run can use (a non-finite
/// start, a tolerance that is not positive, a stop time before the start).
pub fn setup_experiment(
    component: &mut dyn Component,
    tolerance: Option<f64>,
    start_time: f64,
    stop_time: Option<f64>,
) -> Result<(), CallError> {
    if !start_time.is_finite() {
        return Err(CallError::NonFinite { name: "startTime".into(), value: start_time });
    }
    if let Some(tolerance) = tolerance.filter(|t| !(t.is_finite() && *t > 0.0)) {
        return Err(CallError::OutOfRange { name: "tolerance".into(), value: tolerance, must: "positive" });
    }
    if let Some(stop) = stop_time.filter(|s| !s.is_finite()) {
        return Err(CallError::NonFinite { name: "stopTime".into(), value: stop });
    }
    if let Some(stop) = stop_time.filter(|&s| s < start_time) {
        return Err(CallError::StopBeforeStart { start_time, stop_time: stop });
    }
    component.setup_experiment(tolerance, start_time, stop_time);
    Ok(())
}

/// What fmi2DoStep returns after its checks: a refused call, or the step's own outcome.
pub enum Stepped {
    /// The arguments were refused; nothing happened.
    Refused(CallError),
    /// The step ran and stopped inside the interval (fmi2Discard).
    Failed(StepError),
}

/// fmi2DoStep: refuses a communication point other than the instance's
/// time, a step that is not positive and finite, one the component cannot
/// take, or one past the stop time; then steps.
pub fn do_step(component: &mut dyn Component, time: f64, step: f64) -> Result<Option<StepReport>, Stepped> {
    let now = component.time();
    // No tolerance compares a non-finite communication point with the time.
    if !time.is_finite() || (time - now).abs() > TIME_TOLERANCE * now.abs().max(1.0) {
        return Err(Stepped::Refused(CallError::CommunicationPoint { expected: now, found: time }));
    }
    component.check_step_size(step).map_err(Stepped::Refused)?;
    if !(step.is_finite() && step > 0.0) {
        return Err(Stepped::Refused(CallError::StepSize(step)));
    }
    if let Some(stop_time) =
        component.stop_time().filter(|&stop| time + step > stop + TIME_TOLERANCE * stop.abs().max(1.0))
    {
        return Err(Stepped::Refused(CallError::PastStopTime { time, step, stop_time }));
    }
    component.do_step(time, step).map_err(Stepped::Failed)
}

/// The number of continuous states, checked against an array's length `n`.
pub fn state_count(component: &dyn Component, what: &'static str, n: usize) -> Result<usize, CallError> {
    let expected = component.continuous_state_count().ok_or(CallError::NotProvided("model exchange"))?;
    if n != expected {
        return Err(CallError::StateCount { what, found: n, expected });
    }
    Ok(expected)
}

/// fmi2SetContinuousStates: the count, and every value finite (a host
/// whose integration blew up gets fmi2Discard, and the states stay).
pub fn set_continuous_states(component: &mut dyn Component, x: &[f64]) -> Result<(), CallError> {
    state_count(component, "x", x.len())?;
    if let Some((index, &value)) = x.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(CallError::NonFiniteState { index, value });
    }
    component.set_continuous_states(x);
    Ok(())
}

/// fmi2GetContinuousStates.
pub fn get_continuous_states(component: &dyn Component, x: &mut [f64]) -> Result<(), CallError> {
    state_count(component, "x", x.len())?;
    component.continuous_states(x);
    Ok(())
}

/// fmi2GetDerivatives: computed in full and checked finite before any is
/// written, so that a refusal leaves the host's buffer as it was.
pub fn get_derivatives(component: &mut dyn Component, dx: &mut [f64]) -> Result<(), CallError> {
    let n = state_count(component, "derivatives", dx.len())?;
    component.prepare_derivatives()?;
    if let Some((index, value)) = (0..n).map(|i| (i, component.derivative(i))).find(|(_, v)| !v.is_finite()) {
        return Err(CallError::NonFiniteOutput { name: format!("dx[{index}]/dt (0-based)"), value });
    }
    dx.iter_mut().enumerate().for_each(|(i, d)| *d = component.derivative(i));
    Ok(())
}

/// fmi2GetNominalsOfContinuousStates: 1 for every state (angles, unit
/// quaternions, positions in m and ν in √J are all of order one).
pub fn get_nominals(component: &dyn Component, nominals: &mut [f64]) -> Result<(), CallError> {
    state_count(component, "x_nominal", nominals.len())?;
    nominals.fill(1.0);
    Ok(())
}

/// The check of GetEventIndicators' count, before any slice is made of it:
/// model exchange, and `expected` indicators (FMI 3.0 declares none).
pub fn event_indicator_count(component: &dyn Component, found: usize, expected: usize) -> Result<(), CallError> {
    component.continuous_state_count().ok_or(CallError::NotProvided("model exchange"))?;
    if found != expected {
        return Err(CallError::EventIndicators { found, expected });
    }
    Ok(())
}

/// fmi2GetEventIndicators, its count checked.
pub fn get_event_indicators(component: &mut dyn Component, indicators: &mut [f64]) -> Result<(), CallError> {
    component.event_indicators(indicators)
}

/// fmi2SetTime: a finite time.
pub fn set_time(component: &mut dyn Component, time: f64) -> Result<(), CallError> {
    component.continuous_state_count().ok_or(CallError::NotProvided("model exchange"))?;
    if !time.is_finite() {
        return Err(CallError::NonFinite { name: "time".into(), value: time });
    }
    component.set_time(time);
    Ok(())
}

/// Which partial derivative a call asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Partial {
    /// J · seed (fmi2GetDirectionalDerivative, fmi3GetDirectionalDerivative).
    Directional,
    /// Jᵀ · seed (fmi3GetAdjointDerivative).
    Adjoint,
}

/// Partial derivatives of `unknowns` with respect to `knowns` (FMI 2.0
/// value references), once the seed (`seed_name` in messages) is finite.
pub fn partial_derivatives(
    component: &mut dyn Component,
    partial: Partial,
    unknowns: &[u32],
    knowns: &[u32],
    (seed_name, seed): (&str, &[f64]),
    sensitivity: &mut [f64],
) -> Result<(), CallError> {
    if let Some((i, &value)) = seed.iter().enumerate().find(|(_, value)| !value.is_finite()) {
        return Err(CallError::NonFinite { name: format!("{seed_name}[{i}]"), value });
    }
    match partial {
        Partial::Directional => component.directional_derivative(unknowns, knowns, seed, sensitivity),
        Partial::Adjoint => component.adjoint_derivative(unknowns, knowns, seed, sensitivity),
    }
}
