//! The FMU's platform binary, checked before it is packed: a file that is
//! not a shared library for the platform, or does not export the FMI
//! functions, would make an FMU that fails only in the host, far from the
//! cause.

use object::{Architecture, BinaryFormat, Object, ObjectKind, read::NameOrOrdinal};

/// The functions an FMI 2.0 co-simulation FMU's binary exports (FMI 2.0
/// §2.1 common functions and §4.2 co-simulation functions).
pub const FMI2_CO_SIMULATION_FUNCTIONS: [&str; 34] = [
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
];

/// Checks that `library` is an x86_64 Linux shared library (the FMU's
/// `binaries/linux64`) exporting every FMI 2.0 co-simulation function;
/// otherwise says what it is instead.
pub fn check_linux64_library(library: &[u8]) -> Result<(), String> {
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
        FMI2_CO_SIMULATION_FUNCTIONS.into_iter().filter(|f| !exported.iter().any(|e| e == f.as_bytes())).collect();
    let what = match missing.len() {
        0 => return Ok(()),
        n if n == FMI2_CO_SIMULATION_FUNCTIONS.len() => {
            format!("exports none of the {n} FMI 2.0 co-simulation functions")
        }
        n => format!("does not export {n} of the FMI 2.0 co-simulation functions ({})", missing.join(", ")),
    };
    Err(format!(
        "it is a shared library that {what}; the FMU's binary is the libnudyn_fmu.so \
         that `cargo build --release --workspace` builds"
    ))
}
