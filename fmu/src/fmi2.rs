//! The generic FMI 2.0 layer, co-simulation and model exchange: every
//! exported `fmi2*` function, and all of the crate's `unsafe`.
//!
//! Each function checks its pointers, checks the instance's state against
//! the table in [`crate::state`], then calls the instance's
//! [`Component`] through the shared argument checks of [`crate::calls`]
//! inside `catch_unwind` (a panic becomes fmi2Error, never an abort of the
//! host), and turns the result into a status, logging every rejection with
//! the values involved.
//!
//! What a refusal does to the instance follows FMI 2.0 §2.1.3:
//! - fmi2Error ("the simulation cannot be continued with this FMU
//!   instance") moves the instance to the state machine's `error` state
//!   (§4.2.4), whatever the cause: wrong call sequence, NULL or unknown
//!   arguments, a bad serialized state, a panic. Nothing else changes; the
//!   values stay readable, and fmi2SetFMUstate (to a state saved before),
//!   fmi2Reset or fmi2FreeInstance are the ways on, as the standard says.
//!   (The FMI Reference FMUs instead return fmi2Error and stay where they
//!   were; the standard's text does not allow continuing, so neither do we.)
//! - fmi2Discard, which §2.1.3 allows for fmi2SetXXX in co-simulation
//!   (footnote 3: "fmi2SetXXX functions could check whether the input
//!   arguments are in their validity range. If not, these functions could
//!   return with fmi2Discard"), refuses a value out of its range (NaN, ±Inf,
//!   a non-positive `max_step`, an unknown `method` item): the value is not
//!   taken and the instance stays in its state. fmi2DoStep returns it for a
//!   step that failed (§4.2.2), fmi2GetXXXStatus for a status it cannot give.
//!
//! The instance is a `Box<Instance>` handed out with `Box::into_raw`; FMU
//! states are `Box<Snapshot>` pointers likewise. Every instance and FMU
//! state handed out is registered, so that a pointer that is not one (freed
//! already, from another instance, or garbage) is refused without being
//! dereferenced: a second fmi2FreeInstance or fmi2FreeFMUstate is harmless.
//! (A freed address that the allocator hands to a new instance cannot be
//! told from it; the standard leaves calls after fmi2FreeInstance undefined.)

// The patterns below are fmi-sys's C constants, named as in fmi2Functions.h.
#![allow(non_upper_case_globals)]

use std::collections::BTreeSet;
use std::ffi::{CStr, CString, c_char};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::{Mutex, PoisonError};

use fmi_sys::fmi2::*;
use nudyn::integrate::Stats;
use nudyn_contract::log::LogCategory;

use crate::calls::{self, Stepped};
use crate::component::{self, CallError, Component, LoadError, StepError};
use crate::snapshot::Snapshot;
use crate::state::{Function, Phase};

