//! The FMI 3.0 functions, co-simulation and model exchange, over the same
//! components, checks and entry path as FMI 2.0 ([`crate::layer`]).
//!
//! FMI 3.0 value references name whole arrays (`theta`), which the contract's
//! table ([`Fmi3Variables`]) turns into the FMI 2.0 value references of
//! their elements; the component then sees the calls it sees from FMI 2.0.
//! `time` (value reference 0) is read here. What nudyn does not provide is
//! refused with the reason: clocks and scheduled execution, configuration
//! mode (there are no structural parameters), event mode in co-simulation
//! (hasEventMode="false"), early return and intermediate updates, types
//! without variables.

// The patterns below are fmi-sys's C constants, named as in fmi3FunctionTypes.h.
#![allow(non_upper_case_globals)]

use std::ffi::c_char;

use fmi_sys::fmi3::*;
use nudyn_contract::fmi3::{ElementDependency, Fmi3Variables, TIME_NAME, TIME_VR, ValueType};

use crate::calls;
use crate::component::CallError;
use crate::layer::{
    self, Buffers, FmiError, Instance, Logger, Version, initialized, out_of_range_discards, slice, slice_mut, string,
};
use crate::load;
use crate::state::{Function, Interface, Phase};

/// The entry path of every fmi3 function that takes an instance.
///
/// # Safety
/// FMI 3.0 calling conventions (the instance is not used concurrently).
unsafe fn enter(
    instance: fmi3Instance,
    function: Function,
    name: &'static str,
    body: impl FnOnce(&mut Instance) -> Result<(), FmiError>,
) -> fmi3Status {
    // SAFETY: by the contract above.
    unsafe { layer::enter(instance, function, name, body) }.code()
}

/// Refuses the value reference `vr` for a function of type `asked`: another
/// type's variable, or no variable at all.
fn refuse(table: &Fmi3Variables, vr: u32, asked: &'static str) -> FmiError {
    if vr == TIME_VR {
        return FmiError::WrongType { vr, name: TIME_NAME.into(), declared: "Float64", asked };
    }
    match table.get(vr) {
        Some(variable) => {
            FmiError::WrongType { vr, name: variable.name.clone(), declared: variable.value_type.name(), asked }
        }
        None => CallError::UnknownValueReference { vr, kind: asked }.into(),
    }
}

/// The value references of a getter or setter of `n_values` values,
/// refused unread if they are more than the values (every variable has at
/// least one): a count past the end of the array is not followed.
///
/// # Safety
/// A non-NULL `ptr` points to `n_value_references` value references.
unsafe fn reference_array<'a>(
    ptr: *const fmi3ValueReference,
    n_value_references: usize,
    n_values: usize,
) -> Result<&'a [u32], FmiError> {
    if n_value_references > n_values {
        return Err(FmiError::MoreReferencesThanValues { n_value_references, n_values });
    }
    // SAFETY: by the contract above.
    unsafe { slice(ptr, n_value_references, "valueReferences") }
}

/// The number of elements of the variable `vr`, checked to be of `asked` type.
fn variable_len(table: &Fmi3Variables, vr: u32, asked: ValueType) -> Result<usize, FmiError> {
    match table.get(vr) {
        Some(variable) if variable.value_type == asked => Ok(variable.len),
        None if vr == TIME_VR && asked == ValueType::Float64 => Ok(1),
        _ => Err(refuse(table, vr, asked.name())),
    }
}

/// Refuses `vrs` unless they are all of `asked` type and name `n_values`
/// values together. Counted, not collected: nothing is allocated before
/// `n_values`, the caller's number, is known to be the arrays' size.
fn check_count(table: &Fmi3Variables, vrs: &[u32], asked: ValueType, n_values: usize) -> Result<(), FmiError> {
    let mut expected = 0usize;
    for &vr in vrs {
        expected = expected.saturating_add(variable_len(table, vr, asked)?);
    }
    if expected != n_values {
        return Err(FmiError::ValueCount { expected, found: n_values });
    }
    Ok(())
}

// The buffers are the instance's (crate::layer); what they do is FMI 3.0's.
impl Buffers {
    /// Fills `elements` with those of `vrs`, checked by [`check_count`] to
    /// be `n_values`, as FMI 2.0 value references (`None`: time).
    fn elements(
        &mut self,
        table: &Fmi3Variables,
        vrs: &[u32],
        asked: ValueType,
        n_values: usize,
    ) -> Result<(), FmiError> {
        check_count(table, vrs, asked, n_values)?;
        self.elements.clear();
        for &vr in vrs {
            match table.get(vr) {
                Some(variable) => self.elements.extend(variable.elements().map(Some)),
                None => self.elements.push(None),
            }
        }
        Ok(())
    }

    /// Those elements as FMI 2.0 value references, refusing `time` (which
    /// cannot be set).
    fn settable(
        &mut self,
        table: &Fmi3Variables,
        vrs: &[u32],
        asked: ValueType,
        n_values: usize,
    ) -> Result<&[u32], FmiError> {
        self.elements(table, vrs, asked, n_values)?;
        self.references.clear();
        for element in &self.elements {
            self.references.push(element.ok_or(FmiError::SetTime)?);
        }
        Ok(&self.references)
    }
}

/// A getter or setter of a type nudyn has no variables of: refused for any
/// value reference, of which only the first is read.
///
/// # Safety
/// A non-NULL `vrs` points to `n` value references.
unsafe fn none_of(table: &Fmi3Variables, vrs: *const u32, n: usize, asked: &'static str) -> Result<(), FmiError> {
    // SAFETY: by the contract above.
    match unsafe { slice(vrs, n.min(1), "valueReferences") }?.first() {
        Some(&vr) => Err(refuse(table, vr, asked)),
        None => Ok(()),
    }
}

