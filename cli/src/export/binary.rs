//! The FMU's platform binary, checked before it is packed: a file that is
//! not a shared library for the platform, or does not export the FMI
//! functions, would make an FMU that fails only in the host, far from the
//! cause.

use object::{Architecture, BinaryFormat, Object, ObjectKind, read::NameOrOrdinal};

/// The functions an FMI 2.0 FMU's binary exports (FMI 2.0 §2.1 common
/// functions, §3.2 model exchange and §4.2 co-simulation functions).
pub const FMI2_FUNCTIONS: [&str; 44] = [
    "fmi2GetTypesPlatform",
    "fmi2GetVersion",
    "fmi2SetDebugLogging",
    "fmi2Instantiate",
    "fmi2FreeInstance",
    "fmi2SetupExperiment",
    "fmi2EnterInitializationMode",
    "fmi2ExitInitializationMode",
    "fmi2Terminate",
    "fmi2Reset",
    "fmi2GetReal",
    "fmi2GetInteger",
    "fmi2GetBoolean",
    "fmi2GetString",
    "fmi2SetReal",
    "fmi2SetInteger",
    "fmi2SetBoolean",
    "fmi2SetString",
    "fmi2GetFMUstate",
    "fmi2SetFMUstate",
    "fmi2FreeFMUstate",
    "fmi2SerializedFMUstateSize",
    "fmi2SerializeFMUstate",
    "fmi2DeSerializeFMUstate",
    "fmi2GetDirectionalDerivative",
    "fmi2SetRealInputDerivatives",
    "fmi2GetRealOutputDerivatives",
    "fmi2DoStep",
    "fmi2CancelStep",
    "fmi2GetStatus",
    "fmi2GetRealStatus",
    "fmi2GetIntegerStatus",
    "fmi2GetBooleanStatus",
    "fmi2GetStringStatus",
    "fmi2EnterEventMode",
    "fmi2NewDiscreteStates",
    "fmi2EnterContinuousTimeMode",
    "fmi2CompletedIntegratorStep",
    "fmi2SetTime",
    "fmi2SetContinuousStates",
    "fmi2GetDerivatives",
    "fmi2GetEventIndicators",
    "fmi2GetContinuousStates",
    "fmi2GetNominalsOfContinuousStates",
];

/// The functions an FMI 3.0 FMU's binary exports: every function of the
/// standard's fmi3FunctionTypes.h (those an FMU does not provide must still
/// be there, and refuse).
pub const FMI3_FUNCTIONS: [&str; 75] = [
    "fmi3ActivateModelPartition",
    "fmi3CompletedIntegratorStep",
    "fmi3DeserializeFMUState",
    "fmi3DoStep",
    "fmi3EnterConfigurationMode",
    "fmi3EnterContinuousTimeMode",
    "fmi3EnterEventMode",
    "fmi3EnterInitializationMode",
    "fmi3EnterStepMode",
    "fmi3EvaluateDiscreteStates",
    "fmi3ExitConfigurationMode",
    "fmi3ExitInitializationMode",
    "fmi3FreeFMUState",
    "fmi3FreeInstance",
    "fmi3GetAdjointDerivative",
    "fmi3GetBinary",
    "fmi3GetBoolean",
    "fmi3GetClock",
    "fmi3GetContinuousStateDerivatives",
    "fmi3GetContinuousStates",
    "fmi3GetDirectionalDerivative",
    "fmi3GetEventIndicators",
    "fmi3GetFMUState",
    "fmi3GetFloat32",
    "fmi3GetFloat64",
    "fmi3GetInt16",
    "fmi3GetInt32",
    "fmi3GetInt64",
    "fmi3GetInt8",
    "fmi3GetIntervalDecimal",
    "fmi3GetIntervalFraction",
    "fmi3GetNominalsOfContinuousStates",
    "fmi3GetNumberOfContinuousStates",
    "fmi3GetNumberOfEventIndicators",
    "fmi3GetNumberOfVariableDependencies",
    "fmi3GetOutputDerivatives",
    "fmi3GetShiftDecimal",
    "fmi3GetShiftFraction",
    "fmi3GetString",
    "fmi3GetUInt16",
    "fmi3GetUInt32",
    "fmi3GetUInt64",
    "fmi3GetUInt8",
    "fmi3GetVariableDependencies",
    "fmi3GetVersion",
    "fmi3InstantiateCoSimulation",
    "fmi3InstantiateModelExchange",
    "fmi3InstantiateScheduledExecution",
    "fmi3Reset",
    "fmi3SerializeFMUState",
    "fmi3SerializedFMUStateSize",
    "fmi3SetBinary",
    "fmi3SetBoolean",
    "fmi3SetClock",
    "fmi3SetContinuousStates",
    "fmi3SetDebugLogging",
    "fmi3SetFMUState",
    "fmi3SetFloat32",
    "fmi3SetFloat64",
    "fmi3SetInt16",
    "fmi3SetInt32",
    "fmi3SetInt64",
    "fmi3SetInt8",
    "fmi3SetIntervalDecimal",
    "fmi3SetIntervalFraction",
    "fmi3SetShiftDecimal",
    "fmi3SetShiftFraction",
    "fmi3SetString",
    "fmi3SetTime",
    "fmi3SetUInt16",
    "fmi3SetUInt32",
    "fmi3SetUInt64",
    "fmi3SetUInt8",
    "fmi3Terminate",
    "fmi3UpdateDiscreteStates",
];

/// Checks that `library` is an x86_64 Linux shared library (the FMU's
/// `binaries/linux64` or `binaries/x86_64-linux`) exporting every function
/// of the FMI version (`functions`: [`FMI2_FUNCTIONS`] or
/// [`FMI3_FUNCTIONS`], `version` their name); otherwise says what it is instead.
pub fn check_linux64_library(library: &[u8], functions: &[&str], version: &str) -> Result<(), String> {
    let file = object::File::parse(library).map_err(|e| format!("it is not a shared library ({e})"))?;
    let (format, architecture) = (file.format(), file.architecture());
    if (format, architecture) != (BinaryFormat::Elf, Architecture::X86_64) {
        return Err(format!("it is a {format:?} file for {architecture:?}, not an x86_64 Linux (ELF) shared library"));
    }
    if file.kind() != ObjectKind::Dynamic {
        return Err(format!("it is an ELF file of kind {:?}, not a shared library", file.kind()));
    }
    let exports = file.exports().map_err(|e| format!("its exported symbols cannot be read ({e})"))?;
    let mut exported: Vec<Vec<u8>> = Vec::new();
    for export in exports {
        let export = export.map_err(|e| format!("its exported symbols cannot be read ({e})"))?;
        if let NameOrOrdinal::Name(name) = export.name() {
            exported.push(name.to_vec());
        }
    }
    let missing: Vec<&str> =
        functions.iter().copied().filter(|f| !exported.iter().any(|e| e == f.as_bytes())).collect();
    let what = match missing.len() {
        0 => return Ok(()),
        n if n == functions.len() => format!("exports none of the {n} {version} functions"),
        n => format!("does not export {n} of the {version} functions ({})", missing.join(", ")),
    };
    Err(format!(
        "it is a shared library that {what}; the FMU's binary is the libnudyn_fmu.so \
         that `cargo build --release --workspace` builds"
    ))
}