/// Why a call is refused before or after reaching the component.
#[derive(Debug, thiserror::Error)]
enum FmiError {
    /// The function was called in a state that does not allow it.
    #[error("{function} may not be called in state {phase}")]
    IllegalState {
        /// The C name of the function.
        function: &'static str,
        /// The state's name.
        phase: &'static str,
    },
    /// fmi2Instantiate asked for an interface that is not one of FMI 2.0's.
    #[error("fmuType = {0} is neither fmi2ModelExchange (0) nor fmi2CoSimulation (1)")]
    UnknownType(fmi2Type),
    /// fmi2Instantiate asked for model exchange of an FMU that does not serve it.
    #[error(
        "fmuType = fmi2ModelExchange: this FMU serves co-simulation (fmi2CoSimulation = 1) only (its \
         modelDescription has no <ModelExchange>: a controller FMU, or a plant with the energy_residual output)"
    )]
    NoModelExchange,
    /// fmi2SetFMUstate with a state saved by an instance of the other interface.
    #[error("the FMU state was saved in state {0} of the other interface (co-simulation or model exchange)")]
    OtherInterface(&'static str),
    /// A required pointer is NULL.
    #[error("{0} is NULL")]
    Null(&'static str),
    /// fmi2SetDebugLogging named a category the FMU does not declare.
    #[error("unknown log category '{0}' (known: {known})", known = LogCategory::known_names())]
    UnknownCategory(String),
    /// An fmi2FMUstate that this instance did not hand out, or has freed.
    #[error("FMUstate {0:#x} is not a live FMU state of this instance (freed already, or from another instance)")]
    UnknownState(usize),
    /// A value out of its range passed to fmi2SetXXX: fmi2Discard (§2.1.3, footnote 3).
    #[error(transparent)]
    OutOfRange(CallError),
    /// A serialized state buffer of the wrong size.
    #[error("the buffer for the serialized FMU state has {found} bytes, expected {expected}")]
    BufferSize {
        /// fmi2SerializedFMUstateSize.
        expected: usize,
        /// The size passed.
        found: usize,
    },
    /// A status the FMU does not provide.
    #[error("status kind {0} is not available")]
    StatusUnavailable(fmi2StatusKind),
    /// Directional derivatives are not provided (providesDirectionalDerivative="false").
    #[error("directional derivatives are not provided (providesDirectionalDerivative=\"false\")")]
    NoDirectionalDerivatives,
    /// The resources cannot make an instance.
    #[error(transparent)]
    Load(#[from] LoadError),
    /// The component refused the call, or cannot answer it.
    #[error(transparent)]
    Call(#[from] CallError),
    /// The step stopped inside the interval.
    #[error(transparent)]
    Step(#[from] StepError),
}

impl FmiError {
    fn status(&self) -> fmi2Status {
        match self {
            FmiError::Step(_) | FmiError::StatusUnavailable(_) | FmiError::OutOfRange(_) => fmi2Status_fmi2Discard,
            _ => fmi2Status_fmi2Error,
        }
    }
}

/// Where log messages go: the importer's callback and the enabled categories.
struct Logger {
    callback: fmi2CallbackLogger,
    environment: fmi2ComponentEnvironment,
    instance_name: CString,
    enabled: [bool; LogCategory::ALL.len()],
}

impl Logger {
    fn new(functions: &fmi2CallbackFunctions, instance_name: CString, logging_on: bool) -> Self {
        let enabled = LogCategory::ALL.map(|category| category.on_at_start(logging_on));
        Logger { callback: functions.logger, environment: functions.componentEnvironment, instance_name, enabled }
    }

    fn enabled(&self, category: LogCategory) -> bool {
        self.enabled[category.index()]
    }

    fn log(&self, status: fmi2Status, category: LogCategory, message: &str) {
        let Some(callback) = self.callback else { return };
        if !self.enabled(category) {
            return;
        }
        let category = CString::new(category.name()).expect("no NUL in category names");
        // The message is the format itself, with '%' escaped: importers that
        // cannot read C varargs (FMPy's ctypes logger) print it as it is.
        let message = CString::new(message.replace('\0', " ").replace('%', "%%")).expect("NULs replaced");
        // SAFETY: the callback is the importer's fmi2CallbackLogger; every
        // string is NUL-terminated and outlives the call, and the format
        // has no conversions left to read arguments.
        unsafe { callback(self.environment, self.instance_name.as_ptr(), status, category.as_ptr(), message.as_ptr()) };
    }

    fn log_status(&self, status: fmi2Status, message: &str) {
        let category = match status {
            fmi2Status_fmi2Discard => LogCategory::Discard,
            fmi2Status_fmi2Fatal => LogCategory::Fatal,
            _ => LogCategory::Error,
        };
        self.log(status, category, message);
    }
}

/// The interface an instance was instantiated for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Interface {
    ModelExchange,
    CoSimulation,
}

impl Interface {
    /// Whether `phase` is one of this interface's state machine.
    fn has(self, phase: Phase) -> bool {
        match phase {
            Phase::StepComplete | Phase::StepFailed => self == Interface::CoSimulation,
            Phase::EventMode | Phase::ContinuousTimeMode => self == Interface::ModelExchange,
            _ => true,
        }
    }
}

/// One FMU instance: the logger, the state machine and the component (plant or controller).
struct Instance {
    logger: Logger,
    interface: Interface,
    phase: Phase,
    component: Box<dyn Component>,
    /// The FMU states handed out by this instance and not yet freed (addresses).
    states: BTreeSet<usize>,
    /// A warning the last call completed with: its status is fmi2Warning.
    warning: Option<String>,
}

/// The FMU state `state`, if it is among `states`, those an instance handed
/// out and has not freed.
///
/// # Safety
/// `states` are live `Box<Snapshot>` addresses; the reference is used
/// before any of them is freed, and is the only one to that state.
unsafe fn snapshot<'a>(states: &BTreeSet<usize>, state: fmi2FMUstate) -> Result<&'a mut Snapshot, FmiError> {
    if state.is_null() {
        return Err(FmiError::Null("FMUstate"));
    }
    if !states.contains(&(state as usize)) {
        return Err(FmiError::UnknownState(state as usize));
    }
    // SAFETY: by the contract above.
    Ok(unsafe { &mut *(state as *mut Snapshot) })
}

impl Instance {
    /// Hands out a new FMU state.
    fn register(&mut self, snapshot: Snapshot) -> fmi2FMUstate {
        let state = Box::into_raw(Box::new(snapshot));
        self.states.insert(state as usize);
        state as fmi2FMUstate
    }
}

impl Drop for Instance {
    /// FMU states die with their instance (they are valid for it only).
    fn drop(&mut self) {
        for &state in &self.states {
            // SAFETY: each address is a live Box<Snapshot> from `register`.
            drop(unsafe { Box::from_raw(state as *mut Snapshot) });
        }
    }
}

/// The addresses of the live instances of this process.
static INSTANCES: Mutex<BTreeSet<usize>> = Mutex::new(BTreeSet::new());

/// The registry of live instances. No code panics while holding the lock,
/// but a poisoned lock still holds a consistent set.
fn instances() -> std::sync::MutexGuard<'static, BTreeSet<usize>> {
    INSTANCES.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The instance `c` points to, if it is a live one.
///
/// # Safety
/// No other reference to the instance may be alive (FMI 2.0 §2.1.5: an
/// instance is not called from two threads at once).
unsafe fn instance<'a>(c: fmi2Component) -> Option<&'a mut Instance> {
    if !instances().contains(&(c as usize)) {
        return None;
    }
    // SAFETY: registered at fmi2Instantiate, removed before fmi2FreeInstance frees it.
    Some(unsafe { &mut *(c as *mut Instance) })
}

/// The text of a panic payload.
fn panic_message(payload: &(dyn std::any::Any + Send)) -> &str {
    payload
        .downcast_ref::<&str>()
        .copied()
        .or_else(|| payload.downcast_ref::<String>().map(String::as_str))
        .unwrap_or("(no message)")
}

/// The common entry path: state check, panic guard, status and logging.
/// A `c` that is not a live instance (NULL, freed, garbage) gets fmi2Error
/// and nothing else: there is no logger to tell.
///
/// # Safety
/// FMI 2.0 calling conventions (the instance is not used concurrently).
unsafe fn enter(
    c: fmi2Component,
    function: Function,
    body: impl FnOnce(&mut Instance) -> Result<(), FmiError>,
) -> fmi2Status {
    // SAFETY: by the contract above.
    let Some(instance) = (unsafe { instance(c) }) else {
        return fmi2Status_fmi2Error;
    };
    let result = if function.allowed_in(instance.phase) {
        catch_unwind(AssertUnwindSafe(|| body(&mut *instance)))
    } else {
        Ok(Err(FmiError::IllegalState { function: function.name(), phase: instance.phase.name() }))
    };
    let status = match result {
        Ok(Ok(())) => match instance.warning.take() {
            Some(message) => {
                instance.logger.log(fmi2Status_fmi2Warning, LogCategory::Warning, &message);
                fmi2Status_fmi2Warning
            }
            None => fmi2Status_fmi2OK,
        },
        Ok(Err(error)) => {
            let status = error.status();
            if status == fmi2Status_fmi2Error {
                instance.phase = Phase::Error;
            }
            instance.logger.log_status(status, &format!("{}: {error}", function.name()));
            status
        }
        Err(payload) => {
            instance.phase = Phase::Error;
            let message = format!("{}: internal error (panic): {}", function.name(), panic_message(&*payload));
            instance.logger.log_status(fmi2Status_fmi2Error, &message);
            fmi2Status_fmi2Error
        }
    };
    if instance.logger.enabled(LogCategory::Calls) {
        instance.logger.log(status, LogCategory::Calls, &format!("{} returned status {status}", function.name()));
    }
    status
}

/// A slice from a C array; NULL is accepted for an empty one.
///
/// # Safety
/// A non-NULL `ptr` must point to `n` valid elements that live for `'a`.
unsafe fn slice<'a, T>(ptr: *const T, n: usize, what: &'static str) -> Result<&'a [T], FmiError> {
    if n == 0 {
        return Ok(&[]);
    }
    if ptr.is_null() {
        return Err(FmiError::Null(what));
    }
    // SAFETY: non-NULL, and `n` elements by the contract above.
    Ok(unsafe { std::slice::from_raw_parts(ptr, n) })
}

/// A mutable slice from a C array; NULL is accepted for an empty one.
///
/// # Safety
/// A non-NULL `ptr` must point to `n` valid, writable elements, unaliased for `'a`.
unsafe fn slice_mut<'a, T>(ptr: *mut T, n: usize, what: &'static str) -> Result<&'a mut [T], FmiError> {
    if n == 0 {
        return Ok(&mut []);
    }
    if ptr.is_null() {
        return Err(FmiError::Null(what));
    }
    // SAFETY: non-NULL, and `n` writable elements by the contract above.
    Ok(unsafe { std::slice::from_raw_parts_mut(ptr, n) })
}

