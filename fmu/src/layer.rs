//! What the FMI 2.0 and FMI 3.0 layers share: the instance (logger, state
//! machine, component, FMU states), the registries of live instances and
//! FMU states, the one entry path every call takes, and the bodies of the
//! calls that are the same in both versions. With [`crate::fmi2`] and
//! [`crate::fmi3`] it holds all of the crate's `unsafe`.
//!
//! Every call checks its pointers, checks the instance's state against the
//! table in [`crate::state`], then calls the instance's [`Component`]
//! through the shared argument checks of [`crate::calls`] inside
//! `catch_unwind` (a panic becomes an error status, never an abort of the
//! host, and its message goes to the importer's logger, not to the host's
//! stderr), and turns the result into a status, logging every rejection
//! with the values involved. No array is made, read or allocated for a
//! count before the count is checked.
//!
//! What a refusal does to the instance (FMI 2.0 §2.1.3, FMI 3.0 §2.2.3):
//! - Error ("the simulation cannot be continued with this FMU instance")
//!   moves the instance to the `error` state whatever the cause: wrong call
//!   sequence, NULL or unknown arguments, a bad serialized state, a panic.
//!   Nothing else changes; the values stay readable, and setting an FMU
//!   state saved before, a reset or freeing the instance are the ways on, as
//!   the standards say. (The FMI Reference FMUs instead return an error and
//!   stay where they were; the standards' text does not allow continuing,
//!   so neither do we.)
//! - Discard refuses a value out of its range passed to a setter (NaN, ±Inf,
//!   a negative `max_step`, an unknown `method` item; FMI 2.0 §2.1.3
//!   footnote 3): the value is not taken and the instance stays in its
//!   state. doStep returns it for a step that failed, and FMI 2.0's status
//!   functions for a status they cannot give.
//!
//! The instance is a `Box<Instance>` handed out with `Box::into_raw`; FMU
//! states are `Box<Snapshot>` pointers likewise. Every instance and FMU
//! state handed out is registered, so that a pointer that is not one (freed
//! already, from another instance, or garbage) is refused without being
//! dereferenced: a second free of either is harmless. (A freed address that
//! the allocator hands to a new instance cannot be told from it; the
//! standards leave calls after freeing an instance undefined.)

use std::cell::Cell;
use std::collections::BTreeSet;
use std::ffi::{CStr, CString, c_char, c_uint, c_void};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::{Mutex, OnceLock, PoisonError};

use fmi_sys::{fmi2, fmi3};
use nudyn_contract::fmi3::Fmi3Variables;
use nudyn_contract::log::LogCategory;

use crate::calls;
use crate::component::{CallError, Component, StepError};
use crate::load::LoadError;
use crate::snapshot::Snapshot;
use crate::state::{Function, Interface, Phase};

/// The FMI version an instance was made through.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Version {
    /// fmi2Instantiate.
    Fmi2,
    /// fmi3InstantiateModelExchange or fmi3InstantiateCoSimulation.
    Fmi3,
}

/// A call's outcome. FMI 2.0 and FMI 3.0 give the statuses the same codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// fmi2OK, fmi3OK.
    Ok = 0,
    /// fmi2Warning, fmi3Warning.
    Warning = 1,
    /// fmi2Discard, fmi3Discard.
    Discard = 2,
    /// fmi2Error, fmi3Error. (Nothing here is fatal: no call harms other instances.)
    Error = 3,
}

impl Status {
    /// The C value (fmi2Status and fmi3Status are both unsigned ints).
    pub fn code(self) -> c_uint {
        self as c_uint
    }
}

