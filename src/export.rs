//! The library side of `nudyn export`: the FMU's variables and their value
//! references (shared with the `fmu` crate, which serves them), its
//! resource file, its content-derived GUID, and the archive.
//!
//! Variables follow MuJoCo's qpos/qvel order with 1-based structured names
//! (`theta[1]`): inputs `eps[1..nv]`, outputs `theta[1..nq]` and
//! `nu[1..nv]`, and the optional outputs chosen at export.

use std::io::Write;
use std::path::{Path, PathBuf};

use modeldescription as md;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::integrate::Method;
use crate::model::Model;
use crate::vehicle::JointKind;

/// Version of the resource file layout ([`FmuResource`]).
pub const RESOURCE_FORMAT: u32 = 1;

/// Path of the compiled model inside the FMU archive.
pub const RESOURCE_PATH: &str = "resources/model.json";

/// Value reference of the Integer (enumeration) parameter `method`.
pub const METHOD_VR: u32 = 0;

/// Value reference of the Boolean parameter `energy_projection`.
pub const ENERGY_PROJECTION_VR: u32 = 0;

/// The value of `method` in the FMU's enumeration: 1-based, as FMI
/// enumerations usually are, in the order of [`Method::ALL`].
pub fn method_value(method: Method) -> i32 {
    Method::ALL.iter().position(|&m| m == method).expect("listed") as i32 + 1
}

/// The method of an enumeration value, if it is one.
pub fn method_of_value(value: i32) -> Option<Method> {
    usize::try_from(value - 1).ok().and_then(|i| Method::ALL.get(i).copied())
}

/// Default of the `method` parameter.
pub const DEFAULT_METHOD: Method = Method::Dop853;

/// Default of the `max_step` parameter (s): the longest internal step.
pub const DEFAULT_MAX_STEP: f64 = 1e-2;

/// Default of the `tolerance` parameter.
pub const DEFAULT_TOLERANCE: f64 = 1e-8;

/// The FMU's log categories (name, description); the FMU indexes them by
/// position. Errors are logged by default, calls only with loggingOn.
pub const LOG_CATEGORIES: [(&str, &str); 5] = [
    ("logStatusDiscard", "why a step was discarded"),
    ("logStatusError", "why a call was refused or failed"),
    ("logStatusFatal", "unrecoverable failures"),
    ("logCalls", "every call and its status (debug)"),
    ("logStatusWarning", "a step that completed at a looser tolerance than asked"),
];

/// The optional outputs chosen at export; those not chosen do not exist in
/// the FMU, so they cost nothing at run time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct OptionalOutputs {
    /// `qvel[1..nv]`: θ̇ in MuJoCo's convention.
    pub qvel: bool,
    /// `kinetic_energy`: K = ½|ν|².
    pub kinetic_energy: bool,
    /// `power`: ν·ε of the applied ε.
    pub power: bool,
    /// `momentum[1..6]`: spatial momentum (angular about the world origin, then linear), world axes.
    pub momentum: bool,
    /// `energy_residual`: K − K₀ − ∫ν·ν̇ dt, the integration's energy error.
    #[serde(default)]
    pub energy_residual: bool,
}

/// Why a list of optional outputs cannot be parsed.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("unknown optional output '{0}': expected qvel, kinetic_energy, power, momentum or energy_residual")]
pub struct UnknownOutput(pub String);

impl std::str::FromStr for OptionalOutputs {
    type Err = UnknownOutput;

    /// Parses a comma-separated list such as `qvel,kinetic_energy` (empty: none).
    fn from_str(list: &str) -> Result<Self, UnknownOutput> {
        let mut outputs = OptionalOutputs::default();
        for name in list.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            match name {
                "qvel" => outputs.qvel = true,
                "kinetic_energy" => outputs.kinetic_energy = true,
                "power" => outputs.power = true,
                "momentum" => outputs.momentum = true,
                "energy_residual" => outputs.energy_residual = true,
                _ => return Err(UnknownOutput(name.to_string())),
            }
        }
        Ok(outputs)
    }
}

