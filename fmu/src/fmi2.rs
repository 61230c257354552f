//! The FMI 2.0 functions, co-simulation and model exchange: each exported
//! `fmi2*` function takes its C arguments apart and runs through the shared
//! entry path of [`crate::layer`] (pointer, state and interface checks,
//! panic guard, statuses and logging) into the component.
//!
//! Statuses follow FMI 2.0 §2.1.3 as [`crate::layer`] describes: fmi2Error
//! moves the instance to the `error` state (§4.2.4); fmi2Discard refuses a
//! value out of its range in fmi2SetXXX (footnote 3), a failed fmi2DoStep
//! (§4.2.2), and a status fmi2GetXXXStatus cannot give.

// The patterns below are fmi-sys's C constants, named as in fmi2Functions.h.
#![allow(non_upper_case_globals)]

use std::ffi::c_char;

use fmi_sys::fmi2::*;
use nudyn_contract::fmi3::Fmi3Variables;

use crate::calls;
use crate::component::CallError;
use crate::layer::{
    self, FmiError, Instance, Logger, Version, initialized, out_of_range_discards, slice, slice_mut, string,
};
use crate::load;
use crate::state::{Function, Interface, Phase};
use crate::uri::resource_directory;

/// The entry path of every fmi2 function that takes an instance.
///
/// # Safety
/// FMI 2.0 calling conventions (the instance is not used concurrently).
unsafe fn enter(
    c: fmi2Component,
    function: Function,
    body: impl FnOnce(&mut Instance) -> Result<(), FmiError>,
) -> fmi2Status {
    // SAFETY: by the contract above.
    unsafe { layer::enter(c, function, function.name(), body) }.code()
}

#[unsafe(no_mangle)]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    c"default".as_ptr()
}

#[unsafe(no_mangle)]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    c"2.0".as_ptr()
}

/// # Safety
/// FMI 2.0 calling conventions: pointers as the standard describes them.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2Instantiate(
    instance_name: fmi2String,
    fmu_type: fmi2Type,
    fmu_guid: fmi2String,
    fmu_resource_location: fmi2String,
    functions: *const fmi2CallbackFunctions,
    _visible: fmi2Boolean,
    logging_on: fmi2Boolean,
) -> fmi2Component {
    // SAFETY: a non-NULL `functions` points to the importer's callbacks.
    let Some(functions) = (unsafe { functions.as_ref() }) else {
        return std::ptr::null_mut();
    };
    // SAFETY: NUL-terminated by the standard when non-NULL.
    let name = unsafe { string(instance_name, "instanceName") }.unwrap_or_else(|_| "(NULL)".into());
    let logger = Logger::fmi2(functions, &name, logging_on != 0);
    layer::instantiate(logger, "fmi2Instantiate", || {
        let interface = match fmu_type {
            fmi2Type_fmi2ModelExchange => Interface::ModelExchange,
            fmi2Type_fmi2CoSimulation => Interface::CoSimulation,
            other => return Err(FmiError::UnknownType(other)),
        };
        if instance_name.is_null() {
            return Err(FmiError::Null("instanceName"));
        }
        // SAFETY: NUL-terminated by the standard when non-NULL.
        let guid = unsafe { string(fmu_guid, "fmuGUID") }?;
        // SAFETY: as above.
        let location = unsafe { string(fmu_resource_location, "fmuResourceLocation") }?;
        let directory = resource_directory(&location).map_err(load::LoadError::from)?;
        let (component, _) = load::load(&directory, &guid)?;
        if interface == Interface::ModelExchange && component.continuous_state_count().is_none() {
            return Err(FmiError::NoModelExchange);
        }
        Ok((Version::Fmi2, interface, component, Fmi3Variables::default()))
    })
}