/// Why a call is refused before or after reaching the component.
#[derive(Debug, thiserror::Error)]
pub enum FmiError {
    /// The function was called in a state that does not allow it.
    #[error("{function} may not be called in state {phase}")]
    IllegalState {
        /// The C name of the function.
        function: &'static str,
        /// The state's name.
        phase: &'static str,
    },
    /// A function of the other interface (model exchange or co-simulation).
    #[error("{function} is a {interface} function, but this instance was instantiated for {other}")]
    OtherInterfaceFunction {
        /// The C name of the function.
        function: &'static str,
        /// The interface it belongs to.
        interface: &'static str,
        /// The instance's interface.
        other: &'static str,
    },
    /// fmi2Instantiate asked for an interface that is not one of FMI 2.0's.
    #[error("fmuType = {0} is neither fmi2ModelExchange (0) nor fmi2CoSimulation (1)")]
    UnknownType(c_uint),
    /// Model exchange asked of an FMU that does not serve it.
    #[error(
        "model exchange: this FMU serves co-simulation only (its modelDescription has no <ModelExchange>: \
         a controller FMU, or a plant with the energy_residual output)"
    )]
    NoModelExchange,
    /// An interface or mode the FMU does not provide.
    #[error("{0}")]
    Unsupported(&'static str),
    /// Setting an FMU state saved by an instance of the other interface.
    #[error("the FMU state was saved in state {0} of the other interface (co-simulation or model exchange)")]
    OtherInterface(&'static str),
    /// A required pointer is NULL.
    #[error("{0} is NULL")]
    Null(&'static str),
    /// SetDebugLogging named a category the FMU does not declare.
    #[error("unknown log category '{0}' (known: {known})", known = LogCategory::known_names())]
    UnknownCategory(String),
    /// An FMU state that this instance did not hand out, or has freed.
    #[error("FMUstate {0:#x} is not a live FMU state of this instance (freed already, or from another instance)")]
    UnknownState(usize),
    /// A value out of its range passed to a setter: Discard.
    #[error(transparent)]
    OutOfRange(CallError),
    /// A serialized state buffer of the wrong size.
    #[error("the buffer for the serialized FMU state has {found} bytes, expected {expected}")]
    BufferSize {
        /// The serialized size.
        expected: usize,
        /// The size passed.
        found: usize,
    },
    /// An FMI 2.0 status the FMU does not provide.
    #[error("status kind {0} is not available")]
    StatusUnavailable(c_uint),
    /// FMI 3.0: a seed or sensitivity whose length is not the elements' of its value references.
    #[error("{what} = {found}, but the value references of the {of} name {expected} values")]
    PartialCount {
        /// nSeed or nSensitivity.
        what: &'static str,
        /// "knowns" or "unknowns".
        of: &'static str,
        /// The elements of those value references.
        expected: usize,
        /// The length passed.
        found: usize,
    },
    /// FMI 3.0: time passed as a known or an unknown.
    #[error("time (value reference 0) is neither a known nor an unknown of the partial derivatives")]
    TimeInPartial,
    /// An FMI 3.0 value reference of another type than the function's.
    #[error("value reference {vr} is the {declared} variable '{name}', not a variable of type {asked}")]
    WrongType {
        /// The value reference.
        vr: u32,
        /// The variable's name.
        name: String,
        /// Its type.
        declared: &'static str,
        /// The function's type.
        asked: &'static str,
    },
    /// An array length whose bytes exceed what any array can hold (isize::MAX).
    #[error("{what} has {n} elements: more than any array can hold")]
    TooLong {
        /// The array's C name.
        what: &'static str,
        /// The length passed.
        n: usize,
    },
    /// More value references than values: every variable has at least one
    /// value, so the value references cannot all be read.
    #[error("nValueReferences = {n_value_references} is more than nValues = {n_values}")]
    MoreReferencesThanValues {
        /// nValueReferences.
        n_value_references: usize,
        /// nValues.
        n_values: usize,
    },
    /// SetDebugLogging named more categories than the FMU has.
    #[error("nCategories = {0} is more than the {known} log categories the FMU has", known = LogCategory::ALL.len())]
    TooManyCategories(usize),
    /// FMI 3.0's nValues does not match the value references' sizes.
    #[error("nValues = {found}, but the value references name {expected} values")]
    ValueCount {
        /// What the value references add up to.
        expected: usize,
        /// nValues.
        found: usize,
    },
    /// FMI 3.0: an Int64 value that no enumeration item can have.
    #[error("{name} = {value} is not an item of the enumeration")]
    EnumerationValue {
        /// The variable.
        name: String,
        /// The value.
        value: i64,
    },
    /// FMI 3.0: the independent variable is set.
    #[error("time (value reference 0) is the independent variable: it cannot be set")]
    SetTime,
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
    fn status(&self) -> Status {
        match self {
            FmiError::Step(_) | FmiError::StatusUnavailable(_) | FmiError::OutOfRange(_) => Status::Discard,
            _ => Status::Error,
        }
    }
}

/// The importer's logging function, as each version declares it.
enum Callback {
    Fmi2 { callback: fmi2::fmi2CallbackLogger, environment: fmi2::fmi2ComponentEnvironment, instance_name: CString },
    Fmi3 { callback: fmi3::fmi3LogMessageCallback, environment: fmi3::fmi3InstanceEnvironment },
}

/// Where log messages go: the importer's callback and the enabled categories.
pub struct Logger {
    callback: Callback,
    enabled: [bool; LogCategory::ALL.len()],
}

impl Logger {
    /// An FMI 2.0 logger.
    pub fn fmi2(functions: &fmi2::fmi2CallbackFunctions, instance_name: &str, logging_on: bool) -> Self {
        let instance_name = CString::new(instance_name.replace('\0', " ")).expect("NULs replaced");
        let callback =
            Callback::Fmi2 { callback: functions.logger, environment: functions.componentEnvironment, instance_name };
        Logger { callback, enabled: LogCategory::ALL.map(|category| category.on_at_start(logging_on)) }
    }

    /// An FMI 3.0 logger.
    pub fn fmi3(
        callback: fmi3::fmi3LogMessageCallback,
        environment: fmi3::fmi3InstanceEnvironment,
        logging_on: bool,
    ) -> Self {
        let callback = Callback::Fmi3 { callback, environment };
        Logger { callback, enabled: LogCategory::ALL.map(|category| category.on_at_start(logging_on)) }
    }

    /// Whether messages of `category` are passed on.
    pub fn enabled(&self, category: LogCategory) -> bool {
        self.enabled[category.index()]
    }

    /// Passes `message` to the importer, if its category is enabled.
    pub fn log(&self, status: Status, category: LogCategory, message: &str) {
        if !self.enabled(category) {
            return;
        }
        let category = CString::new(category.name()).expect("no NUL in category names");
        match &self.callback {
            Callback::Fmi2 { callback: Some(callback), environment, instance_name } => {
                // The message is the format itself, with '%' escaped: importers that
                // cannot read C varargs (FMPy's ctypes logger) print it as it is.
                let message = CString::new(message.replace('\0', " ").replace('%', "%%")).expect("NULs replaced");
                // SAFETY: the callback is the importer's fmi2CallbackLogger; every
                // string is NUL-terminated and outlives the call, and the format
                // has no conversions left to read arguments.
                unsafe {
                    callback(*environment, instance_name.as_ptr(), status.code(), category.as_ptr(), message.as_ptr())
                };
            }
            Callback::Fmi3 { callback: Some(callback), environment } => {
                // FMI 3.0 messages are plain strings, not formats.
                let message = CString::new(message.replace('\0', " ")).expect("NULs replaced");
                // SAFETY: the importer's fmi3LogMessageCallback; NUL-terminated strings that outlive the call.
                unsafe { callback(*environment, status.code(), category.as_ptr(), message.as_ptr()) };
            }
            _ => {}
        }
    }

    /// Logs a refusal under the category of its status.
    pub fn log_status(&self, status: Status, message: &str) {
        let category = match status {
            Status::Discard => LogCategory::Discard,
            _ => LogCategory::Error,
        };
        self.log(status, category, message);
    }
}

/// What the array functions reuse from call to call: a host sets ε and
/// reads θ and ν at every communication point, and once these have grown to
/// those calls' sizes the calls allocate nothing. Filled by the FMI 3.0
/// functions (crate::fmi3), which implement its methods.
#[derive(Debug, Default)]
pub struct Buffers {
    /// The elements of a call's value references (`None`: time).
    pub(crate) elements: Vec<Option<u32>>,
    /// Their FMI 2.0 value references.
    pub(crate) references: Vec<u32>,
    /// The values read for them.
    pub(crate) reals: Vec<f64>,
}

/// One FMU instance: the logger, the state machine and the component (plant or controller).
pub struct Instance {
    /// The importer's logger.
    pub logger: Logger,
    /// The FMI version of the instance's functions.
    pub version: Version,
    /// The interface it was instantiated for.
    pub interface: Interface,
    /// Where it is in its state machine.
    pub phase: Phase,
    /// What it runs.
    pub component: Box<dyn Component>,
    /// The FMI 3.0 variables (empty for an FMI 2.0 instance).
    pub fmi3: Fmi3Variables,
    /// The FMI 3.0 array functions' buffers.
    pub fmi3_buffers: Buffers,
    /// The FMU states handed out by this instance and not yet freed (addresses).
    states: BTreeSet<usize>,
    /// A warning the last call completed with: its status is Warning.
    pub warning: Option<String>,
}

impl Instance {
    /// A new instance in state instantiated.
    pub fn new(
        logger: Logger,
        version: Version,
        interface: Interface,
        component: Box<dyn Component>,
        fmi3: Fmi3Variables,
    ) -> Self {
        let phase = Phase::Instantiated;
        Instance {
            logger,
            version,
            interface,
            phase,
            component,
            fmi3,
            fmi3_buffers: Default::default(),
            states: BTreeSet::new(),
            warning: None,
        }
    }

    /// Hands out a new FMU state.
    fn register(&mut self, snapshot: Snapshot) -> *mut c_void {
        let state = Box::into_raw(Box::new(snapshot));
        self.states.insert(state as usize);
        state as *mut c_void
    }

    /// The FMU state `state`, if this instance handed it out and has not freed it.
    fn snapshot<'a>(&self, state: *mut c_void) -> Result<&'a mut Snapshot, FmiError> {
        if state.is_null() {
            return Err(FmiError::Null("FMUstate"));
        }
        if !self.states.contains(&(state as usize)) {
            return Err(FmiError::UnknownState(state as usize));
        }
        // SAFETY: registered addresses are live Box<Snapshot>s; the reference
        // is used before any of them is freed, and is the only one to that state.
        Ok(unsafe { &mut *(state as *mut Snapshot) })
    }

    /// The state's name in this instance's version of the standard.
    fn phase_name(&self) -> &'static str {
        match self.version {
            Version::Fmi2 => self.phase.name(),
            Version::Fmi3 => self.phase.fmi3_name(),
        }
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

/// Hands out a new instance.
pub fn register(instance: Instance) -> *mut c_void {
    let c = Box::into_raw(Box::new(instance));
    instances().insert(c as usize);
    c as *mut c_void
}

/// Frees the instance `c`; a NULL, freed or foreign `c` is ignored.
///
/// # Safety
/// No other reference to the instance may be alive.
pub unsafe fn free(c: *mut c_void) {
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
    // SAFETY: `c` came from Box::into_raw in `register` and was live until just now.
    let instance = unsafe { Box::from_raw(c as *mut Instance) };
    // Dropping frees plain Rust data; guard anyway so nothing unwinds into C.
    let _ = guarded(move || drop(instance));
}

/// The instance `c` points to, if it is a live one.
///
/// # Safety
/// No other reference to the instance may be alive (an instance is not
/// called from two threads at once).
unsafe fn instance<'a>(c: *mut c_void) -> Option<&'a mut Instance> {
    if !instances().contains(&(c as usize)) {
        return None;
    }
    // SAFETY: registered at instantiation, removed before it is freed.
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

thread_local! {
    /// How many guarded calls this thread is inside (a host's logger may call back in).
    static GUARD_DEPTH: Cell<u32> = const { Cell::new(0) };
    /// Where the last panic inside a guard was raised, for its log message.
    static PANIC_LOCATION: Cell<Option<String>> = const { Cell::new(None) };
}

/// The panic hook there was before [`guarded`] installed its own.
type Hook = Box<dyn Fn(&std::panic::PanicHookInfo<'_>) + Sync + Send>;
static PREVIOUS_HOOK: OnceLock<Hook> = OnceLock::new();

/// Runs `body`; a panic becomes an `Err` with its message and location,
/// for the importer's logger. The default panic hook would print them on
/// the host's stderr, so a hook installed on first use keeps panics inside
/// a guard quiet and passes any other (a Rust host's own, when this crate
/// is linked as a library) to the hook that was there before. Neither
/// hook allocates (the default hook and this one capture nothing), so a
/// host that unloads the library (dlclose) loses no memory to them.
fn guarded<R>(body: impl FnOnce() -> R) -> Result<R, String> {
    PREVIOUS_HOOK.get_or_init(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(|info| {
            if GUARD_DEPTH.get() > 0 {
                PANIC_LOCATION.set(info.location().map(ToString::to_string));
            } else if let Some(previous) = PREVIOUS_HOOK.get() {
                previous(info);
            }
        }));
        previous
    });
    GUARD_DEPTH.set(GUARD_DEPTH.get() + 1);
    let result = catch_unwind(AssertUnwindSafe(body));
    GUARD_DEPTH.set(GUARD_DEPTH.get() - 1);
    result.map_err(|payload| {
        let location = PANIC_LOCATION.take().map_or_else(String::new, |at| format!(" at {at}"));
        format!("internal error (panic{location}): {}", panic_message(&*payload))
    })
}

/// Runs an instantiation: a panic or an error is logged and makes no instance.
pub fn instantiate(
    logger: Logger,
    function: &'static str,
    make: impl FnOnce() -> Result<(Version, Interface, Box<dyn Component>, Fmi3Variables), FmiError>,
) -> *mut c_void {
    match guarded(make) {
        Ok(Ok((version, interface, component, fmi3))) => {
            register(Instance::new(logger, version, interface, component, fmi3))
        }
        Ok(Err(error)) => {
            logger.log_status(Status::Error, &format!("{function}: {error}"));
            std::ptr::null_mut()
        }
        Err(panic) => {
            logger.log_status(Status::Error, &format!("{function}: {panic}"));
            std::ptr::null_mut()
        }
    }
}

/// The common entry path: state and interface check, panic guard, status
/// and logging. A `c` that is not a live instance (NULL, freed, garbage)
/// gets Error and nothing else: there is no logger to tell. `name` is the
/// C name of the function called.
///
/// # Safety
/// The version's calling conventions (the instance is not used concurrently).
pub unsafe fn enter(
    c: *mut c_void,
    function: Function,
    name: &'static str,
    body: impl FnOnce(&mut Instance) -> Result<(), FmiError>,
) -> Status {
    // SAFETY: by the contract above.
    let Some(instance) = (unsafe { instance(c) }) else {
        return Status::Error;
    };
    let interface = function.interface().filter(|&interface| interface != instance.interface);
    let result = if let Some(interface) = interface {
        Ok(Err(FmiError::OtherInterfaceFunction {
            function: name,
            interface: interface.name(),
            other: instance.interface.name(),
        }))
    } else if function.allowed_in(instance.phase) {
        guarded(|| body(&mut *instance))
    } else {
        Ok(Err(FmiError::IllegalState { function: name, phase: instance.phase_name() }))
    };
    let status = match result {
        Ok(Ok(())) => match instance.warning.take() {
            Some(message) => {
                instance.logger.log(Status::Warning, LogCategory::Warning, &message);
                Status::Warning
            }
            None => Status::Ok,
        },
        Ok(Err(error)) => {
            let status = error.status();
            if status == Status::Error {
                instance.phase = Phase::Error;
            }
            instance.logger.log_status(status, &format!("{name}: {error}"));
            status
        }
        Err(panic) => {
            instance.phase = Phase::Error;
            instance.logger.log_status(Status::Error, &format!("{name}: {panic}"));
            Status::Error
        }
    };
    if instance.logger.enabled(LogCategory::Calls) {
        instance.logger.log(status, LogCategory::Calls, &format!("{name} returned status {}", status.code()));
    }
    status
}

/// Refuses a length `n` of `T`s that no array can have (more than
/// isize::MAX bytes), which a slice may not be made of.
fn fits<T>(n: usize, what: &'static str) -> Result<(), FmiError> {
    match n.checked_mul(size_of::<T>()) {
        Some(bytes) if bytes <= isize::MAX as usize => Ok(()),
        _ => Err(FmiError::TooLong { what, n }),
    }
}

/// A slice from a C array; NULL is accepted for an empty one.
///
/// # Safety
/// A non-NULL `ptr` must point to `n` valid elements that live for `'a`.
pub unsafe fn slice<'a, T>(ptr: *const T, n: usize, what: &'static str) -> Result<&'a [T], FmiError> {
    if n == 0 {
        return Ok(&[]);
    }
    if ptr.is_null() {
        return Err(FmiError::Null(what));
    }
    fits::<T>(n, what)?;
    // SAFETY: non-NULL, and `n` elements by the contract above.
    Ok(unsafe { std::slice::from_raw_parts(ptr, n) })
}

/// A mutable slice from a C array; NULL is accepted for an empty one.
///
/// # Safety
/// A non-NULL `ptr` must point to `n` valid, writable elements, unaliased for `'a`.
pub unsafe fn slice_mut<'a, T>(ptr: *mut T, n: usize, what: &'static str) -> Result<&'a mut [T], FmiError> {
    if n == 0 {
        return Ok(&mut []);
    }
    if ptr.is_null() {
        return Err(FmiError::Null(what));
    }
    fits::<T>(n, what)?;
    // SAFETY: non-NULL, and `n` writable elements by the contract above.
    Ok(unsafe { std::slice::from_raw_parts_mut(ptr, n) })
}

