//! The element and attribute types of an FMI 3.0 `modelDescription.xml`
//! (FMI 3.0 §2.4), limited to what a nudyn FMU uses: model exchange and
//! co-simulation, Float64 (scalar and 1-D array), Boolean and Enumeration
//! variables, enumeration types, log categories, the default experiment and
//! the model structure. Written and read like the FMI 2.0 types
//! ([`crate::FmiModelDescription`]); [`validate`] checks the rules the schema
//! cannot express.

use std::collections::{BTreeMap, BTreeSet};

use serde::{Deserialize, Serialize};

use crate::xsd;
use crate::{Category, DefaultExperiment, Error};

/// Root element `<fmiModelDescription>` (§2.4.1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Fmi3ModelDescription {
    /// `fmiVersion`: "3.0".
    #[serde(rename = "@fmiVersion")]
    pub fmi_version: String,
    /// `modelName`.
    #[serde(rename = "@modelName")]
    pub model_name: String,
    /// `instantiationToken`: must match what the binary expects.
    #[serde(rename = "@instantiationToken")]
    pub instantiation_token: String,
    /// `description`.
    #[serde(rename = "@description", default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// `generationTool`.
    #[serde(rename = "@generationTool", default, skip_serializing_if = "Option::is_none")]
    pub generation_tool: Option<String>,
    /// `generationDateAndTime`: xs:dateTime, e.g. 2026-11-25T10:00:00Z.
    #[serde(rename = "@generationDateAndTime", default, skip_serializing_if = "Option::is_none")]
    pub generation_date_and_time: Option<String>,
    /// `variableNamingConvention`: "flat" or "structured".
    #[serde(rename = "@variableNamingConvention", default, skip_serializing_if = "Option::is_none")]
    pub variable_naming_convention: Option<String>,
    /// `<ModelExchange>`.
    #[serde(rename = "ModelExchange", default, skip_serializing_if = "Option::is_none")]
    pub model_exchange: Option<ModelExchange>,
    /// `<CoSimulation>`.
    #[serde(rename = "CoSimulation", default, skip_serializing_if = "Option::is_none")]
    pub co_simulation: Option<CoSimulation>,
    /// Children of `<TypeDefinitions>`.
    #[serde(rename = "TypeDefinitions", default, skip_serializing_if = "Option::is_none")]
    pub type_definitions: Option<TypeDefinitions>,
    /// Children of `<LogCategories>`.
    #[serde(rename = "LogCategories", with = "xsd::log_categories", default, skip_serializing_if = "Vec::is_empty")]
    pub log_categories: Vec<Category>,
    /// `<DefaultExperiment>`.
    #[serde(rename = "DefaultExperiment", default, skip_serializing_if = "Option::is_none")]
    pub default_experiment: Option<DefaultExperiment>,
    /// `<ModelVariables>`.
    #[serde(rename = "ModelVariables")]
    pub model_variables: ModelVariables,
    /// `<ModelStructure>`.
    #[serde(rename = "ModelStructure")]
    pub model_structure: ModelStructure,
}

/// `<ModelExchange>` (§3.4): capability flags, always written.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ModelExchange {
    /// `modelIdentifier`.
    #[serde(rename = "@modelIdentifier")]
    pub model_identifier: String,
    /// `needsCompletedIntegratorStep`.
    #[serde(rename = "@needsCompletedIntegratorStep")]
    pub needs_completed_integrator_step: bool,
    /// `canGetAndSetFMUState`.
    #[serde(rename = "@canGetAndSetFMUState")]
    pub can_get_and_set_fmu_state: bool,
    /// `canSerializeFMUState`.
    #[serde(rename = "@canSerializeFMUState")]
    pub can_serialize_fmu_state: bool,
    /// `providesDirectionalDerivatives`.
    #[serde(rename = "@providesDirectionalDerivatives")]
    pub provides_directional_derivatives: bool,
    /// `providesAdjointDerivatives`.
    #[serde(rename = "@providesAdjointDerivatives")]
    pub provides_adjoint_derivatives: bool,
    /// `providesPerElementDependencies`.
    #[serde(rename = "@providesPerElementDependencies")]
    pub provides_per_element_dependencies: bool,
}

