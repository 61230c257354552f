//! The FMU's platform binary, checked before it is packed: a file that is
//! not a shared library for the platform, or does not export the FMI
//! functions, would make an FMU that fails only in the host, far from the
//! cause.

use object::{Architecture, BinaryFormat, Object, ObjectKind, ObjectSection, read::NameOrOrdinal};

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

/// A platform an FMU carries a binary for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Platform {
    /// x86-64 Linux: `binaries/linux64/<id>.so`, FMI 3.0 `binaries/x86_64-linux/`.
    Linux64,
    /// x86-64 Windows: `binaries/win64/<id>.dll`, FMI 3.0 `binaries/x86_64-windows/`.
    Win64,
}

impl Platform {
    /// Every platform, in the order FMUs list them.
    pub const ALL: [Platform; 2] = [Platform::Linux64, Platform::Win64];

    /// The FMI 2.0 name of its binaries folder (FMI 2.0 §2.5).
    pub fn fmi2_folder(self) -> &'static str {
        match self {
            Platform::Linux64 => "linux64",
            Platform::Win64 => "win64",
        }
    }

    /// The FMI 3.0 name of its binaries folder (FMI 3.0 §2.5.1.1).
    pub fn fmi3_folder(self) -> &'static str {
        match self {
            Platform::Linux64 => "x86_64-linux",
            Platform::Win64 => "x86_64-windows",
        }
    }

    /// The extension of a shared library on the platform.
    pub fn library_extension(self) -> &'static str {
        match self {
            Platform::Linux64 => "so",
            Platform::Win64 => "dll",
        }
    }

    /// The file cargo writes when it builds the `nudyn_fmu` library for the platform.
    pub fn built_library_name(self) -> &'static str {
        match self {
            Platform::Linux64 => "libnudyn_fmu.so",
            Platform::Win64 => "nudyn_fmu.dll",
        }
    }

    /// What builds it, for messages.
    fn built_by(self) -> &'static str {
        match self {
            Platform::Linux64 => "`cargo build --release --workspace`",
            Platform::Win64 => "scripts/build-windows.sh",
        }
    }

    fn file_kind(self) -> (BinaryFormat, &'static str) {
        match self {
            Platform::Linux64 => (BinaryFormat::Elf, "an x86_64 Linux (ELF) shared library"),
            Platform::Win64 => (BinaryFormat::Pe, "an x86_64 Windows (PE) DLL"),
        }
    }
}

impl std::fmt::Display for Platform {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.fmi2_folder())
    }
}

/// Checks that `library` is a shared library for `platform` exporting every
/// function of the FMI version (`functions`: [`FMI2_FUNCTIONS`] or
/// [`FMI3_FUNCTIONS`], `version` their name); otherwise says what it is instead.
pub fn check_library(platform: Platform, library: &[u8], functions: &[&str], version: &str) -> Result<(), String> {
    let file = object::File::parse(library).map_err(|e| format!("it is not a shared library ({e})"))?;
    let (format, architecture) = (file.format(), file.architecture());
    let (expected_format, expected) = platform.file_kind();
    if (format, architecture) != (expected_format, Architecture::X86_64) {
        return Err(format!("it is a {format:?} file for {architecture:?}, not {expected}"));
    }
    if file.kind() != ObjectKind::Dynamic {
        let format = match format {
            BinaryFormat::Elf => "an ELF",
            BinaryFormat::Pe => "a PE",
            _ => "an object",
        };
        return Err(format!("it is {format} file of kind {:?}, not a shared library", file.kind()));
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
        "it is a shared library that {what}; the FMU's binary is the {} that {} builds",
        platform.built_library_name(),
        platform.built_by()
    ))
}

/// `library` as the FMU carries it: an ELF library without its DWARF
/// sections (`.debug_*`), which a debug build has, or a release build with
/// line tables for a profiler (the release profile has none); a PE DLL as it is
/// (scripts/build-windows.sh strips it). Done here rather than by `strip`:
/// `nudyn export` also runs where binutils are not installed (the wheel).
pub fn without_debug_sections(platform: Platform, library: Vec<u8>) -> Result<Vec<u8>, String> {
    let is_debug = |name: &[u8]| name.starts_with(b".debug_");
    let has_debug_sections = object::File::parse(&library[..])
        .is_ok_and(|file| file.sections().any(|section| section.name_bytes().is_ok_and(is_debug)));
    if platform != Platform::Linux64 || !has_debug_sections {
        return Ok(library);
    }
    let mut builder =
        object::build::elf::Builder::read(&library[..]).map_err(|e| format!("its sections cannot be read ({e})"))?;
    for section in builder.sections.iter_mut() {
        if is_debug(&section.name) {
            section.delete = true;
        }
    }
    builder.delete_orphans();
    let mut stripped = Vec::with_capacity(library.len());
    builder.write(&mut stripped).map_err(|e| format!("it cannot be written without its debug sections ({e})"))?;
    Ok(stripped)
}
