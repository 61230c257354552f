//! The element and attribute types of an FMI 2.0 `modelDescription.xml`
//! (FMI 2.0.x specification §2.2 and §4.3.1), limited to what a
//! co-simulation FMU uses.
//!
//! Field names are snake_case; each is renamed to the exact FMI spelling
//! (`@` marks an XML attribute for quick-xml). Optional attributes are
//! `Option`s and are left out of the document when `None`. Wrapper elements
//! such as `<ModelVariables>` are not types of their own: their children are
//! plain `Vec`s (see [`crate::xsd`]).

use serde::{Deserialize, Serialize};

use crate::xsd;

/// Root element `<fmiModelDescription>` (§2.2.1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FmiModelDescription {
    /// `fmiVersion`: always "2.0".
    #[serde(rename = "@fmiVersion")]
    pub fmi_version: FmiVersion,
    /// `modelName`.
    #[serde(rename = "@modelName")]
    pub model_name: String,
    /// `guid`: must match the GUID compiled into the binary.
    #[serde(rename = "@guid")]
    pub guid: String,
    /// `description`.
    #[serde(rename = "@description", default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// `author`.
    #[serde(rename = "@author", default, skip_serializing_if = "Option::is_none")]
    pub author: Option<String>,
    /// `version` of the model.
    #[serde(rename = "@version", default, skip_serializing_if = "Option::is_none")]
    pub version: Option<String>,
    /// `copyright`.
    #[serde(rename = "@copyright", default, skip_serializing_if = "Option::is_none")]
    pub copyright: Option<String>,
    /// `license`.
    #[serde(rename = "@license", default, skip_serializing_if = "Option::is_none")]
    pub license: Option<String>,
    /// `generationTool`.
    #[serde(rename = "@generationTool", default, skip_serializing_if = "Option::is_none")]
    pub generation_tool: Option<String>,
    /// `generationDateAndTime`, an `xs:dateTime` such as `2024-01-31T12:00:00Z`.
    #[serde(rename = "@generationDateAndTime", default, skip_serializing_if = "Option::is_none")]
    pub generation_date_and_time: Option<String>,
    /// `variableNamingConvention`; absent means flat.
    #[serde(rename = "@variableNamingConvention", default, skip_serializing_if = "Option::is_none")]
    pub variable_naming_convention: Option<VariableNamingConvention>,
    /// `numberOfEventIndicators`.
    #[serde(rename = "@numberOfEventIndicators", default, skip_serializing_if = "Option::is_none")]
    pub number_of_event_indicators: Option<u32>,
    /// `<ModelExchange>`, for an FMU that also serves model exchange (it
    /// precedes `<CoSimulation>` in the schema's sequence).
    #[serde(rename = "ModelExchange", default, skip_serializing_if = "Option::is_none")]
    pub model_exchange: Option<ModelExchange>,
    /// `<CoSimulation>`: every nudyn FMU serves co-simulation.
    #[serde(rename = "CoSimulation")]
    pub co_simulation: CoSimulation,
    /// Children of `<UnitDefinitions>`.
    #[serde(
        rename = "UnitDefinitions",
        with = "xsd::unit_definitions",
        default,
        skip_serializing_if = "Vec::is_empty"
    )]
    pub unit_definitions: Vec<Unit>,
    /// Children of `<TypeDefinitions>`.
    #[serde(
        rename = "TypeDefinitions",
        with = "xsd::type_definitions",
        default,
        skip_serializing_if = "Vec::is_empty"
    )]
    pub type_definitions: Vec<SimpleType>,
    /// Children of `<LogCategories>`.
    #[serde(rename = "LogCategories", with = "xsd::log_categories", default, skip_serializing_if = "Vec::is_empty")]
    pub log_categories: Vec<Category>,
    /// `<DefaultExperiment>`.
    #[serde(rename = "DefaultExperiment", default, skip_serializing_if = "Option::is_none")]
    pub default_experiment: Option<DefaultExperiment>,
    /// Children of `<ModelVariables>`; position `i` has ScalarVariable index
    /// `i + 1`, the index that `<ModelStructure>` refers to.
    #[serde(rename = "ModelVariables", with = "xsd::model_variables")]
    pub model_variables: Vec<ScalarVariable>,
    /// `<ModelStructure>`.
    #[serde(rename = "ModelStructure")]
    pub model_structure: ModelStructure,
}