/// `<CoSimulation>` (§4.4): capability flags, always written.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct CoSimulation {
    /// `modelIdentifier`.
    #[serde(rename = "@modelIdentifier")]
    pub model_identifier: String,
    /// `canGetAndSetFMUState`.
    #[serde(rename = "@canGetAndSetFMUState")]
    pub can_get_and_set_fmu_state: bool,
    /// `canSerializeFMUState`.
    #[serde(rename = "@canSerializeFMUState")]
    pub can_serialize_fmu_state: bool,
    /// `providesDirectionalDerivatives`.
    #[serde(rename = "@providesDirectionalDerivatives")]
    pub provides_directional_derivatives: bool,
    /// `providesAdjointDerivatives`.
    #[serde(rename = "@providesAdjointDerivatives")]
    pub provides_adjoint_derivatives: bool,
    /// `providesPerElementDependencies`.
    #[serde(rename = "@providesPerElementDependencies")]
    pub provides_per_element_dependencies: bool,
    /// `canHandleVariableCommunicationStepSize`.
    #[serde(rename = "@canHandleVariableCommunicationStepSize")]
    pub can_handle_variable_communication_step_size: bool,
    /// `maxOutputDerivativeOrder`.
    #[serde(rename = "@maxOutputDerivativeOrder")]
    pub max_output_derivative_order: u32,
    /// `providesIntermediateUpdate`.
    #[serde(rename = "@providesIntermediateUpdate")]
    pub provides_intermediate_update: bool,
    /// `mightReturnEarlyFromDoStep`.
    #[serde(rename = "@mightReturnEarlyFromDoStep")]
    pub might_return_early_from_do_step: bool,
    /// `hasEventMode`.
    #[serde(rename = "@hasEventMode")]
    pub has_event_mode: bool,
}

/// `<TypeDefinitions>`: nudyn declares enumeration types only.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct TypeDefinitions {
    /// `<EnumerationType>`s.
    #[serde(rename = "EnumerationType", default)]
    pub enumeration_types: Vec<EnumerationType>,
}

/// `<EnumerationType>` (§2.4.3).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct EnumerationType {
    /// `name`.
    #[serde(rename = "@name")]
    pub name: String,
    /// `description`.
    #[serde(rename = "@description", default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// `<Item>`s.
    #[serde(rename = "Item", default)]
    pub items: Vec<Item>,
}

/// `<Item>` of an enumeration type (values are Int64).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Item {
    /// `name`.
    #[serde(rename = "@name")]
    pub name: String,
    /// `value`.
    #[serde(rename = "@value")]
    pub value: i64,
    /// `description`.
    #[serde(rename = "@description", default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
}

/// `<ModelVariables>`: variables of any type, in value-reference order here.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ModelVariables {
    /// The variables.
    #[serde(rename = "$value", default)]
    pub variables: Vec<Variable>,
}

/// A variable element of `<ModelVariables>`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Variable {
    /// `<Float64>`.
    Float64(Float64),
    /// `<Boolean>`.
    Boolean(Boolean),
    /// `<Enumeration>`.
    Enumeration(Enumeration),
}

/// The attributes every variable has (§2.4.7), borrowed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Common<'a> {
    /// `name`.
    pub name: &'a str,
    /// `valueReference`, unique across all variables.
    pub value_reference: u32,
    /// `causality`.
    pub causality: &'a str,
    /// `variability`.
    pub variability: &'a str,
}