/// `resources/model.json`: what the FMU loads at instantiation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FmuResource {
    /// [`RESOURCE_FORMAT`] of the writer.
    pub format: u32,
    /// The optional outputs the FMU provides.
    pub outputs: OptionalOutputs,
    /// The compiled vehicle.
    pub model: Model,
}

/// One Real variable of the FMU; indices are 0-based here, 1-based in names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RealVariable {
    /// Parameter `tolerance`.
    Tolerance,
    /// Parameter `max_step`.
    MaxStep,
    /// Input `eps[k+1]`.
    Eps(usize),
    /// Output `theta[k+1]` (qpos).
    Theta(usize),
    /// Output `nu[k+1]`.
    Nu(usize),
    /// Optional output `qvel[k+1]`.
    Qvel(usize),
    /// Optional output `kinetic_energy`.
    KineticEnergy,
    /// Optional output `power`.
    Power,
    /// Optional output `momentum[k+1]`.
    Momentum(usize),
    /// Optional output `energy_residual`.
    EnergyResidual,
}

/// The variable of index k within a block of variables of type V.
pub(crate) type VariableOf<V> = fn(usize) -> V;

/// Blocks of variables numbered consecutively from value reference `first`:
/// (length, variable of index k) becomes (first value reference, length,
/// variable of index k). A layout's value references are its blocks'.
pub(crate) fn numbered_blocks<V, const N: usize>(
    first: u32,
    blocks: [(usize, VariableOf<V>); N],
) -> impl Iterator<Item = (u32, usize, VariableOf<V>)> {
    let mut next = first;
    blocks.into_iter().map(move |(len, variable)| {
        let first = next;
        next += len as u32;
        (first, len, variable)
    })
}

/// The variable with value reference `vr` among numbered `blocks`, if any.
pub(crate) fn variable_at<V>(mut blocks: impl Iterator<Item = (u32, usize, VariableOf<V>)>, vr: u32) -> Option<V> {
    blocks
        .find(|&(first, len, _)| vr >= first && ((vr - first) as usize) < len)
        .map(|(first, _, variable)| variable((vr - first) as usize))
}

/// Every variable of numbered `blocks` with its value reference, in order.
pub(crate) fn every_variable<V>(
    blocks: impl Iterator<Item = (u32, usize, VariableOf<V>)>,
) -> impl Iterator<Item = (u32, V)> {
    blocks.flat_map(|(first, len, variable)| (0..len).map(move |k| (first + k as u32, variable(k))))
}

/// The FMU's Real variables and their value references: consecutive blocks
/// after the two parameters, `tolerance` (1) and `max_step` (2), in the
/// order eps, theta, nu, then the chosen optional outputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    /// Number of position coordinates.
    pub nq: usize,
    /// Number of dofs.
    pub nv: usize,
    /// The optional outputs present.
    pub outputs: OptionalOutputs,
}

impl Layout {
    /// The layout of an FMU of `model` with `outputs`.
    pub fn new(model: &Model, outputs: OptionalOutputs) -> Self {
        Layout { nq: model.nq, nv: model.nv, outputs }
    }

    /// The blocks in value-reference order: (first value reference, length, variable of index k).
    fn blocks(&self) -> impl Iterator<Item = (u32, usize, VariableOf<RealVariable>)> {
        let o = self.outputs;
        let blocks: [(usize, VariableOf<RealVariable>); 10] = [
            (1, |_| RealVariable::Tolerance),
            (1, |_| RealVariable::MaxStep),
            (self.nv, RealVariable::Eps),
            (self.nq, RealVariable::Theta),
            (self.nv, RealVariable::Nu),
            (if o.qvel { self.nv } else { 0 }, RealVariable::Qvel),
            (usize::from(o.kinetic_energy), |_| RealVariable::KineticEnergy),
            (usize::from(o.power), |_| RealVariable::Power),
            (if o.momentum { 6 } else { 0 }, RealVariable::Momentum),
            (usize::from(o.energy_residual), |_| RealVariable::EnergyResidual),
        ];
        numbered_blocks(METHOD_VR + 1, blocks)
    }