/// Value of `fmiVersion`. A single variant, so reading any other version
/// fails with a typed error instead of producing a wrong model.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum FmiVersion {
    /// FMI 2.0 ("2.0").
    #[default]
    #[serde(rename = "2.0")]
    Fmi2,
}

/// Value of `variableNamingConvention` (§2.2.9).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub enum VariableNamingConvention {
    /// "flat": any name without control characters.
    Flat,
    /// "structured": names such as `body.q[1]` and `der(x)`.
    Structured,
}

/// `<CoSimulation>` (§4.3.1). The capability flags default to `false` in the
/// schema; they are always written so the document states them explicitly.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct CoSimulation {
    /// `modelIdentifier`: the binary's file name stem and function prefix.
    #[serde(rename = "@modelIdentifier")]
    pub model_identifier: String,
    /// `needsExecutionTool`.
    #[serde(rename = "@needsExecutionTool", default)]
    pub needs_execution_tool: bool,
    /// `canHandleVariableCommunicationStepSize`.
    #[serde(rename = "@canHandleVariableCommunicationStepSize", default)]
    pub can_handle_variable_communication_step_size: bool,
    /// `canInterpolateInputs`.
    #[serde(rename = "@canInterpolateInputs", default)]
    pub can_interpolate_inputs: bool,
    /// `maxOutputDerivativeOrder`.
    #[serde(rename = "@maxOutputDerivativeOrder", default)]
    pub max_output_derivative_order: u32,
    /// `canRunAsynchronuously` (the standard's spelling).
    #[serde(rename = "@canRunAsynchronuously", default)]
    pub can_run_asynchronuously: bool,
    /// `canBeInstantiatedOnlyOncePerProcess`.
    #[serde(rename = "@canBeInstantiatedOnlyOncePerProcess", default)]
    pub can_be_instantiated_only_once_per_process: bool,
    /// `canNotUseMemoryManagementFunctions`.
    #[serde(rename = "@canNotUseMemoryManagementFunctions", default)]
    pub can_not_use_memory_management_functions: bool,
    /// `canGetAndSetFMUstate`.
    #[serde(rename = "@canGetAndSetFMUstate", default)]
    pub can_get_and_set_fmu_state: bool,
    /// `canSerializeFMUstate`.
    #[serde(rename = "@canSerializeFMUstate", default)]
    pub can_serialize_fmu_state: bool,
    /// `providesDirectionalDerivative`.
    #[serde(rename = "@providesDirectionalDerivative", default)]
    pub provides_directional_derivative: bool,
}

/// `<ModelExchange>` (§3.3.1). The capability flags are always written.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ModelExchange {
    /// `modelIdentifier`: the binary's file name stem and function prefix.
    #[serde(rename = "@modelIdentifier")]
    pub model_identifier: String,
    /// `needsExecutionTool`.
    #[serde(rename = "@needsExecutionTool", default)]
    pub needs_execution_tool: bool,
    /// `completedIntegratorStepNotNeeded`.
    #[serde(rename = "@completedIntegratorStepNotNeeded", default)]
    pub completed_integrator_step_not_needed: bool,
    /// `canBeInstantiatedOnlyOncePerProcess`.
    #[serde(rename = "@canBeInstantiatedOnlyOncePerProcess", default)]
    pub can_be_instantiated_only_once_per_process: bool,
    /// `canNotUseMemoryManagementFunctions`.
    #[serde(rename = "@canNotUseMemoryManagementFunctions", default)]
    pub can_not_use_memory_management_functions: bool,
    /// `canGetAndSetFMUstate`.
    #[serde(rename = "@canGetAndSetFMUstate", default)]
    pub can_get_and_set_fmu_state: bool,
    /// `canSerializeFMUstate`.
    #[serde(rename = "@canSerializeFMUstate", default)]
    pub can_serialize_fmu_state: bool,
    /// `providesDirectionalDerivative`.
    #[serde(rename = "@providesDirectionalDerivative", default)]
    pub provides_directional_derivative: bool,
}

