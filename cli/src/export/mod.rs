//! `nudyn export`: the FMU archive. The variables, value references,
//! defaults, capability flags, log categories and GUID come from the
//! `nudyn-contract` crate, which the FMU binary serves from; this module
//! only writes them down as an FMI 2.0 or FMI 3.0 `modelDescription.xml`
//! (with the descriptions a person reads) and zips it with the binary and
//! the resource file. One binary serves both versions (it exports the fmi2
//! and the fmi3 functions).

pub mod binary;
pub mod controller;
mod documentation;
mod fmi3;
pub mod plant;
pub mod system;
pub mod variable_table;

use std::io::Write;
use std::path::{Path, PathBuf};

use modeldescription as md;
use nudyn_contract::capabilities::Capabilities;
use nudyn_contract::log::LogCategory;
use nudyn_contract::resource::Resource;
use nudyn_contract::variable::{Causality, Kind, Range, Variability};
use nudyn_contract::{DEFAULT_STEP_SIZE, DEFAULT_STOP_TIME};

pub use binary::Platform;

/// The most knowns a `<ModelStructure>` entry lists. An unknown that depends
/// on more is written without `dependencies`, which declares it dependent on
/// every known: the exact lists grow with the square of the dofs (a
/// 4000-link chain's FMI 2.0 description took 588 MB with them), and a list
/// that long tells a host little. The FMU's fmi3GetVariableDependencies
/// still gives each element's exact knowns.
pub const LISTED_DEPENDENCIES_AT_MOST: usize = 1000;

/// `knowns` as a `<ModelStructure>` entry lists them (ascending), or `None`
/// (every known) past [`LISTED_DEPENDENCIES_AT_MOST`].
fn listed(mut knowns: Vec<u32>) -> Option<Vec<u32>> {
    knowns.sort_unstable();
    (knowns.len() <= LISTED_DEPENDENCIES_AT_MOST).then_some(knowns)
}