/// A variable type's struct: the attributes every variable has, then its own.
/// (quick-xml cannot read flattened attribute structs, so each type lists them.)
macro_rules! variable_type {
    ($(#[$meta:meta])* $name:ident { $($(#[$field_meta:meta])* $field:ident: $type:ty,)* }) => {
        $(#[$meta])*
        #[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
        pub struct $name {
            /// `name`.
            #[serde(rename = "@name")]
            pub name: String,
            /// `valueReference`, unique across all variables.
            #[serde(rename = "@valueReference")]
            pub value_reference: u32,
            /// `description`.
            #[serde(rename = "@description", default, skip_serializing_if = "Option::is_none")]
            pub description: Option<String>,
            /// `causality`: parameter, input, output, local, independent.
            #[serde(rename = "@causality")]
            pub causality: String,
            /// `variability`: fixed, tunable, continuous.
            #[serde(rename = "@variability")]
            pub variability: String,
            /// `initial`: exact or calculated.
            #[serde(rename = "@initial", default, skip_serializing_if = "Option::is_none")]
            pub initial: Option<String>,
            $($(#[$field_meta])* pub $field: $type,)*
        }

        impl $name {
            /// The common attributes.
            pub fn common(&self) -> Common<'_> {
                Common {
                    name: &self.name,
                    value_reference: self.value_reference,
                    causality: &self.causality,
                    variability: &self.variability,
                }
            }
        }
    };
}

variable_type!(
    /// `<Float64>`: a scalar, or an array with one `<Dimension>`.
    Float64 {
        /// `unit`.
        #[serde(rename = "@unit", default, skip_serializing_if = "Option::is_none")]
        unit: Option<String>,
        /// `min`.
        #[serde(rename = "@min", with = "xsd::optional_double", default, skip_serializing_if = "Option::is_none")]
        min: Option<f64>,
        /// `start`: one value per element.
        #[serde(rename = "@start", with = "xsd::double_list", default, skip_serializing_if = "Option::is_none")]
        start: Option<Vec<f64>>,
        /// `derivative`: the value reference of the variable this one is the time derivative of.
        #[serde(rename = "@derivative", default, skip_serializing_if = "Option::is_none")]
        derivative: Option<u32>,
        /// `<Dimension>`s: one for a 1-D array, none for a scalar.
        #[serde(rename = "Dimension", default, skip_serializing_if = "Vec::is_empty")]
        dimensions: Vec<Dimension>,
    }
);

/// `<Dimension start="n"/>`: a fixed array size.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Dimension {
    /// `start`: the number of elements.
    #[serde(rename = "@start")]
    pub start: u64,
}

variable_type!(
    /// `<Boolean>`.
    Boolean {
        /// `start`.
        #[serde(rename = "@start", default, skip_serializing_if = "Option::is_none")]
        start: Option<bool>,
    }
);

variable_type!(
    /// `<Enumeration>`.
    Enumeration {
        /// `declaredType`: an `<EnumerationType>`.
        #[serde(rename = "@declaredType")]
        declared_type: String,
        /// `start`: an item value.
        #[serde(rename = "@start", default, skip_serializing_if = "Option::is_none")]
        start: Option<i64>,
    }
);

impl Variable {
    /// The common attributes.
    pub fn common(&self) -> Common<'_> {
        match self {
            Variable::Float64(v) => v.common(),
            Variable::Boolean(v) => v.common(),
            Variable::Enumeration(v) => v.common(),
        }
    }
}

/// `<ModelStructure>` (§2.4.8).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ModelStructure {
    /// `<Output>`s: every output, in value-reference order.
    #[serde(rename = "Output", default, skip_serializing_if = "Vec::is_empty")]
    pub outputs: Vec<Unknown>,
    /// `<ContinuousStateDerivative>`s.
    #[serde(rename = "ContinuousStateDerivative", default, skip_serializing_if = "Vec::is_empty")]
    pub continuous_state_derivatives: Vec<Unknown>,
    /// `<InitialUnknown>`s.
    #[serde(rename = "InitialUnknown", default, skip_serializing_if = "Vec::is_empty")]
    pub initial_unknowns: Vec<Unknown>,
    /// `<EventIndicator>`s, in the order of fmi3GetEventIndicators (an
    /// array's elements in order).
    #[serde(rename = "EventIndicator", default, skip_serializing_if = "Vec::is_empty")]
    pub event_indicators: Vec<Unknown>,
}

/// An unknown of `<ModelStructure>`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Unknown {
    /// `valueReference`.
    #[serde(rename = "@valueReference")]
    pub value_reference: u32,
    /// `dependencies`: value references of the knowns, ascending; `None`: all.
    #[serde(rename = "@dependencies", default, skip_serializing_if = "Option::is_none")]
    pub dependencies: Option<Vec<u32>>,
}

/// Writes `model` as a complete, indented document.
pub fn to_xml(model: &Fmi3ModelDescription) -> Result<String, Error> {
    crate::write_document(model)
}

/// Reads an FMI 3.0 `modelDescription.xml`.
pub fn from_xml(document: &str) -> Result<Fmi3ModelDescription, Error> {
    Ok(quick_xml::de::from_str(document)?)
}

/// What [`validate`] found wrong, naming the variable.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Problem3 {
    /// fmiVersion is not 3.0.
    #[error("fmiVersion is '{0}', not 3.0")]
    Version(String),
    /// Two variables share a name.
    #[error("the name '{0}' is used more than once")]
    RepeatedName(String),
    /// Two variables share a value reference.
    #[error("value reference {0} is used more than once")]
    RepeatedValueReference(u32),
    /// No variable has causality independent.
    #[error("no variable has causality=\"independent\"")]
    NoIndependent,
    /// A start list whose length is not the array's size.
    #[error("'{name}' has {found} start values for {expected} elements")]
    StartLength {
        /// The variable.
        name: String,
        /// Its element count.
        expected: u64,
        /// The start values.
        found: usize,
    },
    /// A reference (derivative, structure, dependency, declared type) to nothing suitable.
    #[error("{what} of '{name}' refers to {target}, which is not {must}")]
    Reference {
        /// Which reference.
        what: &'static str,
        /// The variable holding it.
        name: String,
        /// What it refers to.
        target: String,
        /// What it must be.
        must: &'static str,
    },
    /// An output missing from, or a non-output in, the `<Output>` list.
    #[error("the <Output> list does not list exactly the outputs, in order")]
    Outputs,
}