/// `<Unit>` (§2.2.2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Unit {
    /// `name`, e.g. "m/s2"; referenced by the `unit` attribute of Real types
    /// and variables.
    #[serde(rename = "@name")]
    pub name: String,
    /// `<BaseUnit>`: the unit in SI base units.
    #[serde(rename = "BaseUnit", default, skip_serializing_if = "Option::is_none")]
    pub base_unit: Option<BaseUnit>,
    /// `<DisplayUnit>`s: alternative units for showing values to a person.
    #[serde(rename = "DisplayUnit", default, skip_serializing_if = "Vec::is_empty")]
    pub display_units: Vec<DisplayUnit>,
}

/// `<BaseUnit>` (§2.2.2): `value_in_unit * factor + offset` is the value in
/// `kg^kg * m^m * s^s * A^A * K^K * mol^mol * cd^cd * rad^rad`.
/// Exponents default to 0 and are written only when non-zero.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct BaseUnit {
    /// Exponent of kilogram.
    #[serde(rename = "@kg", default, skip_serializing_if = "is_zero")]
    pub kg: i32,
    /// Exponent of metre.
    #[serde(rename = "@m", default, skip_serializing_if = "is_zero")]
    pub m: i32,
    /// Exponent of second.
    #[serde(rename = "@s", default, skip_serializing_if = "is_zero")]
    pub s: i32,
    /// Exponent of ampere.
    #[serde(rename = "@A", default, skip_serializing_if = "is_zero")]
    pub a: i32,
    /// Exponent of kelvin.
    #[serde(rename = "@K", default, skip_serializing_if = "is_zero")]
    pub k: i32,
    /// Exponent of mole.
    #[serde(rename = "@mol", default, skip_serializing_if = "is_zero")]
    pub mol: i32,
    /// Exponent of candela.
    #[serde(rename = "@cd", default, skip_serializing_if = "is_zero")]
    pub cd: i32,
    /// Exponent of radian.
    #[serde(rename = "@rad", default, skip_serializing_if = "is_zero")]
    pub rad: i32,
    /// `factor`; absent means 1.
    #[serde(rename = "@factor", with = "xsd::optional_double", default, skip_serializing_if = "Option::is_none")]
    pub factor: Option<f64>,
    /// `offset`; absent means 0.
    #[serde(rename = "@offset", with = "xsd::optional_double", default, skip_serializing_if = "Option::is_none")]
    pub offset: Option<f64>,
}

fn is_zero(exponent: &i32) -> bool {
    *exponent == 0
}

/// `<DisplayUnit>` (§2.2.2): `display_value = factor * value + offset`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DisplayUnit {
    /// `name`, e.g. "deg"; referenced by `displayUnit`.
    #[serde(rename = "@name")]
    pub name: String,
    /// `factor`; absent means 1.
    #[serde(rename = "@factor", with = "xsd::optional_double", default, skip_serializing_if = "Option::is_none")]
    pub factor: Option<f64>,
    /// `offset`; absent means 0.
    #[serde(rename = "@offset", with = "xsd::optional_double", default, skip_serializing_if = "Option::is_none")]
    pub offset: Option<f64>,
}