#[unsafe(no_mangle)]
pub extern "C" fn fmi3GetVersion() -> *const c_char {
    c"3.0".as_ptr()
}

/// What the two instantiation functions share.
///
/// # Safety
/// FMI 3.0 calling conventions: NUL-terminated strings or NULL.
unsafe fn instantiate(
    function: &'static str,
    interface: Interface,
    instance_name: fmi3String,
    instantiation_token: fmi3String,
    resource_path: fmi3String,
    logger: Logger,
    refusal: Option<&'static str>,
) -> fmi3Instance {
    layer::instantiate(logger, function, || {
        if let Some(reason) = refusal {
            return Err(FmiError::Unsupported(reason));
        }
        // SAFETY: NUL-terminated by the standard when non-NULL.
        unsafe { string(instance_name, "instanceName") }?;
        // SAFETY: as above.
        let token = unsafe { string(instantiation_token, "instantiationToken") }?;
        // SAFETY: as above. FMI 3.0 passes a path, not a URI (§2.3.1).
        let path = unsafe { string(resource_path, "resourcePath") }?;
        let (component, variables) = load::load(std::path::Path::new(&path), &token)?;
        if interface == Interface::ModelExchange && component.continuous_state_count().is_none() {
            return Err(FmiError::NoModelExchange);
        }
        Ok((Version::Fmi3, interface, component, variables))
    })
}

/// # Safety
/// FMI 3.0 calling conventions: pointers as the standard describes them.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3InstantiateModelExchange(
    instance_name: fmi3String,
    instantiation_token: fmi3String,
    resource_path: fmi3String,
    _visible: fmi3Boolean,
    logging_on: fmi3Boolean,
    instance_environment: fmi3InstanceEnvironment,
    log_message: fmi3LogMessageCallback,
) -> fmi3Instance {
    let logger = Logger::fmi3(log_message, instance_environment, logging_on);
    let function = "fmi3InstantiateModelExchange";
    // SAFETY: by the contract above.
    unsafe {
        instantiate(function, Interface::ModelExchange, instance_name, instantiation_token, resource_path, logger, None)
    }
}

/// # Safety
/// FMI 3.0 calling conventions: pointers as the standard describes them.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
    instance_name: fmi3String,
    instantiation_token: fmi3String,
    resource_path: fmi3String,
    _visible: fmi3Boolean,
    logging_on: fmi3Boolean,
    event_mode_used: fmi3Boolean,
    _early_return_allowed: fmi3Boolean,
    _required_intermediate_variables: *const fmi3ValueReference,
    _n_required_intermediate_variables: usize,
    instance_environment: fmi3InstanceEnvironment,
    log_message: fmi3LogMessageCallback,
    _intermediate_update: fmi3IntermediateUpdateCallback,
) -> fmi3Instance {
    let logger = Logger::fmi3(log_message, instance_environment, logging_on);
    // Early return is never needed: doStep always completes or discards.
    let refusal = event_mode_used.then_some(
        "eventModeUsed = true, but the FMU declares hasEventMode=\"false\": it has no events, \
         so co-simulation runs in step mode only",
    );
    let function = "fmi3InstantiateCoSimulation";
    // SAFETY: by the contract above.
    unsafe {
        instantiate(
            function,
            Interface::CoSimulation,
            instance_name,
            instantiation_token,
            resource_path,
            logger,
            refusal,
        )
    }
}

/// # Safety
/// FMI 3.0 calling conventions: pointers as the standard describes them.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3InstantiateScheduledExecution(
    _instance_name: fmi3String,
    _instantiation_token: fmi3String,
    _resource_path: fmi3String,
    _visible: fmi3Boolean,
    logging_on: fmi3Boolean,
    instance_environment: fmi3InstanceEnvironment,
    log_message: fmi3LogMessageCallback,
    _clock_update: fmi3ClockUpdateCallback,
    _lock_preemption: fmi3LockPreemptionCallback,
    _unlock_preemption: fmi3UnlockPreemptionCallback,
) -> fmi3Instance {
    let logger = Logger::fmi3(log_message, instance_environment, logging_on);
    layer::instantiate(logger, "fmi3InstantiateScheduledExecution", || {
        Err(FmiError::Unsupported(
            "scheduled execution is not provided: the modelDescription has no <ScheduledExecution>",
        ))
    })
}