    /// The variable with value reference `vr`, if any.
    pub fn real_variable(&self, vr: u32) -> Option<RealVariable> {
        variable_at(self.blocks(), vr)
    }

    /// All Real variables with their value references, in order.
    pub fn real_variables(&self) -> impl Iterator<Item = (u32, RealVariable)> {
        every_variable(self.blocks())
    }

    /// The value reference of `variable` (which must exist in this layout).
    pub fn value_reference(&self, variable: RealVariable) -> Option<u32> {
        self.real_variables().find(|&(_, v)| v == variable).map(|(vr, _)| vr)
    }
}

impl RealVariable {
    /// The structured, 1-based name, as in `modelDescription.xml`.
    pub fn name(self) -> String {
        match self {
            RealVariable::Tolerance => "tolerance".into(),
            RealVariable::MaxStep => "max_step".into(),
            RealVariable::Eps(k) => format!("eps[{}]", k + 1),
            RealVariable::Theta(k) => format!("theta[{}]", k + 1),
            RealVariable::Nu(k) => format!("nu[{}]", k + 1),
            RealVariable::Qvel(k) => format!("qvel[{}]", k + 1),
            RealVariable::KineticEnergy => "kinetic_energy".into(),
            RealVariable::Power => "power".into(),
            RealVariable::Momentum(k) => format!("momentum[{}]", k + 1),
            RealVariable::EnergyResidual => "energy_residual".into(),
        }
    }
}

/// The FMU's GUID: a SHA-256 of the resource file's bytes and the variable
/// list, written as a braced UUID. The FMU recomputes it from the resource
/// it loads, so a GUID that does not match the resources fails instantiation.
pub fn guid(resource_json: &[u8], layout: &Layout) -> String {
    guid_of(resource_json, layout.real_variables().map(|(vr, variable)| (vr, variable.name())))
}

/// The GUID of [`guid`] for any FMU nudyn writes: a SHA-256 of the resource
/// and of its (value reference, name) list.
pub fn guid_of(resource_json: &[u8], variables: impl Iterator<Item = (u32, String)>) -> String {
    let mut hasher = Sha256::new();
    hasher.update(resource_json);
    for (vr, name) in variables {
        hasher.update(format!("\n{vr} {name}").as_bytes());
    }
    let hex: String = hasher.finalize()[..16].iter().map(|b| format!("{b:02x}")).collect();
    format!("{{{}-{}-{}-{}-{}}}", &hex[0..8], &hex[8..12], &hex[12..16], &hex[16..20], &hex[20..32])
}

/// What one coordinate or dof is, for variable descriptions: the joint, its
/// kind, and the component and unit of entry `k` within the joint.
fn joint_entry(model: &Model, index: usize, qpos: bool) -> (String, &'static str) {
    let joint = model
        .joints
        .iter()
        .rev()
        .find(|j| if qpos { j.qpos_adr <= index } else { j.dof_adr <= index })
        .expect("every coordinate belongs to a joint");
    let k = index - if qpos { joint.qpos_adr } else { joint.dof_adr };
    const AXES: [&str; 3] = ["x", "y", "z"];
    const QUAT: [&str; 4] = ["w", "x", "y", "z"];
    let (kind, component, unit) = match (joint.kind, qpos) {
        (JointKind::Hinge, true) => ("hinge", String::new(), "rad"),
        (JointKind::Hinge, false) => ("hinge", String::new(), "rad/s"),
        (JointKind::Slide, true) => ("slide", String::new(), "m"),
        (JointKind::Slide, false) => ("slide", String::new(), "m/s"),
        (JointKind::Ball, true) => ("ball", format!(", quaternion {}", QUAT[k]), "1"),
        (JointKind::Ball, false) => ("ball", format!(", angular velocity {} in the body frame", AXES[k]), "rad/s"),
        (JointKind::Free, true) if k < 3 => ("free", format!(", position {} in world", AXES[k]), "m"),
        (JointKind::Free, true) => ("free", format!(", quaternion {}", QUAT[k - 3]), "1"),
        (JointKind::Free, false) if k < 3 => ("free", format!(", linear velocity {} in world", AXES[k]), "m/s"),
        (JointKind::Free, false) => ("free", format!(", angular velocity {} in the body frame", AXES[k - 3]), "rad/s"),
    };
    (format!("{kind} joint '{}'{component}", joint.name), unit)
}