/// A C string argument, lossily as UTF-8.
///
/// # Safety
/// A non-NULL `ptr` must be a NUL-terminated string.
pub unsafe fn string(ptr: *const c_char, what: &'static str) -> Result<String, FmiError> {
    if ptr.is_null() {
        return Err(FmiError::Null(what));
    }
    // SAFETY: non-NULL and NUL-terminated by the contract above.
    Ok(unsafe { CStr::from_ptr(ptr) }.to_string_lossy().into_owned())
}

/// A setter's refusal: a value out of its range is Discard, anything else
/// (unknown or unsettable variable) Error.
pub fn out_of_range_discards(error: CallError) -> FmiError {
    if error.is_out_of_range() { FmiError::OutOfRange(error) } else { FmiError::Call(error) }
}

/// Whether the phase is after initialization.
pub fn initialized(phase: Phase) -> bool {
    !matches!(phase, Phase::Instantiated | Phase::InitializationMode)
}

/// SetDebugLogging: `categories` on or off, or all of them if none is named.
///
/// # Safety
/// `categories` points to `n` NUL-terminated strings (or is NULL with n = 0).
pub unsafe fn set_debug_logging(
    instance: &mut Instance,
    logging_on: bool,
    n: usize,
    categories: *const *const c_char,
) -> Result<(), FmiError> {
    // Naming a category twice is no use; more names than categories would
    // only be a count that runs past the array.
    if n > LogCategory::ALL.len() {
        return Err(FmiError::TooManyCategories(n));
    }
    // SAFETY: by the contract above.
    let categories = unsafe { slice(categories, n, "categories") }?;
    let mut indices = Vec::with_capacity(categories.len());
    for &category in categories {
        // SAFETY: by the contract above.
        let name = unsafe { string(category, "a category") }?;
        let category = LogCategory::from_name(&name).ok_or(FmiError::UnknownCategory(name))?;
        indices.push(category.index());
    }
    let enabled = &mut instance.logger.enabled;
    if indices.is_empty() {
        enabled.fill(logging_on);
    }
    indices.into_iter().for_each(|i| enabled[i] = logging_on);
    Ok(())
}