/// # Safety
/// FMI 3.0 calling conventions. A NULL, freed or foreign `instance` is ignored.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3FreeInstance(instance: fmi3Instance) {
    // SAFETY: every state allows fmi3FreeInstance; by the FMI 3.0 calling conventions.
    unsafe { layer::free(instance) }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetDebugLogging(
    instance: fmi3Instance,
    logging_on: fmi3Boolean,
    n_categories: usize,
    categories: *const fmi3String,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::SetDebugLogging, "fmi3SetDebugLogging", |instance| {
            layer::set_debug_logging(instance, logging_on, n_categories, categories)
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3EnterInitializationMode(
    instance: fmi3Instance,
    tolerance_defined: fmi3Boolean,
    tolerance: fmi3Float64,
    start_time: fmi3Float64,
    stop_time_defined: fmi3Boolean,
    stop_time: fmi3Float64,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::EnterInitializationMode, "fmi3EnterInitializationMode", |instance| {
            let tolerance = tolerance_defined.then_some(tolerance);
            let stop_time = stop_time_defined.then_some(stop_time);
            calls::setup_experiment(&mut *instance.component, tolerance, start_time, stop_time)?;
            instance.phase = Phase::InitializationMode;
            Ok(())
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3ExitInitializationMode(instance: fmi3Instance) -> fmi3Status {
    unsafe {
        enter(instance, Function::ExitInitializationMode, "fmi3ExitInitializationMode", |instance| {
            layer::exit_initialization_mode(instance)
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3EnterEventMode(instance: fmi3Instance) -> fmi3Status {
    unsafe {
        enter(instance, Function::EnterEventMode, "fmi3EnterEventMode", |instance| {
            instance.phase = Phase::EventMode;
            Ok(())
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3Terminate(instance: fmi3Instance) -> fmi3Status {
    unsafe {
        enter(instance, Function::Terminate, "fmi3Terminate", |instance| {
            instance.phase = Phase::Terminated;
            Ok(())
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3Reset(instance: fmi3Instance) -> fmi3Status {
    unsafe { enter(instance, Function::Reset, "fmi3Reset", layer::reset) }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetFloat64(
    instance: fmi3Instance,
    value_references: *const fmi3ValueReference,
    n_value_references: usize,
    values: *mut fmi3Float64,
    n_values: usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::GetReal, "fmi3GetFloat64", |instance| {
            let vrs = reference_array(value_references, n_value_references, n_values)?;
            let buffers = &mut instance.fmi3_buffers;
            buffers.elements(&instance.fmi3, vrs, ValueType::Float64, n_values)?;
            let values = slice_mut(values, n_values, "values")?;
            buffers.references.clear();
            buffers.references.extend(buffers.elements.iter().flatten());
            buffers.reals.clear();
            buffers.reals.resize(buffers.references.len(), 0.0);
            let warning = calls::get_real(&mut *instance.component, &buffers.references, &mut buffers.reals)?;
            instance.warning = warning.map(|w| format!("fmi3GetFloat64: {w}"));
            let mut read = buffers.reals.iter();
            for (value, element) in values.iter_mut().zip(&buffers.elements) {
                *value = match element {
                    Some(_) => *read.next().expect("one value per Real element"),
                    None => instance.component.time(),
                };
            }
            Ok(())
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetFloat64(
    instance: fmi3Instance,
    value_references: *const fmi3ValueReference,
    n_value_references: usize,
    values: *const fmi3Float64,
    n_values: usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::SetReal, "fmi3SetFloat64", |instance| {
            let vrs = reference_array(value_references, n_value_references, n_values)?;
            let reals = instance.fmi3_buffers.settable(&instance.fmi3, vrs, ValueType::Float64, n_values)?;
            let values = slice(values, n_values, "values")?;
            let initialized = initialized(instance.phase);
            calls::set_real(&mut *instance.component, reals, values, initialized).map_err(out_of_range_discards)
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetInt64(
    instance: fmi3Instance,
    value_references: *const fmi3ValueReference,
    n_value_references: usize,
    values: *mut fmi3Int64,
    n_values: usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::GetInteger, "fmi3GetInt64", |instance| {
            let vrs = reference_array(value_references, n_value_references, n_values)?;
            let integers = instance.fmi3_buffers.settable(&instance.fmi3, vrs, ValueType::Enumeration, n_values)?;
            let values = slice_mut(values, n_values, "values")?;
            let mut read = vec![0; integers.len()];
            instance.component.get_integer(integers, &mut read)?;
            values.iter_mut().zip(read).for_each(|(value, read)| *value = i64::from(read));
            Ok(())
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetInt64(
    instance: fmi3Instance,
    value_references: *const fmi3ValueReference,
    n_value_references: usize,
    values: *const fmi3Int64,
    n_values: usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::SetInteger, "fmi3SetInt64", |instance| {
            let vrs = reference_array(value_references, n_value_references, n_values)?;
            let integers = instance.fmi3_buffers.settable(&instance.fmi3, vrs, ValueType::Enumeration, n_values)?;
            let values = slice(values, n_values, "values")?;
            let mut narrowed = Vec::with_capacity(values.len());
            for (&vr, &value) in integers.iter().zip(values) {
                let name = instance.fmi3.iter().find(|v| v.value_type == ValueType::Enumeration && v.first == vr);
                let name = name.map_or_else(String::new, |v| v.name.clone());
                narrowed.push(i32::try_from(value).map_err(|_| FmiError::EnumerationValue { name, value })?);
            }
            let initialized = initialized(instance.phase);
            instance.component.set_integer(integers, &narrowed, initialized).map_err(out_of_range_discards)
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetBoolean(
    instance: fmi3Instance,
    value_references: *const fmi3ValueReference,
    n_value_references: usize,
    values: *mut fmi3Boolean,
    n_values: usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::GetBoolean, "fmi3GetBoolean", |instance| {
            let vrs = reference_array(value_references, n_value_references, n_values)?;
            let booleans = instance.fmi3_buffers.settable(&instance.fmi3, vrs, ValueType::Boolean, n_values)?;
            let values = slice_mut(values, n_values, "values")?;
            let mut read = vec![false; booleans.len()];
            instance.component.get_boolean(booleans, &mut read)?;
            values.copy_from_slice(&read);
            Ok(())
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetBoolean(
    instance: fmi3Instance,
    value_references: *const fmi3ValueReference,
    n_value_references: usize,
    values: *const fmi3Boolean,
    n_values: usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::SetBoolean, "fmi3SetBoolean", |instance| {
            let vrs = reference_array(value_references, n_value_references, n_values)?;
            let booleans = instance.fmi3_buffers.settable(&instance.fmi3, vrs, ValueType::Boolean, n_values)?;
            // Read as bytes: a C bool that is neither 0 nor 1 is true, not undefined behaviour.
            let values = slice(values as *const u8, n_values, "values")?;
            let flags: Vec<bool> = values.iter().map(|&v| v != 0).collect();
            Ok(instance.component.set_boolean(booleans, &flags, initialized(instance.phase))?)
        })
    }
}

/// Getters and setters of the types nudyn has no variables of: any value
/// reference is refused (naming the variable's real type, if it has one).
macro_rules! no_variables_of_type {
    ($($function:ident, $kind:ident, $table:ident, $type_name:literal, $value:ty;)+) => {$(
        /// # Safety
        /// FMI 3.0 calling conventions.
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn $function(
            instance: fmi3Instance,
            value_references: *const fmi3ValueReference,
            n_value_references: usize,
            _values: $value,
            _n_values: usize,
        ) -> fmi3Status {
            unsafe {
                enter(instance, Function::$table, stringify!($function), |instance| {
                    none_of(&instance.fmi3, value_references, n_value_references, $type_name)
                })
            }
        }
    )+};
}

no_variables_of_type! {
    fmi3GetFloat32, get, GetReal, "Float32", *mut fmi3Float32;
    fmi3GetInt8, get, GetInteger, "Int8", *mut fmi3Int8;
    fmi3GetUInt8, get, GetInteger, "UInt8", *mut fmi3UInt8;
    fmi3GetInt16, get, GetInteger, "Int16", *mut fmi3Int16;
    fmi3GetUInt16, get, GetInteger, "UInt16", *mut fmi3UInt16;
    fmi3GetInt32, get, GetInteger, "Int32", *mut fmi3Int32;
    fmi3GetUInt32, get, GetInteger, "UInt32", *mut fmi3UInt32;
    fmi3GetUInt64, get, GetInteger, "UInt64", *mut fmi3UInt64;
    fmi3GetString, get, GetString, "String", *mut fmi3String;
    fmi3SetFloat32, set, SetReal, "Float32", *const fmi3Float32;
    fmi3SetInt8, set, SetInteger, "Int8", *const fmi3Int8;
    fmi3SetUInt8, set, SetInteger, "UInt8", *const fmi3UInt8;
    fmi3SetInt16, set, SetInteger, "Int16", *const fmi3Int16;
    fmi3SetUInt16, set, SetInteger, "UInt16", *const fmi3UInt16;
    fmi3SetInt32, set, SetInteger, "Int32", *const fmi3Int32;
    fmi3SetUInt32, set, SetInteger, "UInt32", *const fmi3UInt32;
    fmi3SetUInt64, set, SetInteger, "UInt64", *const fmi3UInt64;
    fmi3SetString, set, SetString, "String", *const fmi3String;
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetBinary(
    instance: fmi3Instance,
    value_references: *const fmi3ValueReference,
    n_value_references: usize,
    _value_sizes: *mut usize,
    _values: *mut fmi3Binary,
    _n_values: usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::GetString, "fmi3GetBinary", |instance| {
            none_of(&instance.fmi3, value_references, n_value_references, "Binary")
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetBinary(
    instance: fmi3Instance,
    value_references: *const fmi3ValueReference,
    n_value_references: usize,
    _value_sizes: *const usize,
    _values: *const fmi3Binary,
    _n_values: usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::SetString, "fmi3SetBinary", |instance| {
            none_of(&instance.fmi3, value_references, n_value_references, "Binary")
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetClock(
    instance: fmi3Instance,
    value_references: *const fmi3ValueReference,
    n_value_references: usize,
    _values: *mut fmi3Clock,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::GetReal, "fmi3GetClock", |instance| {
            none_of(&instance.fmi3, value_references, n_value_references, "Clock")
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetClock(
    instance: fmi3Instance,
    value_references: *const fmi3ValueReference,
    n_value_references: usize,
    _values: *const fmi3Clock,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::SetReal, "fmi3SetClock", |instance| {
            none_of(&instance.fmi3, value_references, n_value_references, "Clock")
        })
    }
}

/// The clock functions: there are no clocks, so any value reference is refused.
macro_rules! no_clocks {
    ($($function:ident($($argument:ident: $type:ty),*);)+) => {$(
        /// # Safety
        /// FMI 3.0 calling conventions.
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn $function(
            instance: fmi3Instance,
            value_references: *const fmi3ValueReference,
            n_value_references: usize,
            $($argument: $type),*
        ) -> fmi3Status {
            unsafe {
                enter(instance, Function::NotProvided, stringify!($function), |instance| {
                    none_of(&instance.fmi3, value_references, n_value_references, "Clock")
                })
            }
        }
    )+};
}

no_clocks! {
    fmi3GetIntervalDecimal(_intervals: *mut fmi3Float64, _qualifiers: *mut fmi3IntervalQualifier);
    fmi3GetIntervalFraction(
        _counters: *mut fmi3UInt64,
        _resolutions: *mut fmi3UInt64,
        _qualifiers: *mut fmi3IntervalQualifier
    );
    fmi3GetShiftDecimal(_shifts: *mut fmi3Float64);
    fmi3GetShiftFraction(_counters: *mut fmi3UInt64, _resolutions: *mut fmi3UInt64);
    fmi3SetIntervalDecimal(_intervals: *const fmi3Float64);
    fmi3SetIntervalFraction(_counters: *const fmi3UInt64, _resolutions: *const fmi3UInt64);
    fmi3SetShiftDecimal(_shifts: *const fmi3Float64);
    fmi3SetShiftFraction(_counters: *const fmi3UInt64, _resolutions: *const fmi3UInt64);
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetNumberOfVariableDependencies(
    instance: fmi3Instance,
    value_reference: fmi3ValueReference,
    n_dependencies: *mut usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::GetVariableDependencies, "fmi3GetNumberOfVariableDependencies", |instance| {
            let n = n_dependencies.as_mut().ok_or(FmiError::Null("nDependencies"))?;
            *n = unknown_dependencies(instance, value_reference)?.len();
            Ok(())
        })
    }
}

/// The element dependencies of the unknown `vr`, or why it has none to give.
fn unknown_dependencies(instance: &Instance, vr: u32) -> Result<Vec<ElementDependency>, FmiError> {
    let table = &instance.fmi3;
    match table.element_dependencies(vr, |element| instance.component.dependencies(element)) {
        Some(list) => Ok(list),
        None if vr == TIME_VR || table.get(vr).is_some() => Err(FmiError::Unsupported(
            "dependencies are given of outputs, continuous-state derivatives and event indicators only (FMI 3.0 §2.2.10)",
        )),
        None => Err(CallError::UnknownValueReference { vr, kind: "any" }.into()),
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetVariableDependencies(
    instance: fmi3Instance,
    dependent: fmi3ValueReference,
    element_indices_of_dependent: *mut usize,
    independents: *mut fmi3ValueReference,
    element_indices_of_independents: *mut usize,
    dependency_kinds: *mut fmi3DependencyKind,
    n_dependencies: usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::GetVariableDependencies, "fmi3GetVariableDependencies", |instance| {
            let list = unknown_dependencies(instance, dependent)?;
            if list.len() != n_dependencies {
                return Err(FmiError::ValueCount { expected: list.len(), found: n_dependencies });
            }
            let elements = slice_mut(element_indices_of_dependent, n_dependencies, "elementIndicesOfDependent")?;
            let knowns = slice_mut(independents, n_dependencies, "independents")?;
            let known_elements =
                slice_mut(element_indices_of_independents, n_dependencies, "elementIndicesOfIndependents")?;
            let kinds = slice_mut(dependency_kinds, n_dependencies, "dependencyKinds")?;
            for (i, dependency) in list.into_iter().enumerate() {
                elements[i] = dependency.element;
                knowns[i] = dependency.known;
                known_elements[i] = dependency.known_element;
                kinds[i] = fmi3DependencyKind_fmi3Dependent;
            }
            Ok(())
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetFMUState(instance: fmi3Instance, state: *mut fmi3FMUState) -> fmi3Status {
    unsafe { enter(instance, Function::GetFmuState, "fmi3GetFMUState", |i| layer::get_fmu_state(i, state)) }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetFMUState(instance: fmi3Instance, state: fmi3FMUState) -> fmi3Status {
    unsafe { enter(instance, Function::SetFmuState, "fmi3SetFMUState", |i| layer::set_fmu_state(i, state)) }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3FreeFMUState(instance: fmi3Instance, state: *mut fmi3FMUState) -> fmi3Status {
    unsafe { enter(instance, Function::FreeFmuState, "fmi3FreeFMUState", |i| layer::free_fmu_state(i, state)) }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SerializedFMUStateSize(
    instance: fmi3Instance,
    state: fmi3FMUState,
    size: *mut usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::SerializedFmuStateSize, "fmi3SerializedFMUStateSize", |i| {
            layer::serialized_size(i, state, size)
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SerializeFMUState(
    instance: fmi3Instance,
    state: fmi3FMUState,
    serialized_state: *mut fmi3Byte,
    size: usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::SerializeFmuState, "fmi3SerializeFMUState", |i| {
            layer::serialize(i, state, serialized_state, size)
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3DeserializeFMUState(
    instance: fmi3Instance,
    serialized_state: *const fmi3Byte,
    size: usize,
    state: *mut fmi3FMUState,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::DeSerializeFmuState, "fmi3DeserializeFMUState", |i| {
            layer::deserialize(i, serialized_state, size, state)
        })
    }
}

/// The FMI 2.0 value references of the elements of the Float64 variables
/// `vrs`, the `of` of a partial derivative, whose `what` (nSeed or
/// nSensitivity) must be their number of elements.
fn partial_elements(
    table: &Fmi3Variables,
    vrs: &[u32],
    (what, n): (&'static str, usize),
    of: &'static str,
) -> Result<Vec<u32>, FmiError> {
    let mut expected = 0usize;
    for &vr in vrs {
        if vr == TIME_VR {
            return Err(FmiError::TimeInPartial);
        }
        expected = expected.saturating_add(variable_len(table, vr, ValueType::Float64)?);
    }
    if expected != n {
        return Err(FmiError::PartialCount { what, of, expected, found: n });
    }
    Ok(vrs.iter().flat_map(|&vr| table.get(vr).expect("checked above").elements()).collect())
}

/// A C array and its length.
type Array<T> = (T, usize);

/// fmi3GetDirectionalDerivative (seed along the knowns, sensitivity along
/// the unknowns) and fmi3GetAdjointDerivative (the other way round).
///
/// # Safety
/// FMI 3.0 calling conventions: each non-NULL pointer to its count of elements.
unsafe fn partial_derivatives(
    instance: fmi3Instance,
    (partial, name): (calls::Partial, &'static str),
    (unknowns, n_unknowns): Array<*const fmi3ValueReference>,
    (knowns, n_knowns): Array<*const fmi3ValueReference>,
    (seed, n_seed): Array<*const fmi3Float64>,
    (sensitivity, n_sensitivity): Array<*mut fmi3Float64>,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::GetDirectionalDerivative, name, |instance| {
            instance.component.partials()?;
            let (along_knowns, along_unknowns) = match partial {
                calls::Partial::Directional => (("nSeed", n_seed), ("nSensitivity", n_sensitivity)),
                calls::Partial::Adjoint => (("nSensitivity", n_sensitivity), ("nSeed", n_seed)),
            };
            let unknowns = reference_array(unknowns, n_unknowns, along_unknowns.1)?;
            let knowns = reference_array(knowns, n_knowns, along_knowns.1)?;
            let unknowns = partial_elements(&instance.fmi3, unknowns, along_unknowns, "unknowns")?;
            let knowns = partial_elements(&instance.fmi3, knowns, along_knowns, "knowns")?;
            let seed = slice(seed, n_seed, "seed")?;
            let sensitivity = slice_mut(sensitivity, n_sensitivity, "sensitivity")?;
            let component = &mut *instance.component;
            Ok(calls::partial_derivatives(component, partial, &unknowns, &knowns, ("seed", seed), sensitivity)?)
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetDirectionalDerivative(
    instance: fmi3Instance,
    unknowns: *const fmi3ValueReference,
    n_unknowns: usize,
    knowns: *const fmi3ValueReference,
    n_knowns: usize,
    seed: *const fmi3Float64,
    n_seed: usize,
    sensitivity: *mut fmi3Float64,
    n_sensitivity: usize,
) -> fmi3Status {
    let partial = (calls::Partial::Directional, "fmi3GetDirectionalDerivative");
    let (unknowns, knowns) = ((unknowns, n_unknowns), (knowns, n_knowns));
    // SAFETY: FMI 3.0 calling conventions.
    unsafe { partial_derivatives(instance, partial, unknowns, knowns, (seed, n_seed), (sensitivity, n_sensitivity)) }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetAdjointDerivative(
    instance: fmi3Instance,
    unknowns: *const fmi3ValueReference,
    n_unknowns: usize,
    knowns: *const fmi3ValueReference,
    n_knowns: usize,
    seed: *const fmi3Float64,
    n_seed: usize,
    sensitivity: *mut fmi3Float64,
    n_sensitivity: usize,
) -> fmi3Status {
    let partial = (calls::Partial::Adjoint, "fmi3GetAdjointDerivative");
    let (unknowns, knowns) = ((unknowns, n_unknowns), (knowns, n_knowns));
    // SAFETY: FMI 3.0 calling conventions.
    unsafe { partial_derivatives(instance, partial, unknowns, knowns, (seed, n_seed), (sensitivity, n_sensitivity)) }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3EnterConfigurationMode(instance: fmi3Instance) -> fmi3Status {
    unsafe {
        enter(instance, Function::NotProvided, "fmi3EnterConfigurationMode", |_| {
            Err(FmiError::Unsupported("configuration mode: the FMU has no structural parameters"))
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3ExitConfigurationMode(instance: fmi3Instance) -> fmi3Status {
    unsafe {
        enter(instance, Function::NotProvided, "fmi3ExitConfigurationMode", |_| {
            Err(FmiError::Unsupported("configuration mode: the FMU has no structural parameters"))
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3EvaluateDiscreteStates(instance: fmi3Instance) -> fmi3Status {
    unsafe {
        enter(instance, Function::NotProvided, "fmi3EvaluateDiscreteStates", |_| {
            Err(FmiError::Unsupported("providesEvaluateDiscreteStates=\"false\": the FMU has no discrete states"))
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3UpdateDiscreteStates(
    instance: fmi3Instance,
    discrete_states_need_update: *mut fmi3Boolean,
    terminate_simulation: *mut fmi3Boolean,
    nominals_of_continuous_states_changed: *mut fmi3Boolean,
    values_of_continuous_states_changed: *mut fmi3Boolean,
    next_event_time_defined: *mut fmi3Boolean,
    next_event_time: *mut fmi3Float64,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::NewDiscreteStates, "fmi3UpdateDiscreteStates", |instance| {
            let flags = [
                (discrete_states_need_update, "discreteStatesNeedUpdate"),
                (terminate_simulation, "terminateSimulation"),
                (nominals_of_continuous_states_changed, "nominalsOfContinuousStatesChanged"),
                (values_of_continuous_states_changed, "valuesOfContinuousStatesChanged"),
                (next_event_time_defined, "nextEventTimeDefined"),
            ];
            let next_event_time = next_event_time.as_mut().ok_or(FmiError::Null("nextEventTime"))?;
            let mut outputs = Vec::with_capacity(flags.len());
            for (flag, name) in flags {
                outputs.push(flag.as_mut().ok_or(FmiError::Null(name))?);
            }
            // The constraint mode the state gives holds until the next event;
            // no discrete states of the host's change, no time events. A mode set
            // anew says the states changed, as fmi2NewDiscreteStates does (fmi2.rs).
            let mode_set = instance.component.update_discrete_states()?;
            for (flag, (_, name)) in outputs.into_iter().zip(flags) {
                *flag = mode_set && name == "valuesOfContinuousStatesChanged";
            }
            *next_event_time = 0.0;
            Ok(())
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3EnterContinuousTimeMode(instance: fmi3Instance) -> fmi3Status {
    unsafe {
        enter(instance, Function::EnterContinuousTimeMode, "fmi3EnterContinuousTimeMode", |instance| {
            instance.phase = Phase::ContinuousTimeMode;
            Ok(())
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3CompletedIntegratorStep(
    instance: fmi3Instance,
    _no_set_fmu_state_prior_to_current_point: fmi3Boolean,
    enter_event_mode: *mut fmi3Boolean,
    terminate_simulation: *mut fmi3Boolean,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::CompletedIntegratorStep, "fmi3CompletedIntegratorStep", |_| {
            let enter_event_mode = enter_event_mode.as_mut().ok_or(FmiError::Null("enterEventMode"))?;
            let terminate_simulation = terminate_simulation.as_mut().ok_or(FmiError::Null("terminateSimulation"))?;
            // No step events.
            *enter_event_mode = false;
            *terminate_simulation = false;
            Ok(())
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetTime(instance: fmi3Instance, time: fmi3Float64) -> fmi3Status {
    unsafe {
        enter(instance, Function::SetTime, "fmi3SetTime", |instance| {
            Ok(calls::set_time(&mut *instance.component, time)?)
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetContinuousStates(
    instance: fmi3Instance,
    continuous_states: *const fmi3Float64,
    n_continuous_states: usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::SetContinuousStates, "fmi3SetContinuousStates", |instance| {
            // The count first: no slice is made of a length that is not the array's.
            calls::state_count(&*instance.component, "x", n_continuous_states)?;
            let x = slice(continuous_states, n_continuous_states, "continuousStates")?;
            calls::set_continuous_states(&mut *instance.component, x).map_err(out_of_range_discards)
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetContinuousStateDerivatives(
    instance: fmi3Instance,
    derivatives: *mut fmi3Float64,
    n_continuous_states: usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::GetDerivatives, "fmi3GetContinuousStateDerivatives", |instance| {
            // The count first: no slice is made of a length that is not the array's.
            calls::state_count(&*instance.component, "derivatives", n_continuous_states)?;
            let derivatives = slice_mut(derivatives, n_continuous_states, "derivatives")?;
            Ok(calls::get_derivatives(&mut *instance.component, derivatives)?)
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetEventIndicators(
    instance: fmi3Instance,
    event_indicators: *mut fmi3Float64,
    n_event_indicators: usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::GetEventIndicators, "fmi3GetEventIndicators", |instance| {
            // The same values as the variable the modelDescription lists as <EventIndicator>.
            let expected = instance.component.event_indicator_count();
            calls::event_indicator_count(&*instance.component, n_event_indicators, expected)?;
            let indicators = slice_mut(event_indicators, n_event_indicators, "eventIndicators")?;
            Ok(calls::get_event_indicators(&mut *instance.component, indicators)?)
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetContinuousStates(
    instance: fmi3Instance,
    continuous_states: *mut fmi3Float64,
    n_continuous_states: usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::GetContinuousStates, "fmi3GetContinuousStates", |instance| {
            // The count first: no slice is made of a length that is not the array's.
            calls::state_count(&*instance.component, "x", n_continuous_states)?;
            let x = slice_mut(continuous_states, n_continuous_states, "continuousStates")?;
            Ok(calls::get_continuous_states(&*instance.component, x)?)
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetNominalsOfContinuousStates(
    instance: fmi3Instance,
    nominals: *mut fmi3Float64,
    n_continuous_states: usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::GetNominalsOfContinuousStates, "fmi3GetNominalsOfContinuousStates", |instance| {
            // The count first: no slice is made of a length that is not the array's.
            calls::state_count(&*instance.component, "x_nominal", n_continuous_states)?;
            let nominals = slice_mut(nominals, n_continuous_states, "nominals")?;
            Ok(calls::get_nominals(&*instance.component, nominals)?)
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetNumberOfEventIndicators(
    instance: fmi3Instance,
    n_event_indicators: *mut usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::GetNumberOf, "fmi3GetNumberOfEventIndicators", |instance| {
            *n_event_indicators.as_mut().ok_or(FmiError::Null("nEventIndicators"))? =
                instance.component.event_indicator_count();
            Ok(())
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetNumberOfContinuousStates(
    instance: fmi3Instance,
    n_continuous_states: *mut usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::GetNumberOf, "fmi3GetNumberOfContinuousStates", |instance| {
            let n = n_continuous_states.as_mut().ok_or(FmiError::Null("nContinuousStates"))?;
            *n = instance.component.continuous_state_count().ok_or(CallError::NotProvided("model exchange"))?;
            Ok(())
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3EnterStepMode(instance: fmi3Instance) -> fmi3Status {
    // The state table refuses it in every state: co-simulation never enters event mode here.
    unsafe { enter(instance, Function::EnterStepMode, "fmi3EnterStepMode", |_| Ok(())) }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetOutputDerivatives(
    instance: fmi3Instance,
    value_references: *const fmi3ValueReference,
    n_value_references: usize,
    orders: *const fmi3Int32,
    values: *mut fmi3Float64,
    n_values: usize,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::GetRealOutputDerivatives, "fmi3GetOutputDerivatives", |instance| {
            let vrs = reference_array(value_references, n_value_references, n_values)?;
            let orders = slice(orders, n_value_references, "orders")?;
            let table = &instance.fmi3;
            let reals = instance.fmi3_buffers.settable(table, vrs, ValueType::Float64, n_values)?;
            let element_orders: Vec<i32> = vrs
                .iter()
                .zip(orders)
                .flat_map(|(&vr, &order)| std::iter::repeat_n(order, table.get(vr).map_or(1, |v| v.len)))
                .collect();
            let values = slice_mut(values, n_values, "values")?;
            Ok(calls::get_output_derivatives(&mut *instance.component, reals, &element_orders, values)?)
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3DoStep(
    instance: fmi3Instance,
    current_communication_point: fmi3Float64,
    communication_step_size: fmi3Float64,
    _no_set_fmu_state_prior_to_current_point: fmi3Boolean,
    event_handling_needed: *mut fmi3Boolean,
    terminate_simulation: *mut fmi3Boolean,
    early_return: *mut fmi3Boolean,
    last_successful_time: *mut fmi3Float64,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::DoStep, "fmi3DoStep", |instance| {
            let event_handling_needed = event_handling_needed.as_mut().ok_or(FmiError::Null("eventHandlingNeeded"))?;
            let terminate_simulation = terminate_simulation.as_mut().ok_or(FmiError::Null("terminateSimulation"))?;
            let early_return = early_return.as_mut().ok_or(FmiError::Null("earlyReturn"))?;
            let last_successful_time = last_successful_time.as_mut().ok_or(FmiError::Null("lastSuccessfulTime"))?;
            let result = layer::do_step(instance, current_communication_point, communication_step_size, "fmi3DoStep");
            *event_handling_needed = false;
            *early_return = false;
            *terminate_simulation = instance.component.failed_for_good();
            *last_successful_time = instance.component.time();
            result
        })
    }
}

/// # Safety
/// FMI 3.0 calling conventions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3ActivateModelPartition(
    instance: fmi3Instance,
    _clock_reference: fmi3ValueReference,
    _activation_time: fmi3Float64,
) -> fmi3Status {
    unsafe {
        enter(instance, Function::NotProvided, "fmi3ActivateModelPartition", |_| {
            Err(FmiError::Unsupported(
                "scheduled execution is not provided: the modelDescription has no <ScheduledExecution>",
            ))
        })
    }
}

// The C types used above, named so that a signature mismatch with fmi-sys's
// function-pointer types is a compile error.
const _: [fmi3InstantiateModelExchangeTYPE; 1] = [Some(fmi3InstantiateModelExchange)];
const _: [fmi3InstantiateCoSimulationTYPE; 1] = [Some(fmi3InstantiateCoSimulation)];
const _: [fmi3InstantiateScheduledExecutionTYPE; 1] = [Some(fmi3InstantiateScheduledExecution)];
const _: [fmi3FreeInstanceTYPE; 1] = [Some(fmi3FreeInstance)];
const _: [fmi3SetDebugLoggingTYPE; 1] = [Some(fmi3SetDebugLogging)];
const _: [fmi3EnterInitializationModeTYPE; 1] = [Some(fmi3EnterInitializationMode)];
const _: [fmi3GetFloat64TYPE; 1] = [Some(fmi3GetFloat64)];
const _: [fmi3SetFloat64TYPE; 1] = [Some(fmi3SetFloat64)];
const _: [fmi3GetInt64TYPE; 1] = [Some(fmi3GetInt64)];
const _: [fmi3SetInt64TYPE; 1] = [Some(fmi3SetInt64)];
const _: [fmi3GetBooleanTYPE; 1] = [Some(fmi3GetBoolean)];
const _: [fmi3SetBooleanTYPE; 1] = [Some(fmi3SetBoolean)];
const _: [fmi3GetFloat32TYPE; 1] = [Some(fmi3GetFloat32)];
const _: [fmi3SetUInt64TYPE; 1] = [Some(fmi3SetUInt64)];
const _: [fmi3GetStringTYPE; 1] = [Some(fmi3GetString)];
const _: [fmi3SetStringTYPE; 1] = [Some(fmi3SetString)];
const _: [fmi3GetBinaryTYPE; 1] = [Some(fmi3GetBinary)];
const _: [fmi3SetBinaryTYPE; 1] = [Some(fmi3SetBinary)];
const _: [fmi3GetClockTYPE; 1] = [Some(fmi3GetClock)];
const _: [fmi3SetClockTYPE; 1] = [Some(fmi3SetClock)];
const _: [fmi3GetIntervalFractionTYPE; 1] = [Some(fmi3GetIntervalFraction)];
const _: [fmi3SetShiftFractionTYPE; 1] = [Some(fmi3SetShiftFraction)];
const _: [fmi3GetNumberOfVariableDependenciesTYPE; 1] = [Some(fmi3GetNumberOfVariableDependencies)];
const _: [fmi3GetVariableDependenciesTYPE; 1] = [Some(fmi3GetVariableDependencies)];
const _: [fmi3GetFMUStateTYPE; 1] = [Some(fmi3GetFMUState)];
const _: [fmi3SerializeFMUStateTYPE; 1] = [Some(fmi3SerializeFMUState)];
const _: [fmi3DeserializeFMUStateTYPE; 1] = [Some(fmi3DeserializeFMUState)];
const _: [fmi3GetDirectionalDerivativeTYPE; 1] = [Some(fmi3GetDirectionalDerivative)];
const _: [fmi3GetAdjointDerivativeTYPE; 1] = [Some(fmi3GetAdjointDerivative)];
const _: [fmi3UpdateDiscreteStatesTYPE; 1] = [Some(fmi3UpdateDiscreteStates)];
const _: [fmi3CompletedIntegratorStepTYPE; 1] = [Some(fmi3CompletedIntegratorStep)];
const _: [fmi3GetContinuousStateDerivativesTYPE; 1] = [Some(fmi3GetContinuousStateDerivatives)];
const _: [fmi3GetNominalsOfContinuousStatesTYPE; 1] = [Some(fmi3GetNominalsOfContinuousStates)];
const _: [fmi3GetNumberOfContinuousStatesTYPE; 1] = [Some(fmi3GetNumberOfContinuousStates)];
const _: [fmi3GetOutputDerivativesTYPE; 1] = [Some(fmi3GetOutputDerivatives)];
const _: [fmi3DoStepTYPE; 1] = [Some(fmi3DoStep)];
const _: [fmi3ActivateModelPartitionTYPE; 1] = [Some(fmi3ActivateModelPartition)];