/// The description of `variable` in `modelDescription.xml`, naming the
/// joint and the unit. ν and ε are in √J = √kg·m/s and √kg·m/s² since K = ½|ν|².
pub fn description(model: &Model, variable: RealVariable) -> String {
    const MOMENTUM: [&str; 6] = [
        "angular momentum x about the world origin (kg*m^2/s)",
        "angular momentum y about the world origin (kg*m^2/s)",
        "angular momentum z about the world origin (kg*m^2/s)",
        "linear momentum x (kg*m/s)",
        "linear momentum y (kg*m/s)",
        "linear momentum z (kg*m/s)",
    ];
    match variable {
        RealVariable::Tolerance => {
            "error allowed per second of simulated time, relative to 1 + |value|, for the adaptive methods; \
             a tolerance passed to fmi2SetupExperiment replaces it (1)"
                .into()
        }
        RealVariable::MaxStep => "longest internal integration step (s)".into(),
        RealVariable::Eps(k) => {
            format!("diagonalized force eps of dof {} of {} (sqrt(kg)*m/s^2)", k + 1, joint_entry(model, k, false).0)
        }
        RealVariable::Theta(k) => {
            let (joint, unit) = joint_entry(model, k, true);
            format!("qpos of {joint} ({unit})")
        }
        RealVariable::Nu(k) => {
            format!("diagonalized velocity nu of dof {} of {} (sqrt(kg)*m/s)", k + 1, joint_entry(model, k, false).0)
        }
        RealVariable::Qvel(k) => {
            let (joint, unit) = joint_entry(model, k, false);
            format!("qvel of {joint} ({unit})")
        }
        RealVariable::KineticEnergy => "kinetic energy 1/2 |nu|^2 (J)".into(),
        RealVariable::Power => "power of the applied eps, nu . eps (W)".into(),
        RealVariable::Momentum(k) => format!("spatial momentum of the vehicle, world axes: {}", MOMENTUM[k]),
        RealVariable::EnergyResidual => {
            "energy residual K - K(start) - integral of nu . nu_dot dt, the integration's energy error (J)".into()
        }
    }
}

/// The default communication step of the DefaultExperiment (s).
pub const DEFAULT_STEP_SIZE: f64 = 0.01;

/// The stop time of the DefaultExperiment (s).
pub const DEFAULT_STOP_TIME: f64 = 10.0;

/// Why an FMU cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The model identifier is not a C identifier (it names the shared library).
    #[error("model identifier '{0}' is not a C identifier ([A-Za-z_][A-Za-z0-9_]*)")]
    ModelIdentifier(String),
    /// The modelDescription breaks the standard's rules: a bug in this exporter.
    #[error("the generated modelDescription.xml breaks FMI 2.0 rules: {}", .0.iter().map(ToString::to_string).collect::<Vec<_>>().join("; "))]
    InvalidModelDescription(Vec<md::Problem>),
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
    /// The archive cannot be written.
    #[error("cannot write {}: {source}", path.display())]
    Zip {
        /// The archive.
        path: PathBuf,
        /// The cause.
        source: zip::result::ZipError,
    },
}

/// What `nudyn export` is asked for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ExportOptions {
    /// The model identifier: the shared library's name, a C identifier.
    pub model_identifier: String,
    /// The optional outputs.
    pub outputs: OptionalOutputs,
}