/// `<SimpleType>` (§2.2.3): a named type that variables refer to with
/// `declaredType`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SimpleType {
    /// `name`.
    #[serde(rename = "@name")]
    pub name: String,
    /// `description`.
    #[serde(rename = "@description", default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// The one child element that gives the base type.
    #[serde(rename = "$value")]
    pub kind: SimpleTypeKind,
}

/// Child element of `<SimpleType>`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum SimpleTypeKind {
    /// `<Real>`.
    Real(RealType),
    /// `<Integer>`.
    Integer(IntegerType),
    /// `<Boolean/>`.
    Boolean,
    /// `<String/>`.
    String,
    /// `<Enumeration>` with its items.
    Enumeration(EnumerationType),
}

/// Attributes of `<SimpleType><Real>`, also the defaults of variables that
/// declare this type.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RealType {
    /// `quantity`, e.g. "Angle".
    #[serde(rename = "@quantity", default, skip_serializing_if = "Option::is_none")]
    pub quantity: Option<String>,
    /// `unit`: a `<Unit>` name.
    #[serde(rename = "@unit", default, skip_serializing_if = "Option::is_none")]
    pub unit: Option<String>,
    /// `displayUnit`: a `<DisplayUnit>` name of `unit`.
    #[serde(rename = "@displayUnit", default, skip_serializing_if = "Option::is_none")]
    pub display_unit: Option<String>,
    /// `relativeQuantity`; absent means false.
    #[serde(rename = "@relativeQuantity", default, skip_serializing_if = "Option::is_none")]
    pub relative_quantity: Option<bool>,
    /// `min`.
    #[serde(rename = "@min", with = "xsd::optional_double", default, skip_serializing_if = "Option::is_none")]
    pub min: Option<f64>,
    /// `max`.
    #[serde(rename = "@max", with = "xsd::optional_double", default, skip_serializing_if = "Option::is_none")]
    pub max: Option<f64>,
    /// `nominal`.
    #[serde(rename = "@nominal", with = "xsd::optional_double", default, skip_serializing_if = "Option::is_none")]
    pub nominal: Option<f64>,
    /// `unbounded`; absent means false.
    #[serde(rename = "@unbounded", default, skip_serializing_if = "Option::is_none")]
    pub unbounded: Option<bool>,
}

/// Attributes of `<SimpleType><Integer>`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct IntegerType {
    /// `quantity`.
    #[serde(rename = "@quantity", default, skip_serializing_if = "Option::is_none")]
    pub quantity: Option<String>,
    /// `min`.
    #[serde(rename = "@min", default, skip_serializing_if = "Option::is_none")]
    pub min: Option<i32>,
    /// `max`.
    #[serde(rename = "@max", default, skip_serializing_if = "Option::is_none")]
    pub max: Option<i32>,
}

/// `<SimpleType><Enumeration>`: named integer values.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct EnumerationType {
    /// `quantity`.
    #[serde(rename = "@quantity", default, skip_serializing_if = "Option::is_none")]
    pub quantity: Option<String>,
    /// `<Item>`s; the schema requires at least one.
    #[serde(rename = "Item", default)]
    pub items: Vec<Item>,
}

/// `<Item>` of an enumeration type.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Item {
    /// `name`.
    #[serde(rename = "@name")]
    pub name: String,
    /// `value`.
    #[serde(rename = "@value")]
    pub value: i32,
    /// `description`.
    #[serde(rename = "@description", default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
}

/// `<Category>` of `<LogCategories>` (§2.2.4).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Category {
    /// `name`, passed to `fmi2SetDebugLogging`.
    #[serde(rename = "@name")]
    pub name: String,
    /// `description`.
    #[serde(rename = "@description", default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
}