/// GetFMUstate: a new state, or an existing one overwritten in place.
///
/// # Safety
/// `state` is NULL or points to a writable FMU state pointer.
pub unsafe fn get_fmu_state(instance: &mut Instance, state: *mut *mut c_void) -> Result<(), FmiError> {
    calls::fmu_states(&*instance.component)?;
    // SAFETY: by the contract above.
    let state = unsafe { state.as_mut() }.ok_or(FmiError::Null("FMUstate"))?;
    let phase = instance.phase;
    if state.is_null() {
        *state = instance.register(instance.component.snapshot(phase)?);
    } else {
        let snapshot = instance.snapshot(*state)?;
        instance.component.save(phase, snapshot)?;
    }
    Ok(())
}

/// SetFMUstate: the component and the state machine go back to where the
/// state was saved (this is how a master leaves `error` or a failed step).
pub fn set_fmu_state(instance: &mut Instance, state: *mut c_void) -> Result<(), FmiError> {
    calls::fmu_states(&*instance.component)?;
    let snapshot = instance.snapshot(state)?;
    let phase = snapshot.phase;
    if !instance.interface.has(phase) {
        return Err(FmiError::OtherInterface(phase.name()));
    }
    instance.component.restore(snapshot)?;
    instance.phase = phase;
    Ok(())
}