/// A C string argument, lossily as UTF-8.
///
/// # Safety
/// A non-NULL `ptr` must be a NUL-terminated string.
unsafe fn string(ptr: fmi2String, what: &'static str) -> Result<String, FmiError> {
    if ptr.is_null() {
        return Err(FmiError::Null(what));
    }
    // SAFETY: non-NULL and NUL-terminated by the contract above.
    Ok(unsafe { CStr::from_ptr(ptr) }.to_string_lossy().into_owned())
}

/// fmi2SetXXX's refusal: a value out of its range is fmi2Discard (§2.1.3,
/// footnote 3), anything else (unknown or unsettable variable) fmi2Error.
fn out_of_range_discards(error: CallError) -> FmiError {
    if error.is_out_of_range() { FmiError::OutOfRange(error) } else { FmiError::Call(error) }
}

/// Whether the phase is before fmi2ExitInitializationMode.
fn initialized(phase: Phase) -> bool {
    !matches!(phase, Phase::Instantiated | Phase::InitializationMode)
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
    let logger = Logger::new(functions, CString::new(name.replace('\0', " ")).expect("NULs replaced"), logging_on != 0);
    let instantiate = || -> Result<(Interface, Box<dyn Component>), FmiError> {
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
        let component = component::load(&location, &guid)?;
        if interface == Interface::ModelExchange && component.continuous_state_count().is_none() {
            return Err(FmiError::NoModelExchange);
        }
        Ok((interface, component))
    };
    match catch_unwind(AssertUnwindSafe(instantiate)) {
        Ok(Ok((interface, component))) => {
            let phase = Phase::Instantiated;
            let instance = Instance { logger, interface, phase, component, states: BTreeSet::new(), warning: None };
            let c = Box::into_raw(Box::new(instance));
            instances().insert(c as usize);
            c as fmi2Component
        }
        Ok(Err(error)) => {
            logger.log_status(fmi2Status_fmi2Error, &format!("fmi2Instantiate: {error}"));
            std::ptr::null_mut()
        }
        Err(payload) => {
            let message = format!("fmi2Instantiate: internal error (panic): {}", panic_message(&*payload));
            logger.log_status(fmi2Status_fmi2Error, &message);
            std::ptr::null_mut()
        }
    }
}