/// `<DefaultExperiment>` (§2.2.5).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DefaultExperiment {
    /// `startTime` in seconds.
    #[serde(rename = "@startTime", with = "xsd::optional_double", default, skip_serializing_if = "Option::is_none")]
    pub start_time: Option<f64>,
    /// `stopTime` in seconds.
    #[serde(rename = "@stopTime", with = "xsd::optional_double", default, skip_serializing_if = "Option::is_none")]
    pub stop_time: Option<f64>,
    /// `tolerance`: relative tolerance of the internal solver.
    #[serde(rename = "@tolerance", with = "xsd::optional_double", default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// `stepSize`: communication step size in seconds.
    #[serde(rename = "@stepSize", with = "xsd::optional_double", default, skip_serializing_if = "Option::is_none")]
    pub step_size: Option<f64>,
}

/// `<ScalarVariable>` (§2.2.7).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScalarVariable {
    /// `name`, unique in the model.
    #[serde(rename = "@name")]
    pub name: String,
    /// `valueReference`: the handle used by `fmi2Get*`/`fmi2Set*`.
    #[serde(rename = "@valueReference")]
    pub value_reference: u32,
    /// `description`.
    #[serde(rename = "@description", default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// `causality`; absent means local. Always written.
    #[serde(rename = "@causality", default)]
    pub causality: Causality,
    /// `variability`; absent means continuous. Always written.
    #[serde(rename = "@variability", default)]
    pub variability: Variability,
    /// `initial`; when absent its value follows from causality and
    /// variability (see [`crate::validate()`]).
    #[serde(rename = "@initial", default, skip_serializing_if = "Option::is_none")]
    pub initial: Option<Initial>,
    /// `canHandleMultipleSetPerTimeInstant`: meaningful for Model Exchange
    /// inputs only, so a co-simulation-only FMU must leave it out.
    #[serde(rename = "@canHandleMultipleSetPerTimeInstant", default, skip_serializing_if = "Option::is_none")]
    pub can_handle_multiple_set_per_time_instant: Option<bool>,
    /// The one child element that gives the variable's type.
    #[serde(rename = "$value")]
    pub kind: VariableKind,
}

/// Value of `causality` (§2.2.7).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub enum Causality {
    /// "parameter": set by the environment, fixed or tunable.
    Parameter,
    /// "calculatedParameter": computed from parameters during initialization.
    CalculatedParameter,
    /// "input": set by the environment, may change at each communication point.
    Input,
    /// "output": read by the environment.
    Output,
    /// "local": internal, only inspected.
    #[default]
    Local,
    /// "independent": the independent variable, usually time.
    Independent,
}

/// Value of `variability` (§2.2.7).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub enum Variability {
    /// "constant": never changes.
    Constant,
    /// "fixed": fixed after initialization.
    Fixed,
    /// "tunable": changes only at event instants set from outside.
    Tunable,
    /// "discrete": changes only at events.
    Discrete,
    /// "continuous": may change at any time; Real variables only.
    #[default]
    Continuous,
}

/// Value of `initial` (§2.2.7).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub enum Initial {
    /// "exact": initialized with `start`.
    Exact,
    /// "approx": `start` is a guess for an iteration during initialization.
    Approx,
    /// "calculated": computed during initialization; no `start`.
    Calculated,
}

/// Child element of `<ScalarVariable>` that gives its type and the
/// type-specific attributes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum VariableKind {
    /// `<Real>`.
    Real(RealVariable),
    /// `<Integer>`.
    Integer(IntegerVariable),
    /// `<Boolean>`.
    Boolean(BooleanVariable),
    /// `<String>`.
    String(StringVariable),
    /// `<Enumeration>`.
    Enumeration(EnumerationVariable),
}