/// FreeFMUstate: NULL, or a pointer to NULL, frees nothing (as free(NULL) does).
///
/// # Safety
/// `state` is NULL or points to a writable FMU state pointer.
pub unsafe fn free_fmu_state(instance: &mut Instance, state: *mut *mut c_void) -> Result<(), FmiError> {
    // SAFETY: by the contract above.
    let Some(state) = (unsafe { state.as_mut() }) else { return Ok(()) };
    if state.is_null() {
        return Ok(());
    }
    instance.snapshot(*state)?;
    instance.states.remove(&(*state as usize));
    // SAFETY: checked live and registered just above, and now deregistered.
    drop(unsafe { Box::from_raw(*state as *mut Snapshot) });
    *state = std::ptr::null_mut();
    Ok(())
}

/// SerializedFMUstateSize.
///
/// # Safety
/// `size` is NULL or writable.
pub unsafe fn serialized_size(instance: &Instance, state: *mut c_void, size: *mut usize) -> Result<(), FmiError> {
    let snapshot = instance.snapshot(state)?;
    // SAFETY: by the contract above.
    *unsafe { size.as_mut() }.ok_or(FmiError::Null("size"))? = snapshot.serialized_size();
    Ok(())
}

/// SerializeFMUstate into a buffer of exactly the serialized size.
///
/// # Safety
/// `bytes` is NULL or points to `size` writable bytes.
pub unsafe fn serialize(instance: &Instance, state: *mut c_void, bytes: *mut u8, size: usize) -> Result<(), FmiError> {
    let snapshot = instance.snapshot(state)?;
    let expected = snapshot.serialized_size();
    if size != expected {
        return Err(FmiError::BufferSize { expected, found: size });
    }
    // SAFETY: by the contract above.
    snapshot.serialize(unsafe { slice_mut(bytes, size, "serializedState") }?);
    Ok(())
}