/// # Safety
/// FMI 2.0 calling conventions. A NULL, freed or foreign `c` is ignored.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2FreeInstance(c: fmi2Component) {
    // SAFETY: every state allows fmi2FreeInstance (§4.2.4); by the FMI 2.0 calling conventions.
    unsafe { layer::free(c) }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: fmi2Component,
    logging_on: fmi2Boolean,
    n_categories: usize,
    categories: *const fmi2String,
) -> fmi2Status {
    unsafe {
        enter(c, Function::SetDebugLogging, |instance| {
            layer::set_debug_logging(instance, logging_on != 0, n_categories, categories)
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetupExperiment(
    c: fmi2Component,
    tolerance_defined: fmi2Boolean,
    tolerance: fmi2Real,
    start_time: fmi2Real,
    stop_time_defined: fmi2Boolean,
    stop_time: fmi2Real,
) -> fmi2Status {
    unsafe {
        enter(c, Function::SetupExperiment, |instance| {
            let tolerance = (tolerance_defined != 0).then_some(tolerance);
            let stop_time = (stop_time_defined != 0).then_some(stop_time);
            Ok(calls::setup_experiment(&mut *instance.component, tolerance, start_time, stop_time)?)
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2EnterInitializationMode(c: fmi2Component) -> fmi2Status {
    unsafe {
        enter(c, Function::EnterInitializationMode, |instance| {
            instance.phase = Phase::InitializationMode;
            Ok(())
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2ExitInitializationMode(c: fmi2Component) -> fmi2Status {
    unsafe { enter(c, Function::ExitInitializationMode, layer::exit_initialization_mode) }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2Terminate(c: fmi2Component) -> fmi2Status {
    unsafe {
        enter(c, Function::Terminate, |instance| {
            instance.phase = Phase::Terminated;
            Ok(())
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2Reset(c: fmi2Component) -> fmi2Status {
    unsafe { enter(c, Function::Reset, layer::reset) }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetReal(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Real,
) -> fmi2Status {
    unsafe {
        enter(c, Function::GetReal, |instance| {
            let vrs = slice(vr, nvr, "vr")?;
            let values = slice_mut(value, nvr, "value")?;
            instance.warning =
                calls::get_real(&mut *instance.component, vrs, values)?.map(|w| format!("fmi2GetReal: {w}"));
            Ok(())
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetReal(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Real,
) -> fmi2Status {
    unsafe {
        enter(c, Function::SetReal, |instance| {
            let (vrs, values) = (slice(vr, nvr, "vr")?, slice(value, nvr, "value")?);
            let initialized = initialized(instance.phase);
            calls::set_real(&mut *instance.component, vrs, values, initialized).map_err(out_of_range_discards)
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetInteger(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Integer,
) -> fmi2Status {
    unsafe {
        enter(c, Function::GetInteger, |instance| {
            let (vrs, values) = (slice(vr, nvr, "vr")?, slice_mut(value, nvr, "value")?);
            Ok(instance.component.get_integer(vrs, values)?)
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetInteger(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Integer,
) -> fmi2Status {
    unsafe {
        enter(c, Function::SetInteger, |instance| {
            let (vrs, values) = (slice(vr, nvr, "vr")?, slice(value, nvr, "value")?);
            let initialized = initialized(instance.phase);
            instance.component.set_integer(vrs, values, initialized).map_err(out_of_range_discards)
        })
    }
}

/// The FMU has no String variables: any value reference is unknown.
fn no_variables(vrs: &[fmi2ValueReference], kind: &'static str) -> Result<(), FmiError> {
    match vrs.first() {
        Some(&vr) => Err(CallError::UnknownValueReference { vr, kind }.into()),
        None => Ok(()),
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetBoolean(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Boolean,
) -> fmi2Status {
    unsafe {
        enter(c, Function::GetBoolean, |instance| {
            let (vrs, values) = (slice(vr, nvr, "vr")?, slice_mut(value, nvr, "value")?);
            let mut flags = vec![false; vrs.len()];
            instance.component.get_boolean(vrs, &mut flags)?;
            values.iter_mut().zip(flags).for_each(|(value, flag)| *value = fmi2Boolean::from(flag));
            Ok(())
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetBoolean(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Boolean,
) -> fmi2Status {
    unsafe {
        enter(c, Function::SetBoolean, |instance| {
            let (vrs, values) = (slice(vr, nvr, "vr")?, slice(value, nvr, "value")?);
            let flags: Vec<bool> = values.iter().map(|&v| v != 0).collect();
            Ok(instance.component.set_boolean(vrs, &flags, initialized(instance.phase))?)
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetString(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    _value: *mut fmi2String,
) -> fmi2Status {
    unsafe { enter(c, Function::GetString, |_| no_variables(slice(vr, nvr, "vr")?, "String")) }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetString(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    _value: *const fmi2String,
) -> fmi2Status {
    unsafe { enter(c, Function::SetString, |_| no_variables(slice(vr, nvr, "vr")?, "String")) }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetFMUstate(c: fmi2Component, state: *mut fmi2FMUstate) -> fmi2Status {
    unsafe { enter(c, Function::GetFmuState, |instance| layer::get_fmu_state(instance, state)) }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetFMUstate(c: fmi2Component, state: fmi2FMUstate) -> fmi2Status {
    unsafe { enter(c, Function::SetFmuState, |instance| layer::set_fmu_state(instance, state)) }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2FreeFMUstate(c: fmi2Component, state: *mut fmi2FMUstate) -> fmi2Status {
    unsafe { enter(c, Function::FreeFmuState, |instance| layer::free_fmu_state(instance, state)) }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: fmi2Component,
    state: fmi2FMUstate,
    size: *mut usize,
) -> fmi2Status {
    unsafe { enter(c, Function::SerializedFmuStateSize, |instance| layer::serialized_size(instance, state, size)) }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: fmi2Component,
    state: fmi2FMUstate,
    bytes: *mut fmi2Byte,
    size: usize,
) -> fmi2Status {
    unsafe {
        enter(c, Function::SerializeFmuState, |instance| layer::serialize(instance, state, bytes as *mut u8, size))
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: fmi2Component,
    bytes: *const fmi2Byte,
    size: usize,
    state: *mut fmi2FMUstate,
) -> fmi2Status {
    unsafe {
        enter(c, Function::DeSerializeFmuState, |instance| {
            layer::deserialize(instance, bytes as *const u8, size, state)
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
    c: fmi2Component,
    unknown: *const fmi2ValueReference,
    n_unknown: usize,
    known: *const fmi2ValueReference,
    n_known: usize,
    dv_known: *const fmi2Real,
    dv_unknown: *mut fmi2Real,
) -> fmi2Status {
    unsafe {
        enter(c, Function::GetDirectionalDerivative, |instance| {
            instance.component.partials()?;
            let (unknowns, knowns) = (slice(unknown, n_unknown, "vUnknown_ref")?, slice(known, n_known, "vKnown_ref")?);
            let seed = slice(dv_known, n_known, "dvKnown")?;
            let sensitivity = slice_mut(dv_unknown, n_unknown, "dvUnknown")?;
            let component = &mut *instance.component;
            let partial = calls::Partial::Directional;
            Ok(calls::partial_derivatives(component, partial, unknowns, knowns, ("dvKnown", seed), sensitivity)?)
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    order: *const fmi2Integer,
    value: *const fmi2Real,
) -> fmi2Status {
    unsafe {
        enter(c, Function::SetRealInputDerivatives, |instance| {
            let (vrs, orders, values) =
                (slice(vr, nvr, "vr")?, slice(order, nvr, "order")?, slice(value, nvr, "value")?);
            Ok(calls::set_input_derivatives(&mut *instance.component, vrs, orders, values)?)
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    order: *const fmi2Integer,
    value: *mut fmi2Real,
) -> fmi2Status {
    unsafe {
        enter(c, Function::GetRealOutputDerivatives, |instance| {
            let (vrs, orders) = (slice(vr, nvr, "vr")?, slice(order, nvr, "order")?);
            let values = slice_mut(value, nvr, "value")?;
            Ok(calls::get_output_derivatives(&mut *instance.component, vrs, orders, values)?)
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2DoStep(
    c: fmi2Component,
    current_communication_point: fmi2Real,
    communication_step_size: fmi2Real,
    _no_set_fmu_state_prior_to_current_point: fmi2Boolean,
) -> fmi2Status {
    unsafe {
        enter(c, Function::DoStep, |instance| {
            layer::do_step(instance, current_communication_point, communication_step_size, "fmi2DoStep")
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2CancelStep(c: fmi2Component) -> fmi2Status {
    // The state table refuses it in every state: no step is ever in progress.
    unsafe { enter(c, Function::CancelStep, |_| Ok(())) }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetStatus(c: fmi2Component, kind: fmi2StatusKind, value: *mut fmi2Status) -> fmi2Status {
    unsafe {
        enter(c, Function::GetStatus, |_| {
            let value = value.as_mut().ok_or(FmiError::Null("value"))?;
            match kind {
                // doStep is synchronous: its status is final when it returns.
                fmi2StatusKind_fmi2DoStepStatus => *value = fmi2Status_fmi2OK,
                _ => return Err(FmiError::StatusUnavailable(kind)),
            }
            Ok(())
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetRealStatus(c: fmi2Component, kind: fmi2StatusKind, value: *mut fmi2Real) -> fmi2Status {
    unsafe {
        enter(c, Function::GetRealStatus, |instance| {
            let value = value.as_mut().ok_or(FmiError::Null("value"))?;
            match kind {
                fmi2StatusKind_fmi2LastSuccessfulTime => *value = instance.component.time(),
                _ => return Err(FmiError::StatusUnavailable(kind)),
            }
            Ok(())
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetIntegerStatus(
    c: fmi2Component,
    kind: fmi2StatusKind,
    _value: *mut fmi2Integer,
) -> fmi2Status {
    unsafe { enter(c, Function::GetIntegerStatus, |_| Err(FmiError::StatusUnavailable(kind))) }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetBooleanStatus(
    c: fmi2Component,
    kind: fmi2StatusKind,
    value: *mut fmi2Boolean,
) -> fmi2Status {
    unsafe {
        enter(c, Function::GetBooleanStatus, |instance| {
            let value = value.as_mut().ok_or(FmiError::Null("value"))?;
            match kind {
                // After a non-finite state the plant cannot go on: tell the master to stop.
                fmi2StatusKind_fmi2Terminated => *value = fmi2Boolean::from(instance.component.failed_for_good()),
                _ => return Err(FmiError::StatusUnavailable(kind)),
            }
            Ok(())
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetStringStatus(
    c: fmi2Component,
    kind: fmi2StatusKind,
    _value: *mut fmi2String,
) -> fmi2Status {
    unsafe { enter(c, Function::GetStringStatus, |_| Err(FmiError::StatusUnavailable(kind))) }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2EnterEventMode(c: fmi2Component) -> fmi2Status {
    unsafe {
        enter(c, Function::EnterEventMode, |instance| {
            instance.phase = Phase::EventMode;
            Ok(())
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2NewDiscreteStates(c: fmi2Component, event_info: *mut fmi2EventInfo) -> fmi2Status {
    unsafe {
        enter(c, Function::NewDiscreteStates, |instance| {
            let event_info = event_info.as_mut().ok_or(FmiError::Null("fmi2eventInfo"))?;
            // The constraint mode the state gives holds until the next event;
            // no discrete states of the host's change, no time events. A mode
            // set anew may make the derivatives jump: the states are said to
            // have changed (their values stay), since that is what makes hosts
            // such as fmusim start their integrator afresh; carried across the
            // jump, CVODE's history missed the next switch (docs/fmi.md).
            let mode_set = instance.component.update_discrete_states()?;
            *event_info = fmi2EventInfo {
                newDiscreteStatesNeeded: fmi2False as fmi2Boolean,
                terminateSimulation: fmi2False as fmi2Boolean,
                nominalsOfContinuousStatesChanged: fmi2False as fmi2Boolean,
                valuesOfContinuousStatesChanged: fmi2Boolean::from(mode_set),
                nextEventTimeDefined: fmi2False as fmi2Boolean,
                nextEventTime: 0.0,
            };
            Ok(())
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2EnterContinuousTimeMode(c: fmi2Component) -> fmi2Status {
    unsafe {
        enter(c, Function::EnterContinuousTimeMode, |instance| {
            instance.phase = Phase::ContinuousTimeMode;
            Ok(())
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2CompletedIntegratorStep(
    c: fmi2Component,
    _no_set_fmu_state_prior_to_current_point: fmi2Boolean,
    enter_event_mode: *mut fmi2Boolean,
    terminate_simulation: *mut fmi2Boolean,
) -> fmi2Status {
    unsafe {
        enter(c, Function::CompletedIntegratorStep, |_| {
            let enter_event_mode = enter_event_mode.as_mut().ok_or(FmiError::Null("enterEventMode"))?;
            let terminate_simulation = terminate_simulation.as_mut().ok_or(FmiError::Null("terminateSimulation"))?;
            // No step events.
            *enter_event_mode = fmi2False as fmi2Boolean;
            *terminate_simulation = fmi2False as fmi2Boolean;
            Ok(())
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetTime(c: fmi2Component, time: fmi2Real) -> fmi2Status {
    unsafe { enter(c, Function::SetTime, |instance| Ok(calls::set_time(&mut *instance.component, time)?)) }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetContinuousStates(c: fmi2Component, x: *const fmi2Real, nx: usize) -> fmi2Status {
    unsafe {
        enter(c, Function::SetContinuousStates, |instance| {
            let x = slice(x, nx, "x")?;
            calls::set_continuous_states(&mut *instance.component, x).map_err(out_of_range_discards)
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetDerivatives(c: fmi2Component, derivatives: *mut fmi2Real, nx: usize) -> fmi2Status {
    unsafe {
        enter(c, Function::GetDerivatives, |instance| {
            let derivatives = slice_mut(derivatives, nx, "derivatives")?;
            Ok(calls::get_derivatives(&mut *instance.component, derivatives)?)
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetEventIndicators(
    c: fmi2Component,
    event_indicators: *mut fmi2Real,
    ni: usize,
) -> fmi2Status {
    unsafe {
        enter(c, Function::GetEventIndicators, |instance| {
            let expected = instance.component.event_indicator_count();
            calls::event_indicator_count(&*instance.component, ni, expected)?;
            let indicators = slice_mut(event_indicators, ni, "eventIndicators")?;
            Ok(calls::get_event_indicators(&mut *instance.component, indicators)?)
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetContinuousStates(c: fmi2Component, x: *mut fmi2Real, nx: usize) -> fmi2Status {
    unsafe {
        enter(c, Function::GetContinuousStates, |instance| {
            let x = slice_mut(x, nx, "x")?;
            Ok(calls::get_continuous_states(&*instance.component, x)?)
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetNominalsOfContinuousStates(
    c: fmi2Component,
    x_nominal: *mut fmi2Real,
    nx: usize,
) -> fmi2Status {
    unsafe {
        enter(c, Function::GetNominalsOfContinuousStates, |instance| {
            let nominals = slice_mut(x_nominal, nx, "x_nominal")?;
            Ok(calls::get_nominals(&*instance.component, nominals)?)
        })
    }
}

// The C types used above, named so that a signature mismatch with fmi-sys's
// function-pointer types is a compile error.
const _: [fmi2NewDiscreteStatesTYPE; 1] = [Some(fmi2NewDiscreteStates)];
const _: [fmi2CompletedIntegratorStepTYPE; 1] = [Some(fmi2CompletedIntegratorStep)];
const _: [fmi2GetDerivativesTYPE; 1] = [Some(fmi2GetDerivatives)];
const _: [fmi2GetNominalsOfContinuousStatesTYPE; 1] = [Some(fmi2GetNominalsOfContinuousStates)];
const _: [fmi2DoStepTYPE; 1] = [Some(fmi2DoStep)];
const _: [fmi2InstantiateTYPE; 1] = [Some(fmi2Instantiate)];
const _: [fmi2GetRealTYPE; 1] = [Some(fmi2GetReal)];
const _: [fmi2SetDebugLoggingTYPE; 1] = [Some(fmi2SetDebugLogging)];
const _: [fmi2SerializeFMUstateTYPE; 1] = [Some(fmi2SerializeFMUstate)];
const _: [fmi2DeSerializeFMUstateTYPE; 1] = [Some(fmi2DeSerializeFMUstate)];
const _: [fmi2GetRealOutputDerivativesTYPE; 1] = [Some(fmi2GetRealOutputDerivatives)];

#[cfg(test)]
mod tests {
    use std::ffi::{CStr, CString};

    use super::*;

    /// The fixed_rig example's resources in a fresh directory: (resource URI, GUID).
    fn resources(test: &str) -> (CString, CString) {
        let (dir, guid, _) = crate::test_resources::write("fixed_rig", test);
        (crate::test_resources::uri(&dir), guid)
    }

    fn instantiate(uri: &CString, guid: &CStr) -> fmi2Component {
        crate::test_resources::instantiate_fmi2(fmi2Type_fmi2CoSimulation, uri, guid)
    }

    fn phase(c: fmi2Component) -> Phase {
        unsafe { (*(c as *const Instance)).phase }
    }

    #[test]
    fn a_panic_becomes_an_error_status_and_reset_recovers() {
        let (uri, guid) = resources("panic");
        let c = instantiate(&uri, &guid);
        assert!(!c.is_null());
        let status = unsafe { enter(c, Function::SetReal, |_| panic!("deliberate")) };
        assert_eq!(status, fmi2Status_fmi2Error);
        assert_eq!(phase(c), Phase::Error);
        assert_eq!(unsafe { fmi2Reset(c) }, fmi2Status_fmi2OK);
        assert_eq!(phase(c), Phase::Instantiated);
        unsafe { fmi2FreeInstance(c) };
    }

    #[test]
    fn a_wrong_guid_or_location_fails_instantiation() {
        let (uri, _) = resources("guid");
        assert!(instantiate(&uri, c"{00000000-0000-0000-0000-000000000000}").is_null());
        let (_, guid) = resources("location");
        assert!(instantiate(&CString::new("file:///nonexistent/").unwrap(), &guid).is_null());
    }

    #[test]
    fn an_error_enters_the_error_state_and_a_saved_state_leaves_it() {
        let (uri, guid) = resources("error");
        let c = instantiate(&uri, &guid);
        let mut value = [0.0; 2];
        unsafe {
            assert_eq!(fmi2GetReal(std::ptr::null_mut(), [1, 2].as_ptr(), 2, value.as_mut_ptr()), fmi2Status_fmi2Error);
            assert_eq!(fmi2DoStep(c, 0.0, 0.01, 1), fmi2Status_fmi2Error, "doStep before initialization");
            assert_eq!(phase(c), Phase::Error);
            assert_eq!(fmi2Reset(c), fmi2Status_fmi2OK);
            assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), fmi2Status_fmi2OK);
            assert_eq!(fmi2EnterInitializationMode(c), fmi2Status_fmi2OK);
            assert_eq!(fmi2GetReal(c, std::ptr::null(), 0, std::ptr::null_mut()), fmi2Status_fmi2OK, "empty arrays");
            assert_eq!(fmi2ExitInitializationMode(c), fmi2Status_fmi2OK);
            let mut saved: fmi2FMUstate = std::ptr::null_mut();
            assert_eq!(fmi2GetFMUstate(c, &mut saved), fmi2Status_fmi2OK);
            assert_eq!(fmi2GetReal(c, std::ptr::null(), 2, value.as_mut_ptr()), fmi2Status_fmi2Error);
            assert_eq!(phase(c), Phase::Error);
            assert_eq!(fmi2DoStep(c, 0.0, 0.01, 1), fmi2Status_fmi2Error, "no step in the error state");
            assert_eq!(fmi2SetFMUstate(c, saved), fmi2Status_fmi2OK);
            assert_eq!(phase(c), Phase::StepComplete);
            assert_eq!(fmi2DoStep(c, 0.0, 0.01, 1), fmi2Status_fmi2OK);
            let eps = [f64::NAN];
            assert_eq!(fmi2SetReal(c, [3].as_ptr(), 1, eps.as_ptr()), fmi2Status_fmi2Discard, "out of range");
            assert_eq!(phase(c), Phase::StepComplete);
            assert_eq!(fmi2FreeFMUstate(c, &mut saved), fmi2Status_fmi2OK);
            assert!(saved.is_null());
            fmi2FreeInstance(c);
        }
    }

    /// θ̇ (the integrated velocity) of a state from which a doStep may
    /// follow must be the one its ν gives; in initialization mode, where
    /// θ̇ is formed from ν on leaving it, it is not read.
    #[test]
    fn a_state_whose_velocities_disagree_is_refused_where_a_step_follows() {
        let (uri, guid) = resources("velocities");
        let c = instantiate(&uri, &guid);
        let qvel_of = |state: fmi2FMUstate| unsafe { &mut (*(state as *mut crate::snapshot::Snapshot)).state.run.qvel };
        unsafe {
            assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), fmi2Status_fmi2OK);
            assert_eq!(fmi2EnterInitializationMode(c), fmi2Status_fmi2OK);
            let mut at_initialization: fmi2FMUstate = std::ptr::null_mut();
            assert_eq!(fmi2GetFMUstate(c, &mut at_initialization), fmi2Status_fmi2OK);
            qvel_of(at_initialization)[0] = 1e270;
            assert_eq!(fmi2ExitInitializationMode(c), fmi2Status_fmi2OK);
            assert_eq!(fmi2DoStep(c, 0.0, 0.01, 1), fmi2Status_fmi2OK);
            let mut stepping: fmi2FMUstate = std::ptr::null_mut();
            assert_eq!(fmi2GetFMUstate(c, &mut stepping), fmi2Status_fmi2OK);
            assert_eq!(fmi2SetFMUstate(c, stepping), fmi2Status_fmi2OK, "its own state");
            qvel_of(stepping)[0] += 1e-3;
            assert_eq!(fmi2SetFMUstate(c, stepping), fmi2Status_fmi2Error);
            assert_eq!(fmi2SetFMUstate(c, at_initialization), fmi2Status_fmi2OK);
            assert_eq!(phase(c), Phase::InitializationMode);
            assert_eq!(fmi2ExitInitializationMode(c), fmi2Status_fmi2OK);
            assert_eq!(fmi2DoStep(c, 0.0, 0.01, 1), fmi2Status_fmi2OK, "θ̇ formed again from ν");
            for mut state in [at_initialization, stepping] {
                assert_eq!(fmi2FreeFMUstate(c, &mut state), fmi2Status_fmi2OK);
            }
            fmi2FreeInstance(c);
        }
    }

    #[test]
    fn pointers_that_were_not_handed_out_are_refused_unread() {
        let (uri, guid) = resources("pointers");
        let (a, b) = (instantiate(&uri, &guid), instantiate(&uri, &guid));
        unsafe {
            let mut state: fmi2FMUstate = std::ptr::null_mut();
            assert_eq!(fmi2GetFMUstate(a, &mut state), fmi2Status_fmi2OK);
            assert_eq!(fmi2SetFMUstate(b, state), fmi2Status_fmi2Error, "a state of another instance");
            let mut copy = state;
            assert_eq!(fmi2FreeFMUstate(a, &mut copy), fmi2Status_fmi2OK);
            assert_eq!(fmi2Reset(a), fmi2Status_fmi2OK);
            assert_eq!(fmi2FreeFMUstate(a, &mut state), fmi2Status_fmi2Error, "freed twice");
            let mut garbage = 0x1234usize as fmi2FMUstate;
            assert_eq!(fmi2FreeFMUstate(a, &mut garbage), fmi2Status_fmi2Error);
            // A state left unfreed goes with its instance.
            let mut left: fmi2FMUstate = std::ptr::null_mut();
            assert_eq!(fmi2Reset(a), fmi2Status_fmi2OK);
            assert_eq!(fmi2GetFMUstate(a, &mut left), fmi2Status_fmi2OK);
            fmi2FreeInstance(a);
            fmi2FreeInstance(a);
            assert_eq!(fmi2Reset(a), fmi2Status_fmi2Error, "a freed instance");
            assert_eq!(fmi2Reset(0x1000usize as fmi2Component), fmi2Status_fmi2Error, "never an instance");
            assert_eq!(fmi2Reset(b), fmi2Status_fmi2OK, "the other instance is unaffected");
            fmi2FreeInstance(b);
        }
    }
}