/// `<ScalarVariable><Real>`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RealVariable {
    /// `declaredType`: a Real `<SimpleType>` name whose attributes are the
    /// defaults of this one's.
    #[serde(rename = "@declaredType", default, skip_serializing_if = "Option::is_none")]
    pub declared_type: Option<String>,
    /// `quantity`.
    #[serde(rename = "@quantity", default, skip_serializing_if = "Option::is_none")]
    pub quantity: Option<String>,
    /// `unit`: a `<Unit>` name.
    #[serde(rename = "@unit", default, skip_serializing_if = "Option::is_none")]
    pub unit: Option<String>,
    /// `displayUnit`: a `<DisplayUnit>` name of the unit.
    #[serde(rename = "@displayUnit", default, skip_serializing_if = "Option::is_none")]
    pub display_unit: Option<String>,
    /// `relativeQuantity`; absent means false.
    #[serde(rename = "@relativeQuantity", default, skip_serializing_if = "Option::is_none")]
    pub relative_quantity: Option<bool>,
    /// `min`.
    #[serde(rename = "@min", with = "xsd::optional_double", default, skip_serializing_if = "Option::is_none")]
    pub min: Option<f64>,
    /// `max`.
    #[serde(rename = "@max", with = "xsd::optional_double", default, skip_serializing_if = "Option::is_none")]
    pub max: Option<f64>,
    /// `nominal`.
    #[serde(rename = "@nominal", with = "xsd::optional_double", default, skip_serializing_if = "Option::is_none")]
    pub nominal: Option<f64>,
    /// `unbounded`; absent means false.
    #[serde(rename = "@unbounded", default, skip_serializing_if = "Option::is_none")]
    pub unbounded: Option<bool>,
    /// `start`.
    #[serde(rename = "@start", with = "xsd::optional_double", default, skip_serializing_if = "Option::is_none")]
    pub start: Option<f64>,
    /// `derivative`: 1-based ScalarVariable index of the variable this one
    /// is the time derivative of.
    #[serde(rename = "@derivative", default, skip_serializing_if = "Option::is_none")]
    pub derivative: Option<u32>,
    /// `reinit` (Model Exchange only); absent means false.
    #[serde(rename = "@reinit", default, skip_serializing_if = "Option::is_none")]
    pub reinit: Option<bool>,
}

/// `<ScalarVariable><Integer>`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct IntegerVariable {
    /// `declaredType`: an Integer `<SimpleType>` name.
    #[serde(rename = "@declaredType", default, skip_serializing_if = "Option::is_none")]
    pub declared_type: Option<String>,
    /// `quantity`.
    #[serde(rename = "@quantity", default, skip_serializing_if = "Option::is_none")]
    pub quantity: Option<String>,
    /// `min`.
    #[serde(rename = "@min", default, skip_serializing_if = "Option::is_none")]
    pub min: Option<i32>,
    /// `max`.
    #[serde(rename = "@max", default, skip_serializing_if = "Option::is_none")]
    pub max: Option<i32>,
    /// `start`.
    #[serde(rename = "@start", default, skip_serializing_if = "Option::is_none")]
    pub start: Option<i32>,
}

/// `<ScalarVariable><Boolean>`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct BooleanVariable {
    /// `declaredType`: a Boolean `<SimpleType>` name.
    #[serde(rename = "@declaredType", default, skip_serializing_if = "Option::is_none")]
    pub declared_type: Option<String>,
    /// `start`.
    #[serde(rename = "@start", default, skip_serializing_if = "Option::is_none")]
    pub start: Option<bool>,
}

/// `<ScalarVariable><String>`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct StringVariable {
    /// `declaredType`: a String `<SimpleType>` name.
    #[serde(rename = "@declaredType", default, skip_serializing_if = "Option::is_none")]
    pub declared_type: Option<String>,
    /// `start`.
    #[serde(rename = "@start", default, skip_serializing_if = "Option::is_none")]
    pub start: Option<String>,
}