/// DeSerializeFMUstate: into a new state, or over an existing one.
///
/// # Safety
/// `bytes` is NULL or points to `size` bytes; `state` is NULL or points to
/// a writable FMU state pointer.
pub unsafe fn deserialize(
    instance: &mut Instance,
    bytes: *const u8,
    size: usize,
    state: *mut *mut c_void,
) -> Result<(), FmiError> {
    calls::fmu_states(&*instance.component)?;
    // SAFETY: by the contract above.
    let state = unsafe { state.as_mut() }.ok_or(FmiError::Null("FMUstate"))?;
    let existing = if state.is_null() { None } else { Some(instance.snapshot(*state)? as *mut Snapshot) };
    // SAFETY: by the contract above.
    let snapshot = instance.component.deserialize(unsafe { slice(bytes, size, "serializedState") }?)?;
    if !instance.interface.has(snapshot.phase) {
        return Err(FmiError::OtherInterface(snapshot.phase.name()));
    }
    match existing {
        // SAFETY: checked live above; nothing freed it since.
        Some(existing) => unsafe { *existing = snapshot },
        None => *state = instance.register(snapshot),
    }
    Ok(())
}

/// ExitInitializationMode: whatever was set must make a run; then the
/// first state of the interface's running machine.
pub fn exit_initialization_mode(instance: &mut Instance) -> Result<(), FmiError> {
    if let Some(note) = instance.component.initialize()? {
        instance.logger.log(Status::Ok, LogCategory::MethodChoice, &note);
    }
    instance.phase = match instance.interface {
        Interface::CoSimulation => Phase::StepComplete,
        Interface::ModelExchange => Phase::EventMode,
    };
    Ok(())
}