/// A model identifier from a name (e.g. the MJCF file stem): characters
/// outside `[A-Za-z0-9_]` become `_`, and a leading digit gets a `_` before it.
pub fn model_identifier_from(name: &str) -> String {
    let identifier: String = name.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect();
    match identifier.chars().next() {
        Some(c) if !c.is_ascii_digit() => identifier,
        _ => format!("_{identifier}"),
    }
}

pub(crate) fn is_c_identifier(name: &str) -> bool {
    let mut chars = name.chars();
    chars.next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// The resource file's bytes for `model` with `outputs`.
pub fn resource_json(model: &Model, outputs: OptionalOutputs) -> Result<Vec<u8>, ExportError> {
    let resource = FmuResource { format: RESOURCE_FORMAT, outputs, model: model.clone() };
    Ok(serde_json::to_vec(&resource)?)
}

/// The enumeration type of the `method` parameter.
const METHOD_TYPE: &str = "Method";

/// The typed modelDescription of the FMU (not yet validated).
pub fn model_description(model: &Model, options: &ExportOptions, guid: &str) -> md::FmiModelDescription {
    let layout = Layout::new(model, options.outputs);
    let scalar = |name: String, vr, description, causality, variability, initial, kind| md::ScalarVariable {
        name,
        value_reference: vr,
        description: Some(description),
        causality,
        variability,
        initial,
        can_handle_multiple_set_per_time_instant: None,
        kind,
    };
    let real = |start: Option<f64>| md::VariableKind::Real(md::RealVariable { start, ..Default::default() });
    let method = scalar(
        "method".into(),
        METHOD_VR,
        "integration method".into(),
        md::Causality::Parameter,
        md::Variability::Fixed,
        Some(md::Initial::Exact),
        md::VariableKind::Enumeration(md::EnumerationVariable {
            declared_type: METHOD_TYPE.into(),
            quantity: None,
            min: None,
            max: None,
            start: Some(method_value(DEFAULT_METHOD)),
        }),
    );
    let energy_projection = scalar(
        "energy_projection".into(),
        ENERGY_PROJECTION_VR,
        "rescale nu after each internal step so that the kinetic energy follows the work done (keeps K exactly when no force acts)".into(),
        md::Causality::Parameter,
        md::Variability::Fixed,
        Some(md::Initial::Exact),
        md::VariableKind::Boolean(md::BooleanVariable { start: Some(false), ..Default::default() }),
    );
    let reals = layout.real_variables().map(|(vr, variable)| {
        use md::{Causality::*, Initial::Exact, Variability::*};
        let (causality, variability, initial, start) = match variable {
            RealVariable::Tolerance => (Parameter, Fixed, Some(Exact), Some(DEFAULT_TOLERANCE)),
            RealVariable::MaxStep => (Parameter, Fixed, Some(Exact), Some(DEFAULT_MAX_STEP)),
            RealVariable::Eps(_) => (Input, Continuous, None, Some(0.0)),
            // initial="exact": the master may set them before initialization to choose the initial state.
            RealVariable::Theta(k) => (Output, Continuous, Some(Exact), Some(model.qpos0[k])),
            RealVariable::Nu(_) => (Output, Continuous, Some(Exact), Some(0.0)),
            _ => (Output, Continuous, None, None),
        };
        scalar(variable.name(), vr, description(model, variable), causality, variability, initial, real(start))
    });
    let model_variables: Vec<md::ScalarVariable> = [method, energy_projection].into_iter().chain(reals).collect();

    // 1-based ScalarVariable indices, as <ModelStructure> refers to them.
    let index_of = |variable: RealVariable| {
        let vr = layout.value_reference(variable).expect("the variable exists");
        model_variables.iter().position(|v| v.value_reference == vr && v.name == variable.name()).expect("listed") as u32 + 1
    };
    let eps_indices: Vec<u32> = (0..model.nv).map(|k| index_of(RealVariable::Eps(k))).collect();
    let mut outputs = Vec::new();
    let mut initial_unknowns = Vec::new();
    for (_, variable) in layout.real_variables() {
        let index = index_of(variable);
        // At a communication point only the power feeds an input through directly.
        let dependencies = match variable {
            RealVariable::Tolerance | RealVariable::MaxStep | RealVariable::Eps(_) => continue,
            RealVariable::Power => eps_indices.clone(),
            _ => Vec::new(),
        };
        outputs.push(md::Unknown { index, dependencies: Some(dependencies), dependencies_kind: None });
        if !matches!(variable, RealVariable::Theta(_) | RealVariable::Nu(_)) {
            // Calculated outputs are initial unknowns; they may depend on every exact start value and input.
            initial_unknowns.push(md::Unknown::new(index));
        }
    }

    md::FmiModelDescription {
        fmi_version: md::FmiVersion::Fmi2,
        model_name: if model.name.is_empty() { options.model_identifier.clone() } else { model.name.clone() },
        guid: guid.to_string(),
        description: Some(format!(
            "diagonalized dynamics of the vehicle '{}' (nq = {}, nv = {}): nu' + C(theta, nu) = eps",
            model.name, model.nq, model.nv
        )),
        author: None,
        version: None,
        copyright: None,
        license: None,
        generation_tool: Some(format!("nudyn {}", env!("CARGO_PKG_VERSION"))),
        generation_date_and_time: None,
        variable_naming_convention: Some(md::VariableNamingConvention::Structured),
        number_of_event_indicators: None,
        co_simulation: md::CoSimulation {
            model_identifier: options.model_identifier.clone(),
            needs_execution_tool: false,
            can_handle_variable_communication_step_size: true,
            can_interpolate_inputs: true,
            max_output_derivative_order: 1,
            can_run_asynchronuously: false,
            can_be_instantiated_only_once_per_process: false,
            can_not_use_memory_management_functions: true,
            can_get_and_set_fmu_state: true,
            can_serialize_fmu_state: true,
            provides_directional_derivative: false,
        },
        unit_definitions: Vec::new(),
        type_definitions: vec![md::SimpleType {
            name: METHOD_TYPE.into(),
            description: Some("integration method".into()),
            kind: md::SimpleTypeKind::Enumeration(md::EnumerationType {
                quantity: None,
                items: Method::ALL
                    .iter()
                    .map(|&method| md::Item {
                        name: method.name().into(),
                        value: method_value(method),
                        description: Some(format!("{} (Munthe-Kaas on rotations)", method.description())),
                    })
                    .collect(),
            }),
        }],
        log_categories: log_categories(),
        default_experiment: Some(default_experiment()),
        model_variables,
        model_structure: md::ModelStructure { outputs, derivatives: Vec::new(), initial_unknowns },
    }
}

/// The LogCategories every nudyn FMU declares (plant and controller).
pub(crate) fn log_categories() -> Vec<md::Category> {
    LOG_CATEGORIES
        .iter()
        .map(|&(name, description)| md::Category { name: name.into(), description: Some(description.into()) })
        .collect()
}

/// The DefaultExperiment every nudyn FMU declares (plant and controller).
pub(crate) fn default_experiment() -> md::DefaultExperiment {
    md::DefaultExperiment {
        start_time: Some(0.0),
        stop_time: Some(DEFAULT_STOP_TIME),
        // None, so that importers which pass the DefaultExperiment's
        // tolerance to fmi2SetupExperiment (FMPy does) leave the plant's
        // `tolerance` parameter in charge unless told otherwise.
        tolerance: None,
        step_size: Some(DEFAULT_STEP_SIZE),
    }
}

/// Writes the FMU archive `out`: modelDescription.xml (validated first),
/// `binaries/linux64/<modelIdentifier>.so` copied from `binary` (the
/// `nudyn_fmu` cdylib) and [`RESOURCE_PATH`].
pub fn write_fmu(model: &Model, options: &ExportOptions, binary: &Path, out: &Path) -> Result<(), ExportError> {
    if !is_c_identifier(&options.model_identifier) {
        return Err(ExportError::ModelIdentifier(options.model_identifier.clone()));
    }
    let resource = resource_json(model, options.outputs)?;
    let guid = guid(&resource, &Layout::new(model, options.outputs));
    let description = model_description(model, options, &guid);
    write_archive(&description, (RESOURCE_PATH, &resource), binary, out)
}

/// Writes an FMU archive: `description` (validated first) as
/// modelDescription.xml, `binary` as `binaries/linux64/<modelIdentifier>.so`
/// and `resource` = (path in the archive, bytes).
pub fn write_archive(
    description: &md::FmiModelDescription,
    resource: (&str, &[u8]),
    binary: &Path,
    out: &Path,
) -> Result<(), ExportError> {
    let problems = md::validate(description);
    if !problems.is_empty() {
        return Err(ExportError::InvalidModelDescription(problems));
    }
    let xml = md::to_xml(description)?;
    let library = std::fs::read(binary).map_err(|source| ExportError::Io { path: binary.to_path_buf(), source })?;

    let file = std::fs::File::create(out).map_err(|source| ExportError::Io { path: out.to_path_buf(), source })?;
    let zip_error = |source| ExportError::Zip { path: out.to_path_buf(), source };
    let mut archive = zip::ZipWriter::new(file);
    let options_for = |mode| {
        zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated)
            .unix_permissions(mode)
    };
    let entries = [
        ("modelDescription.xml".to_string(), xml.as_bytes(), 0o644),
        (format!("binaries/linux64/{}.so", description.co_simulation.model_identifier), &library[..], 0o755),
        (resource.0.to_string(), resource.1, 0o644),
    ];
    for (name, bytes, mode) in entries {
        archive.start_file(name, options_for(mode)).map_err(zip_error)?;
        archive.write_all(bytes).map_err(|source| ExportError::Io { path: out.to_path_buf(), source })?;
    }
    archive.finish().map_err(zip_error)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_optional_outputs() {
        let all: OptionalOutputs = "qvel, kinetic_energy,power,momentum".parse().unwrap();
        assert_eq!(all, OptionalOutputs { qvel: true, kinetic_energy: true, power: true, momentum: true, energy_residual: false });
        assert_eq!("".parse::<OptionalOutputs>().unwrap(), OptionalOutputs::default());
        assert_eq!("qvel,speed".parse::<OptionalOutputs>(), Err(UnknownOutput("speed".into())));
    }

    #[test]
    fn model_identifiers_are_c_identifiers() {
        assert_eq!(model_identifier_from("bus_arm7"), "bus_arm7");
        assert_eq!(model_identifier_from("flexible-boom.v2"), "flexible_boom_v2");
        assert_eq!(model_identifier_from("60links"), "_60links");
        assert!(is_c_identifier("_60links") && !is_c_identifier("a b") && !is_c_identifier(""));
    }

    #[test]
    fn value_references_are_consecutive_and_decode() {
        let layout = Layout { nq: 7, nv: 6, outputs: "qvel,power,momentum".parse().unwrap() };
        let all: Vec<(u32, RealVariable)> = layout.real_variables().collect();
        assert_eq!(all.len(), 2 + 6 + 7 + 6 + 6 + 1 + 6);
        for (k, &(vr, variable)) in all.iter().enumerate() {
            assert_eq!(vr, k as u32 + 1);
            assert_eq!(layout.real_variable(vr), Some(variable));
        }
        assert_eq!(layout.real_variable(0), None, "vr 0 is the Integer method");
        assert_eq!(layout.real_variable(all.len() as u32 + 1), None);
        assert_eq!(layout.value_reference(RealVariable::Theta(0)), Some(9));
        assert_eq!(layout.value_reference(RealVariable::KineticEnergy), None);
    }
}