/// Why an FMU cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The model identifier is not a C identifier (it names the shared library).
    #[error("model identifier '{0}' is not a C identifier ([A-Za-z_][A-Za-z0-9_]*)")]
    ModelIdentifier(String),
    /// The model identifier is too long to name a file inside the FMU.
    #[error(
        "model identifier of {0} characters is longer than {MAX_MODEL_IDENTIFIER_LENGTH}: it names the file \
         binaries/<platform>/<identifier>.<extension> in the FMU, which could not be extracted"
    )]
    ModelIdentifierTooLong(usize),
    /// The model identifier is a device name that Windows reserves.
    #[error(
        "model identifier '{0}' is a device name Windows reserves (CON, PRN, AUX, NUL, COM1-9, LPT1-9, in any \
         case): the FMU's library binaries/win64/{0}.dll could not be opened there"
    )]
    ReservedModelIdentifier(String),
    /// The modelDescription breaks the standard's rules: a bug in this exporter.
    #[error("the generated modelDescription.xml breaks FMI 2.0 rules: {}", .0.iter().map(ToString::to_string).collect::<Vec<_>>().join("; "))]
    InvalidModelDescription(Vec<md::Problem>),
    /// The FMI 3.0 modelDescription breaks the standard's rules: a bug in this exporter.
    #[error("the generated modelDescription.xml breaks FMI 3.0 rules: {}", .0.iter().map(ToString::to_string).collect::<Vec<_>>().join("; "))]
    InvalidFmi3ModelDescription(Vec<md::fmi3::Problem3>),
    /// The modelDescription cannot be written.
    #[error(transparent)]
    ModelDescription(#[from] md::Error),
    /// The compiled model cannot be serialized.
    #[error("cannot serialize the compiled model: {0}")]
    Resource(#[from] serde_json::Error),
    /// A file cannot be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The file given as the FMU's binary cannot be one.
    #[error("{} cannot be the FMU's binary: {reason}", path.display())]
    Binary {
        /// The file.
        path: PathBuf,
        /// What it is instead.
        reason: String,
    },
    /// The output path cannot be replaced (crate::output).
    #[error(transparent)]
    Output(#[from] crate::output::OutputError),
    /// The archive cannot be written.
    #[error("cannot write {}: {source}", path.display())]
    Zip {
        /// The archive.
        path: PathBuf,
        /// The cause.
        source: zip::result::ZipError,
    },
}

/// The FMI version of an exported FMU.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FmiVersion {
    /// FMI 2.0: what every importer reads, OSP's libcosim included (the default).
    #[default]
    Fmi2,
    /// FMI 3.0, with θ, ν and ε as arrays.
    Fmi3,
}

/// Why `--fmi-version` cannot be read.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("unknown FMI version '{0}': expected 2 or 3")]
pub struct UnknownFmiVersion(String);

impl std::str::FromStr for FmiVersion {
    type Err = UnknownFmiVersion;

    fn from_str(text: &str) -> Result<Self, UnknownFmiVersion> {
        match text.trim() {
            "2" | "2.0" => Ok(FmiVersion::Fmi2),
            "3" | "3.0" => Ok(FmiVersion::Fmi3),
            other => Err(UnknownFmiVersion(other.to_string())),
        }
    }
}

/// A modelDescription of either version, validated when written.
pub enum Document {
    /// FMI 2.0.
    Fmi2(md::FmiModelDescription),
    /// FMI 3.0.
    Fmi3(md::fmi3::Fmi3ModelDescription),
}

impl Document {
    /// The document's text, after the standard's rules are checked.
    fn xml(&self) -> Result<String, ExportError> {
        match self {
            Document::Fmi2(description) => {
                let problems = md::validate(description);
                if !problems.is_empty() {
                    return Err(ExportError::InvalidModelDescription(problems));
                }
                Ok(md::to_xml(description)?)
            }
            Document::Fmi3(description) => {
                let problems = md::fmi3::validate(description);
                if !problems.is_empty() {
                    return Err(ExportError::InvalidFmi3ModelDescription(problems));
                }
                Ok(md::fmi3::to_xml(description)?)
            }
        }
    }

    /// The functions the binary must export, and the version's name.
    fn functions(&self) -> (&'static [&'static str], &'static str) {
        match self {
            Document::Fmi2(_) => (&binary::FMI2_FUNCTIONS, "FMI 2.0"),
            Document::Fmi3(_) => (&binary::FMI3_FUNCTIONS, "FMI 3.0"),
        }
    }

    /// Where the binary for `platform` goes in the archive (FMI 2.0 §2.5,
    /// FMI 3.0 §2.5.1).
    fn binary_path(&self, platform: Platform) -> String {
        let (folder, identifier) = match self {
            Document::Fmi2(description) => {
                (platform.fmi2_folder(), description.co_simulation.model_identifier.as_str())
            }
            Document::Fmi3(description) => (
                platform.fmi3_folder(),
                description.co_simulation.as_ref().map_or("", |cs| cs.model_identifier.as_str()),
            ),
        };
        format!("binaries/{folder}/{identifier}.{}", platform.library_extension())
    }
}

/// The longest model identifier: it names binaries/<platform>/<identifier>.dll
/// (or .so, .dylib) inside the FMU, and a file name over 255 bytes cannot be
/// extracted on the usual file systems; 200 leaves room for the extension
/// and for a tool's own prefix or suffix.
pub const MAX_MODEL_IDENTIFIER_LENGTH: usize = 200;

/// A model identifier from a name (e.g. the MJCF file stem): characters
/// outside `[A-Za-z0-9_]` become `_`, a leading digit or a name Windows
/// reserves gets a `_` before it, and it is cut to
/// [`MAX_MODEL_IDENTIFIER_LENGTH`].
pub fn model_identifier_from(name: &str) -> String {
    let mut identifier: String = name.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect();
    let leading_digit = identifier.chars().next().is_none_or(|c| c.is_ascii_digit());
    if leading_digit || reserved_on_windows(&identifier) {
        identifier.insert(0, '_');
    }
    identifier.truncate(MAX_MODEL_IDENTIFIER_LENGTH);
    identifier
}