/// # Safety
/// FMI 2.0 calling conventions. A NULL, freed or foreign `c` is ignored.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2FreeInstance(c: fmi2Component) {
    // Deregistered under the lock, so two racing frees cannot both free it.
    {
        let mut live = instances();
        if !live.remove(&(c as usize)) {
            return;
        }
        // An emptied BTreeSet keeps its root node: drop it, so that a host
        // that unloads the library (dlclose) after the last instance loses nothing.
        if live.is_empty() {
            *live = BTreeSet::new();
        }
    }
    // SAFETY: `c` came from Box::into_raw in fmi2Instantiate and was live
    // until just now; every state allows fmi2FreeInstance (§4.2.4).
    let instance = unsafe { Box::from_raw(c as *mut Instance) };
    // Dropping frees plain Rust data; guard anyway so nothing unwinds into C.
    let _ = catch_unwind(AssertUnwindSafe(move || drop(instance)));
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
            let categories = slice(categories, n_categories, "categories")?;
            let mut indices = Vec::with_capacity(categories.len());
            for &category in categories {
                let name = string(category, "a category")?;
                let category = LogCategory::from_name(&name).ok_or(FmiError::UnknownCategory(name))?;
                indices.push(category.index());
            }
            let enabled = &mut instance.logger.enabled;
            if indices.is_empty() {
                enabled.fill(logging_on != 0);
            }
            indices.into_iter().for_each(|i| enabled[i] = logging_on != 0);
            Ok(())
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
    unsafe {
        enter(c, Function::ExitInitializationMode, |instance| {
            instance.component.initialize()?;
            instance.phase = match instance.interface {
                Interface::CoSimulation => Phase::StepComplete,
                Interface::ModelExchange => Phase::EventMode,
            };
            Ok(())
        })
    }
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
    unsafe {
        enter(c, Function::Reset, |instance| {
            instance.component.reset();
            instance.phase = Phase::Instantiated;
            Ok(())
        })
    }
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
            Ok(calls::get_real(&mut *instance.component, vrs, values)?)
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
    unsafe {
        enter(c, Function::GetFmuState, |instance| {
            calls::fmu_states(&*instance.component)?;
            let state = state.as_mut().ok_or(FmiError::Null("FMUstate"))?;
            let phase = instance.phase;
            if state.is_null() {
                *state = instance.register(instance.component.snapshot(phase)?);
            } else {
                // An existing state is overwritten in place (FMI 2.0 §2.1.8).
                instance.component.save(phase, snapshot(&instance.states, *state)?)?;
            }
            Ok(())
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SetFMUstate(c: fmi2Component, state: fmi2FMUstate) -> fmi2Status {
    unsafe {
        enter(c, Function::SetFmuState, |instance| {
            calls::fmu_states(&*instance.component)?;
            let snapshot = snapshot(&instance.states, state)?;
            let phase = snapshot.phase;
            if !instance.interface.has(phase) {
                return Err(FmiError::OtherInterface(phase.name()));
            }
            instance.component.restore(snapshot)?;
            // The state machine goes back to where the state was saved: this
            // is how a master leaves `error` (§2.1.3) or `stepFailed`.
            instance.phase = phase;
            Ok(())
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2FreeFMUstate(c: fmi2Component, state: *mut fmi2FMUstate) -> fmi2Status {
    unsafe {
        enter(c, Function::FreeFmuState, |instance| {
            // NULL, or a pointer to NULL, frees nothing (as free(NULL) does).
            let Some(state) = state.as_mut() else { return Ok(()) };
            if state.is_null() {
                return Ok(());
            }
            snapshot(&instance.states, *state)?;
            instance.states.remove(&(*state as usize));
            drop(Box::from_raw(*state as *mut Snapshot));
            *state = std::ptr::null_mut();
            Ok(())
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: fmi2Component,
    state: fmi2FMUstate,
    size: *mut usize,
) -> fmi2Status {
    unsafe {
        enter(c, Function::SerializedFmuStateSize, |instance| {
            let snapshot = snapshot(&instance.states, state)?;
            *size.as_mut().ok_or(FmiError::Null("size"))? = snapshot.serialized_size();
            Ok(())
        })
    }
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
        enter(c, Function::SerializeFmuState, |instance| {
            let snapshot = snapshot(&instance.states, state)?;
            let expected = snapshot.serialized_size();
            if size != expected {
                return Err(FmiError::BufferSize { expected, found: size });
            }
            snapshot.serialize(slice_mut(bytes as *mut u8, size, "serializedState")?);
            Ok(())
        })
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
            calls::fmu_states(&*instance.component)?;
            let state = state.as_mut().ok_or(FmiError::Null("FMUstate"))?;
            let existing =
                if state.is_null() { None } else { Some(snapshot(&instance.states, *state)? as *mut Snapshot) };
            let snapshot = instance.component.deserialize(slice(bytes as *const u8, size, "serializedState")?)?;
            if !instance.interface.has(snapshot.phase) {
                return Err(FmiError::OtherInterface(snapshot.phase.name()));
            }
            match existing {
                // SAFETY: checked live above; nothing freed it since.
                Some(existing) => *existing = snapshot,
                None => *state = instance.register(snapshot),
            }
            Ok(())
        })
    }
}

/// # Safety
/// FMI 2.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
    c: fmi2Component,
    _unknown: *const fmi2ValueReference,
    _n_unknown: usize,
    _known: *const fmi2ValueReference,
    _n_known: usize,
    _dv_known: *const fmi2Real,
    _dv_unknown: *mut fmi2Real,
) -> fmi2Status {
    unsafe { enter(c, Function::GetDirectionalDerivative, |_| Err(FmiError::NoDirectionalDerivatives)) }
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
            let stepped =
                calls::do_step(&mut *instance.component, current_communication_point, communication_step_size);
            let report = match stepped {
                Ok(Some(report)) => report,
                Ok(None) => return Ok(()),
                Err(Stepped::Refused(error)) => return Err(error.into()),
                Err(Stepped::Failed(error)) => {
                    instance.phase = Phase::StepFailed;
                    return Err(error.into());
                }
            };
            if instance.logger.enabled(LogCategory::Calls) {
                let Stats { accepted, rejected } = report.stats;
                let message = format!("fmi2DoStep: {accepted} internal steps taken, {rejected} rejected");
                instance.logger.log(fmi2Status_fmi2OK, LogCategory::Calls, &message);
            }
            instance.warning = report.relaxed.map(|relaxed| format!("fmi2DoStep: {relaxed}"));
            Ok(())
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
        enter(c, Function::NewDiscreteStates, |_| {
            let event_info = event_info.as_mut().ok_or(FmiError::Null("fmi2eventInfo"))?;
            // No discrete states, no time or state events: nothing ever changes at an event.
            *event_info = fmi2EventInfo {
                newDiscreteStatesNeeded: fmi2False as fmi2Boolean,
                terminateSimulation: fmi2False as fmi2Boolean,
                nominalsOfContinuousStatesChanged: fmi2False as fmi2Boolean,
                valuesOfContinuousStatesChanged: fmi2False as fmi2Boolean,
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
    _event_indicators: *mut fmi2Real,
    ni: usize,
) -> fmi2Status {
    unsafe {
        enter(c, Function::GetEventIndicators, |instance| Ok(calls::get_event_indicators(&*instance.component, ni)?))
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
    use std::path::PathBuf;

    use nudyn_contract::plant::{OptionalOutputs, PlantResource};
    use nudyn_contract::resource::Resource;

    use super::*;

    /// The fixed_rig example's resources in a fresh directory: (resource URI, GUID).
    fn resources(test: &str) -> (CString, CString) {
        let example = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../examples/fixed_rig.xml");
        let vehicle = nudyn::mjcf::load_mjcf(&example).expect("example imports").vehicle;
        let model = nudyn::model::Model::compile(&vehicle).expect("example compiles");
        let resource = PlantResource::new(model, OptionalOutputs::default());
        let json = resource.to_json().expect("serializable");
        let dir = std::env::temp_dir().join(format!("nudyn-fmu-{test}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        std::fs::write(dir.join("model.json"), &json).expect("resource written");
        let uri = format!("file://{}/", dir.display());
        let guid = resource.guid(&json);
        (CString::new(uri).expect("no NUL"), CString::new(guid).expect("no NUL"))
    }

    fn instantiate(uri: &CString, guid: &CStr) -> fmi2Component {
        let functions = fmi2CallbackFunctions {
            logger: None,
            allocateMemory: None,
            freeMemory: None,
            stepFinished: None,
            componentEnvironment: std::ptr::null_mut(),
        };
        unsafe {
            fmi2Instantiate(c"test".as_ptr(), fmi2Type_fmi2CoSimulation, guid.as_ptr(), uri.as_ptr(), &functions, 0, 0)
        }
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