/// `<ScalarVariable><Enumeration>`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct EnumerationVariable {
    /// `declaredType`: an Enumeration `<SimpleType>` name (required).
    #[serde(rename = "@declaredType")]
    pub declared_type: String,
    /// `quantity`.
    #[serde(rename = "@quantity", default, skip_serializing_if = "Option::is_none")]
    pub quantity: Option<String>,
    /// `min`.
    #[serde(rename = "@min", default, skip_serializing_if = "Option::is_none")]
    pub min: Option<i32>,
    /// `max`.
    #[serde(rename = "@max", default, skip_serializing_if = "Option::is_none")]
    pub max: Option<i32>,
    /// `start`: an item value.
    #[serde(rename = "@start", default, skip_serializing_if = "Option::is_none")]
    pub start: Option<i32>,
}

/// `<ModelStructure>` (§2.2.8). Each list holds `<Unknown>` elements; an
/// empty list is left out, as the schema requires.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ModelStructure {
    /// `<Outputs>`: every output variable, in ScalarVariable order.
    #[serde(rename = "Outputs", with = "xsd::unknowns", default, skip_serializing_if = "Vec::is_empty")]
    pub outputs: Vec<Unknown>,
    /// `<Derivatives>`: the continuous state derivatives.
    #[serde(rename = "Derivatives", with = "xsd::unknowns", default, skip_serializing_if = "Vec::is_empty")]
    pub derivatives: Vec<Unknown>,
    /// `<InitialUnknowns>`: the unknowns of Initialization Mode.
    #[serde(rename = "InitialUnknowns", with = "xsd::unknowns", default, skip_serializing_if = "Vec::is_empty")]
    pub initial_unknowns: Vec<Unknown>,
}

/// `<Unknown>` of a `<ModelStructure>` list.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Unknown {
    /// `index`: 1-based ScalarVariable index of the unknown.
    #[serde(rename = "@index")]
    pub index: u32,
    /// `dependencies`: 1-based ScalarVariable indices of the knowns it
    /// depends on, ascending. `None` means "depends on all knowns";
    /// `Some(vec![])` (written `dependencies=""`) means "depends on none".
    #[serde(rename = "@dependencies", default, skip_serializing_if = "Option::is_none")]
    pub dependencies: Option<Vec<u32>>,
    /// `dependenciesKind`: one kind per entry of `dependencies`.
    #[serde(rename = "@dependenciesKind", default, skip_serializing_if = "Option::is_none")]
    pub dependencies_kind: Option<Vec<DependencyKind>>,
}

impl Unknown {
    /// An unknown at `index` with no dependency information (it may depend
    /// on every known).
    pub fn new(index: u32) -> Self {
        Self { index, dependencies: None, dependencies_kind: None }
    }
}

/// Entry of `dependenciesKind` (§2.2.8).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub enum DependencyKind {
    /// "dependent": no particular structure.
    Dependent,
    /// "constant": linear with a constant factor.
    Constant,
    /// "fixed": linear with a factor fixed after initialization.
    Fixed,
    /// "tunable": linear with a factor that changes only with tunable parameters.
    Tunable,
    /// "discrete": linear with a factor that changes only at events.
    Discrete,
}

/// Writes the FMI spelling of each variant, e.g. `calculatedParameter`.
macro_rules! display_fmi_spelling {
    ($type:ty { $($variant:ident => $spelling:literal),+ $(,)? }) => {
        impl std::fmt::Display for $type {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(match self { $(Self::$variant => $spelling),+ })
            }
        }
    };
}

display_fmi_spelling!(Causality {
    Parameter => "parameter",
    CalculatedParameter => "calculatedParameter",
    Input => "input",
    Output => "output",
    Local => "local",
    Independent => "independent",
});
display_fmi_spelling!(Variability {
    Constant => "constant",
    Fixed => "fixed",
    Tunable => "tunable",
    Discrete => "discrete",
    Continuous => "continuous",
});
display_fmi_spelling!(Initial { Exact => "exact", Approx => "approx", Calculated => "calculated" });
display_fmi_spelling!(DependencyKind {
    Dependent => "dependent",
    Constant => "constant",
    Fixed => "fixed",
    Tunable => "tunable",
    Discrete => "discrete",
});