/// Whether Windows reserves the name for a device (CON, PRN, AUX, NUL,
/// COM1-9, LPT1-9, in any case): a file so named, whatever its extension,
/// cannot be opened there.
fn reserved_on_windows(name: &str) -> bool {
    match name.to_ascii_uppercase().as_bytes() {
        b"CON" | b"PRN" | b"AUX" | b"NUL" => true,
        [b'C', b'O', b'M', digit] | [b'L', b'P', b'T', digit] => (b'1'..=b'9').contains(digit),
        _ => false,
    }
}

fn is_c_identifier(name: &str) -> bool {
    let mut chars = name.chars();
    chars.next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// Refuses a model identifier that cannot name the shared library on
/// every platform the FMU may be unpacked on.
fn check_model_identifier(model_identifier: &str) -> Result<(), ExportError> {
    if !is_c_identifier(model_identifier) {
        Err(ExportError::ModelIdentifier(model_identifier.to_string()))
    } else if model_identifier.len() > MAX_MODEL_IDENTIFIER_LENGTH {
        Err(ExportError::ModelIdentifierTooLong(model_identifier.len()))
    } else if reserved_on_windows(model_identifier) {
        Err(ExportError::ReservedModelIdentifier(model_identifier.to_string()))
    } else {
        Ok(())
    }
}

/// The `<ScalarVariable>` of a Real variable of kind `kind`.
fn real_variable(name: String, vr: u32, description: String, kind: Kind, start: Option<f64>) -> md::ScalarVariable {
    let (causality, initial) = match kind.causality {
        Causality::Parameter => (md::Causality::Parameter, Some(md::Initial::Exact)),
        Causality::Input => (md::Causality::Input, None),
        Causality::Output if kind.exact_start => (md::Causality::Output, Some(md::Initial::Exact)),
        Causality::Output => (md::Causality::Output, Some(md::Initial::Calculated)),
        Causality::Local => (md::Causality::Local, Some(md::Initial::Calculated)),
    };
    let min = (kind.range == Range::NonNegative).then_some(0.0);
    md::ScalarVariable {
        name,
        value_reference: vr,
        description: Some(description),
        causality,
        variability: variability(kind.variability),
        initial,
        can_handle_multiple_set_per_time_instant: None,
        kind: md::VariableKind::Real(md::RealVariable { start, min, ..Default::default() }),
    }
}

fn variability(variability: Variability) -> md::Variability {
    match variability {
        Variability::Fixed => md::Variability::Fixed,
        Variability::Tunable => md::Variability::Tunable,
        Variability::Continuous => md::Variability::Continuous,
    }
}

/// The `<CoSimulation>` element of an FMU with `capabilities`.
fn co_simulation(model_identifier: &str, capabilities: Capabilities) -> md::CoSimulation {
    md::CoSimulation {
        model_identifier: model_identifier.to_string(),
        needs_execution_tool: false,
        can_handle_variable_communication_step_size: capabilities.can_handle_variable_communication_step_size,
        can_interpolate_inputs: capabilities.can_interpolate_inputs,
        max_output_derivative_order: capabilities.max_output_derivative_order,
        can_run_asynchronuously: false,
        can_be_instantiated_only_once_per_process: false,
        can_not_use_memory_management_functions: true,
        can_get_and_set_fmu_state: capabilities.can_get_and_set_fmu_state,
        can_serialize_fmu_state: capabilities.can_serialize_fmu_state,
        provides_directional_derivative: capabilities.provides_directional_derivative,
    }
}

/// The `<ModelExchange>` element of an FMU with `capabilities`, if it serves model exchange.
fn model_exchange(model_identifier: &str, capabilities: Capabilities) -> Option<md::ModelExchange> {
    capabilities.model_exchange.then(|| md::ModelExchange {
        model_identifier: model_identifier.to_string(),
        needs_execution_tool: false,
        // No step events: the host need not call fmi2CompletedIntegratorStep.
        completed_integrator_step_not_needed: true,
        can_be_instantiated_only_once_per_process: false,
        can_not_use_memory_management_functions: true,
        can_get_and_set_fmu_state: capabilities.can_get_and_set_fmu_state,
        can_serialize_fmu_state: capabilities.can_serialize_fmu_state,
        provides_directional_derivative: capabilities.provides_directional_derivative,
    })
}

/// The modelDescription fields every nudyn FMU shares, around its own
/// name, GUID, description, `<ModelExchange>` and `<CoSimulation>`, types,
/// variables and structure.
struct Header {
    model_name: String,
    guid: String,
    description: String,
    model_identifier: String,
    capabilities: Capabilities,
    /// FMI 2.0 model exchange's `numberOfEventIndicators`: the switches of
    /// the constraint forces (FMI 3.0 lists their variable as `<EventIndicator>`s).
    event_indicators: usize,
    /// `generationDateAndTime`: [`generation_date_and_time`].
    generated: String,
}

/// When the FMU is generated, as xs:dateTime in UTC (2026-11-25T10:00:00Z):
/// now, or the time SOURCE_DATE_EPOCH gives (seconds since 1970), so that
/// an archive can be rebuilt byte for byte (reproducible-builds.org's
/// convention; a value that is not a number of seconds is not used).
pub fn generation_date_and_time() -> String {
    let fixed = std::env::var("SOURCE_DATE_EPOCH").ok().and_then(|seconds| seconds.trim().parse::<u64>().ok());
    let time = match fixed {
        Some(seconds) => std::time::UNIX_EPOCH + std::time::Duration::from_secs(seconds),
        None => std::time::SystemTime::now(),
    };
    humantime::format_rfc3339_seconds(time).to_string()
}

impl Header {
    fn into_model_description(
        self,
        type_definitions: Vec<md::SimpleType>,
        model_variables: Vec<md::ScalarVariable>,
        model_structure: md::ModelStructure,
    ) -> md::FmiModelDescription {
        md::FmiModelDescription {
            fmi_version: md::FmiVersion::Fmi2,
            model_name: self.model_name,
            guid: self.guid,
            description: Some(self.description),
            author: None,
            version: None,
            copyright: None,
            license: None,
            generation_tool: Some(format!("nudyn {}", env!("CARGO_PKG_VERSION"))),
            generation_date_and_time: Some(self.generated.clone()),
            variable_naming_convention: Some(md::VariableNamingConvention::Structured),
            number_of_event_indicators: self.capabilities.model_exchange.then_some(self.event_indicators as u32),
            model_exchange: model_exchange(&self.model_identifier, self.capabilities),
            co_simulation: co_simulation(&self.model_identifier, self.capabilities),
            unit_definitions: Vec::new(),
            type_definitions,
            log_categories: LogCategory::ALL
                .iter()
                .map(|c| md::Category { name: c.name().into(), description: Some(c.description().into()) })
                .collect(),
            default_experiment: Some(md::DefaultExperiment {
                start_time: Some(0.0),
                stop_time: Some(DEFAULT_STOP_TIME),
                // None, so that importers which pass the DefaultExperiment's
                // tolerance to fmi2SetupExperiment (FMPy does) leave the plant's
                // `tolerance` parameter in charge unless told otherwise.
                tolerance: None,
                step_size: Some(DEFAULT_STEP_SIZE),
            }),
            model_variables,
            model_structure,
        }
    }
}

/// A built `nudyn_fmu` library and the platform it is for.
#[derive(Clone, Debug, PartialEq)]
pub struct PlatformBinary {
    /// The platform.
    pub platform: Platform,
    /// The library file.
    pub path: PathBuf,
}

/// The FMU archive's bytes: `description` (validated first) as
/// modelDescription.xml, each of `binaries` (the `nudyn_fmu` cdylib built
/// for a platform, checked, without debug sections) as e.g.
/// `binaries/linux64/<modelIdentifier>.so` or `binaries/win64/<modelIdentifier>.dll`
/// (FMI 3.0: `binaries/x86_64-linux/`, `binaries/x86_64-windows/`), the
/// resource file and the documentation. `out` names the archive in messages.
fn fmu_archive<R: Resource>(
    description: &Document,
    resource: &[u8],
    documentation: &str,
    binaries: &[PlatformBinary],
    out: &Path,
) -> Result<Vec<u8>, ExportError> {
    let xml = description.xml()?;
    let (functions, version) = description.functions();
    let mut libraries = Vec::with_capacity(binaries.len());
    for PlatformBinary { platform, path } in binaries {
        let binary_error = |reason| ExportError::Binary { path: path.clone(), reason };
        let library = std::fs::read(path).map_err(|source| ExportError::Io { path: path.clone(), source })?;
        binary::check_library(*platform, &library, functions, version).map_err(binary_error)?;
        let library = binary::without_debug_sections(*platform, library).map_err(binary_error)?;
        libraries.push((description.binary_path(*platform), library));
    }
    let mut entries = vec![Entry { name: "modelDescription.xml".to_string(), bytes: xml.as_bytes(), mode: 0o644 }];
    entries.extend(libraries.iter().map(|(name, library)| Entry { name: name.clone(), bytes: library, mode: 0o755 }));
    entries.push(Entry { name: R::archive_path(), bytes: resource, mode: 0o644 });
    entries.push(Entry { name: "documentation/index.html".to_string(), bytes: documentation.as_bytes(), mode: 0o644 });
    zip_archive(&entries, out)
}

/// One file of an archive, with its Unix mode.
struct Entry<'a> {
    name: String,
    bytes: &'a [u8],
    mode: u32,
}