/// The semantic rules of FMI 3.0 that nudyn's documents must meet: unique
/// names and value references, one independent variable, start lists of
/// the arrays' sizes, derivatives of continuous Float64 states of the same
/// size, declared types that exist, and a model structure whose lists name
/// outputs, derivatives, event indicators and knowns that exist.
pub fn validate(model: &Fmi3ModelDescription) -> Vec<Problem3> {
    let mut problems = Vec::new();
    if model.fmi_version != "3.0" {
        problems.push(Problem3::Version(model.fmi_version.clone()));
    }
    let variables = &model.model_variables.variables;
    let mut names = BTreeSet::new();
    let mut by_vr: BTreeMap<u32, &Variable> = BTreeMap::new();
    for variable in variables {
        let common = variable.common();
        if !names.insert(common.name) {
            problems.push(Problem3::RepeatedName(common.name.to_string()));
        }
        if by_vr.insert(common.value_reference, variable).is_some() {
            problems.push(Problem3::RepeatedValueReference(common.value_reference));
        }
    }
    if !variables.iter().any(|v| v.common().causality == "independent") {
        problems.push(Problem3::NoIndependent);
    }
    let size = |variable: &Float64| variable.dimensions.iter().map(|d| d.start).product::<u64>();
    let enumeration_types: BTreeSet<&str> =
        model.type_definitions.iter().flat_map(|t| t.enumeration_types.iter().map(|e| e.name.as_str())).collect();
    for variable in variables {
        let name = variable.common().name.to_string();
        match variable {
            Variable::Float64(float) => {
                if let Some(start) = &float.start
                    && start.len() as u64 != size(float)
                {
                    problems.push(Problem3::StartLength {
                        name: name.clone(),
                        expected: size(float),
                        found: start.len(),
                    });
                }
                if let Some(state) = float.derivative {
                    let fits = matches!(by_vr.get(&state), Some(Variable::Float64(s))
                        if s.variability == "continuous" && size(s) == size(float));
                    if !fits {
                        let target = format!("value reference {state}");
                        let must = "a continuous Float64 of the same size";
                        problems.push(Problem3::Reference { what: "derivative", name, target, must });
                    }
                }
            }
            Variable::Enumeration(enumeration) if !enumeration_types.contains(enumeration.declared_type.as_str()) => {
                let target = enumeration.declared_type.clone();
                problems.push(Problem3::Reference { what: "declaredType", name, target, must: "an EnumerationType" });
            }
            _ => {}
        }
    }
    let structure = &model.model_structure;
    let outputs: Vec<u32> =
        variables.iter().filter(|v| v.common().causality == "output").map(|v| v.common().value_reference).collect();
    if structure.outputs.iter().map(|u| u.value_reference).collect::<Vec<u32>>() != outputs {
        problems.push(Problem3::Outputs);
    }
    let lists = [
        ("a <ContinuousStateDerivative>", &structure.continuous_state_derivatives),
        ("an <Output>", &structure.outputs),
        ("an <InitialUnknown>", &structure.initial_unknowns),
        ("an <EventIndicator>", &structure.event_indicators),
    ];
    for (what, list) in lists {
        for unknown in list {
            let name = format!("value reference {}", unknown.value_reference);
            let Some(variable) = by_vr.get(&unknown.value_reference) else {
                let target = name.clone();
                problems.push(Problem3::Reference { what: "the model structure", name, target, must: "a variable" });
                continue;
            };
            if what == "a <ContinuousStateDerivative>"
                && !matches!(variable, Variable::Float64(f) if f.derivative.is_some())
            {
                let target = variable.common().name.to_string();
                let must = "a state derivative";
                problems.push(Problem3::Reference {
                    what: "<ContinuousStateDerivative>",
                    name: name.clone(),
                    target,
                    must,
                });
            }
            // FMI 3.0 §2.4.8: an event indicator is a continuous Float64, local or an output.
            if what == "an <EventIndicator>"
                && !matches!(variable, Variable::Float64(f) if f.variability == "continuous"
                    && matches!(f.causality.as_str(), "local" | "output"))
            {
                let target = variable.common().name.to_string();
                let must = "a continuous Float64, local or an output";
                problems.push(Problem3::Reference { what: "<EventIndicator>", name: name.clone(), target, must });
            }
            for known in unknown.dependencies.iter().flatten() {
                if !by_vr.contains_key(known) {
                    let target = format!("value reference {known}");
                    let name = variable.common().name.to_string();
                    problems.push(Problem3::Reference { what: "dependencies", name, target, must: "a variable" });
                }
            }
        }
    }
    problems
}