/// Reset: back to the state just after instantiation.
pub fn reset(instance: &mut Instance) -> Result<(), FmiError> {
    instance.component.reset();
    instance.phase = Phase::Instantiated;
    Ok(())
}

/// DoStep: the step, or its refusal; a step that stopped inside the
/// interval leaves the instance in stepFailed (FMI 3.0: stepDiscarded).
pub fn do_step(instance: &mut Instance, time: f64, step: f64, name: &str) -> Result<(), FmiError> {
    let report = match calls::do_step(&mut *instance.component, time, step) {
        Ok(Some(report)) => report,
        Ok(None) => return Ok(()),
        Err(calls::Stepped::Refused(error)) => return Err(error.into()),
        Err(calls::Stepped::Failed(error)) => {
            instance.phase = Phase::StepFailed;
            return Err(error.into());
        }
    };
    if instance.logger.enabled(LogCategory::MethodChoice) {
        if let Some(choice) = report.chose {
            instance.logger.log(Status::Ok, LogCategory::MethodChoice, &format!("{name}: {choice}"));
        }
        if let Some(moved) = report.moved {
            instance.logger.log(Status::Ok, LogCategory::MethodChoice, &format!("{name}: {moved}"));
        }
        if let Some(held) = report.held {
            instance.logger.log(Status::Ok, LogCategory::MethodChoice, &format!("{name}: {held}"));
        }
    }
    let nudyn::integrate::Stats {
        accepted,
        rejected,
        jacobians,
        exact_jacobians,
        evaluations,
        locating,
        refused_interpolants,
        ..
    } = report.stats;
    if instance.logger.enabled(LogCategory::Calls) {
        let mut message = format!("{name}: {accepted} internal steps taken, {rejected} rejected");
        if locating > 0 {
            message += &format!(
                ", {locating} attempted to locate switches (constraint forces, tendon wraps, activation clamps)"
            );
        }
        if refused_interpolants > 0 {
            message += &format!(
                ", {refused_interpolants} past the communication point taken again at most half as long \
                 (their interpolant strayed from the motion)"
            );
        }
        if jacobians > 0 {
            let by_differences = jacobians - exact_jacobians;
            message += &format!(
                ", W formed {jacobians} times ({exact_jacobians} from exact derivatives, {by_differences} by forward differences)"
            );
        }
        message += &format!(", {evaluations} evaluations of the rates");
        instance.logger.log(Status::Ok, LogCategory::Calls, &message);
    }
    if instance.logger.enabled(LogCategory::StepStatistics) {
        let statistics = serde_json::json!({
            "accepted": accepted, "rejected": rejected, "jacobians": jacobians, "exact_jacobians": exact_jacobians,
            "evaluations": evaluations, "locating": locating, "refused_interpolants": refused_interpolants,
        });
        instance.logger.log(Status::Ok, LogCategory::StepStatistics, &statistics.to_string());
    }
    instance.warning = match report.relaxed {
        Some(relaxed) if relaxed.meets_asked() => {
            // The step meets what was asked: fmi2OK, with what was held and why.
            instance.logger.log(Status::Ok, LogCategory::MethodChoice, &format!("{name}: {relaxed}"));
            None
        }
        relaxed => relaxed.map(|relaxed| format!("{name}: {relaxed}")),
    };
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::process::Command;

    use super::*;

    /// An FMI 3.0 logger that appends each message to the `Vec<String>` its environment points to.
    unsafe extern "C" fn collect(
        environment: fmi3::fmi3InstanceEnvironment,
        _status: fmi3::fmi3Status,
        _category: fmi3::fmi3String,
        message: fmi3::fmi3String,
    ) {
        // SAFETY: the environment is the test's Vec, the message a NUL-terminated string.
        let (messages, message) = unsafe { (&mut *(environment as *mut Vec<String>), CStr::from_ptr(message)) };
        messages.push(message.to_string_lossy().into_owned());
    }

    /// The panic hook prints to the process's stderr, which the test
    /// harness does not capture: the test runs itself in a child process
    /// and reads the child's stderr.
    #[test]
    fn a_panic_goes_to_the_logger_with_its_location_and_never_to_stderr() {
        const CHILD: &str = "NUDYN_FMU_PANIC_CHILD";
        if std::env::var_os(CHILD).is_some() {
            let mut messages = Vec::<String>::new();
            let logger = Logger::fmi3(Some(collect), &mut messages as *mut Vec<String> as *mut c_void, true);
            let made = instantiate(logger, "fmi3InstantiateCoSimulation", || panic!("deliberate"));
            assert!(made.is_null());
            println!("logged: {}", messages.join(" | "));
            return;
        }
        let test = "layer::tests::a_panic_goes_to_the_logger_with_its_location_and_never_to_stderr";
        let child = Command::new(std::env::current_exe().expect("the test binary"))
            .args(["--exact", test, "--nocapture", "--test-threads=1"])
            .env(CHILD, "1")
            .output()
            .expect("the test binary runs");
        let (stdout, stderr) = (String::from_utf8_lossy(&child.stdout), String::from_utf8_lossy(&child.stderr));
        assert!(child.status.success(), "child failed:\n{stdout}\n{stderr}");
        assert!(
            stdout.contains("logged: fmi3InstantiateCoSimulation: internal error (panic at fmu/src/layer.rs:")
                && stdout.contains("): deliberate"),
            "{stdout}"
        );
        assert!(!stderr.contains("deliberate") && !stderr.contains("panicked"), "on stderr:\n{stderr}");
    }
}