/// The zip archive of `entries`, in order, built in memory: FMUs and SSPs
/// (whose FMUs are entries of it) alike. `out` names it in messages.
fn zip_archive(entries: &[Entry], out: &Path) -> Result<Vec<u8>, ExportError> {
    let zip_error = |source| ExportError::Zip { path: out.to_path_buf(), source };
    let mut archive = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    for entry in entries {
        let options = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated)
            .unix_permissions(entry.mode);
        archive.start_file(entry.name.as_str(), options).map_err(zip_error)?;
        archive.write_all(entry.bytes).map_err(|source| ExportError::Io { path: out.to_path_buf(), source })?;
    }
    Ok(archive.finish().map_err(zip_error)?.into_inner())
}

/// Writes `bytes` to `out`, replaced whole or not at all, and only if it is
/// a regular file or new (crate::output).
fn write_file(out: &Path, bytes: &[u8]) -> Result<(), ExportError> {
    crate::output::write_atomically(out, |mut staged| {
        staged.write_all(bytes).map_err(|source| ExportError::Io { path: out.to_path_buf(), source })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn model_identifiers_are_c_identifiers() {
        assert_eq!(model_identifier_from("bus_arm7"), "bus_arm7");
        assert_eq!(model_identifier_from("flexible-boom.v2"), "flexible_boom_v2");
        assert_eq!(model_identifier_from("60links"), "_60links");
        assert!(is_c_identifier("_60links") && !is_c_identifier("a b") && !is_c_identifier(""));
        // What the export refuses is never made up from a file name.
        assert_eq!(model_identifier_from("con"), "_con");
        assert_eq!(model_identifier_from("Lpt1"), "_Lpt1");
        assert_eq!(model_identifier_from(&"a".repeat(300)), "a".repeat(MAX_MODEL_IDENTIFIER_LENGTH));
        for name in ["con", "Lpt1", &"a".repeat(300), "console", "com10", "com0"] {
            let identifier = model_identifier_from(name);
            assert!(check_model_identifier(&identifier).is_ok(), "{name}: {identifier}");
        }
    }

    #[test]
    fn identifiers_windows_reserves_or_too_long_to_extract_are_refused() {
        for reserved in ["con", "CON", "Prn", "aux", "nUl", "COM1", "com9", "LPT1", "lpt9"] {
            let error = check_model_identifier(reserved).unwrap_err();
            assert!(matches!(error, ExportError::ReservedModelIdentifier(_)), "{reserved}: {error}");
        }
        let error = check_model_identifier(&"x".repeat(300)).unwrap_err();
        assert!(matches!(error, ExportError::ModelIdentifierTooLong(300)), "{error}");
        assert!(error.to_string().contains("longer than 200"), "{error}");
        // Names beside the reserved ones, and the longest allowed, stay valid.
        for valid in ["console", "com", "com0", "com10", "lpt", "nul_", "_con", &"x".repeat(200)] {
            assert!(check_model_identifier(valid).is_ok(), "{valid}");
        }
    }
}
