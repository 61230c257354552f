//! Semantic checks of a model description: the rules of the FMI 2.0
//! standard that the XML schema cannot express, the ones an importer such as
//! FMPy or the FMI compliance checker enforces.

use std::cmp::Ordering;
use std::collections::hash_map::Entry;
use std::collections::{HashMap, HashSet};
use std::fmt;

use crate::model::*;

/// A `<ModelStructure>` list.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StructureList {
    /// `<Outputs>`.
    Outputs,
    /// `<Derivatives>`.
    Derivatives,
    /// `<InitialUnknowns>`.
    InitialUnknowns,
}

impl fmt::Display for StructureList {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Outputs => "Outputs",
            Self::Derivatives => "Derivatives",
            Self::InitialUnknowns => "InitialUnknowns",
        })
    }
}

/// The `fmi2Get*`/`fmi2Set*` family a variable is accessed through, which
/// scopes its value reference. Enumerations use `fmi2GetInteger`, so they
/// share the Integer references.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BaseType {
    /// `fmi2Real`.
    Real,
    /// `fmi2Integer` (Integer and Enumeration variables).
    Integer,
    /// `fmi2Boolean`.
    Boolean,
    /// `fmi2String`.
    String,
}

impl fmt::Display for BaseType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Real => "Real",
            Self::Integer => "Integer/Enumeration",
            Self::Boolean => "Boolean",
            Self::String => "String",
        })
    }
}

/// One violation of an FMI 2.0 rule, found by [`validate()`]. The message
/// names the section of the standard that states the rule.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Problem {
    /// The schema requires at least one `<ScalarVariable>`.
    #[error("§2.2.7: <ModelVariables> holds no <ScalarVariable>")]
    NoModelVariables,

    /// Two `<Unit>`s share a name.
    #[error("§2.2.2: unit \"{0}\" is defined more than once")]
    DuplicateUnit(String),
    /// A `<Unit>` defines two `<DisplayUnit>`s with the same name.
    #[error("§2.2.2: unit \"{unit}\" defines display unit \"{display_unit}\" more than once")]
    DuplicateDisplayUnit {
        /// Unit name.
        unit: String,
        /// Repeated display unit name.
        display_unit: String,
    },

    /// Two `<SimpleType>`s share a name.
    #[error("§2.2.3: type \"{0}\" is defined more than once")]
    DuplicateType(String),
    /// A `<SimpleType>` has the name of a `<ScalarVariable>`.
    #[error("§2.2.3: type name \"{0}\" is also a variable name")]
    TypeNameIsVariableName(String),
    /// An enumeration type without `<Item>`s.
    #[error("§2.2.3: enumeration type \"{0}\" has no <Item>")]
    EmptyEnumeration(String),
    /// Two items of one enumeration share a name.
    #[error("§2.2.3: enumeration type \"{type_name}\" has more than one item named \"{item}\"")]
    DuplicateItemName {
        /// Enumeration type name.
        type_name: String,
        /// Repeated item name.
        item: String,
    },
    /// Two items of one enumeration share a value.
    #[error("§2.2.3: enumeration type \"{type_name}\" has more than one item with value {value}")]
    DuplicateItemValue {
        /// Enumeration type name.
        type_name: String,
        /// Repeated item value.
        value: i32,
    },
    /// A Real type's `unit` is not a `<Unit>`.
    #[error("§2.2.3: type \"{type_name}\" has unit \"{unit}\", which <UnitDefinitions> does not define")]
    UndefinedTypeUnit {
        /// Type name.
        type_name: String,
        /// Undefined unit name.
        unit: String,
    },
    /// A Real type's `displayUnit` is not a `<DisplayUnit>` of its unit.
    #[error("§2.2.3: type \"{type_name}\" has display unit \"{display_unit}\", which its unit does not define")]
    UndefinedTypeDisplayUnit {
        /// Type name.
        type_name: String,
        /// Undefined display unit name.
        display_unit: String,
    },
    /// A Real or Integer type with `min > max`.
    #[error("§2.2.3: type \"{0}\" has min > max")]
    TypeMinExceedsMax(String),

    /// Two `<Category>`s share a name.
    #[error("§2.2.4: log category \"{0}\" is defined more than once")]
    DuplicateLogCategory(String),

    /// `stopTime` is not after `startTime`.
    #[error("§2.2.5: stopTime {stop_time} is not after startTime {start_time}")]
    StopTimeNotAfterStartTime {
        /// `startTime`.
        start_time: f64,
        /// `stopTime`.
        stop_time: f64,
    },
    /// `tolerance` or `stepSize` is not a positive number.
    #[error("§2.2.5: {attribute} {value} is not positive")]
    NonPositiveExperimentAttribute {
        /// `"tolerance"` or `"stepSize"`.
        attribute: &'static str,
        /// Its value.
        value: f64,
    },

    /// Two variables share a name.
    #[error("§2.2.7: variable name \"{0}\" is used more than once")]
    DuplicateVariableName(String),
    /// Two variables of one base type share a value reference.
    ///
    /// FMI 2.0 allows this for alias variables; nudyn's FMUs define no
    /// aliases, so a shared reference is reported as a generator bug.
    #[error("§2.2.7: variables \"{first}\" and \"{second}\" share {base_type} value reference {value_reference}")]
    SharedValueReference {
        /// The base type whose references collide.
        base_type: BaseType,
        /// The shared value reference.
        value_reference: u32,
        /// Variable that has it first.
        first: String,
        /// Variable that repeats it.
        second: String,
    },
    /// A causality/variability pair the standard forbids, e.g.
    /// constant input or continuous parameter.
    #[error("§2.2.7: variable \"{variable}\" combines causality=\"{causality}\" with variability=\"{variability}\"")]
    IllegalCausalityVariability {
        /// Variable name.
        variable: String,
        /// Its causality.
        causality: Causality,
        /// Its variability.
        variability: Variability,
    },
    /// An `initial` value the standard forbids for the variable's
    /// causality and variability (inputs and the independent variable take
    /// none at all).
    #[error(
        "§2.2.7: variable \"{variable}\" (causality=\"{causality}\", variability=\"{variability}\") may not have initial=\"{initial}\""
    )]
    IllegalInitial {
        /// Variable name.
        variable: String,
        /// Its causality.
        causality: Causality,
        /// Its variability.
        variability: Variability,
        /// The forbidden `initial`.
        initial: Initial,
    },
    /// No `start` although `initial` is exact or approx, or the variable is an input.
    #[error("§2.2.7: variable \"{0}\" needs a start value (initial exact/approx, or causality input)")]
    MissingStart(String),
    /// A `start` although `initial` is calculated or the variable is independent.
    #[error("§2.2.7: variable \"{0}\" may not have a start value (initial calculated, or causality independent)")]
    UnexpectedStart(String),
    /// `variability="continuous"` on a variable that is not Real.
    #[error("§2.2.7: variable \"{0}\" is continuous but not Real")]
    ContinuousNotReal(String),
    /// More than one variable with `causality="independent"`.
    #[error("§2.2.7: variables \"{first}\" and \"{second}\" are both independent")]
    MultipleIndependent {
        /// The first independent variable.
        first: String,
        /// A further one.
        second: String,
    },
    /// `canHandleMultipleSetPerTimeInstant` in a co-simulation-only FMU.
    #[error("§2.2.7: variable \"{0}\" has canHandleMultipleSetPerTimeInstant, which is for Model Exchange only")]
    MultipleSetInCoSimulation(String),
    /// `declaredType` names no `<SimpleType>`.
    #[error(
        "§2.2.7: variable \"{variable}\" declares type \"{declared_type}\", which <TypeDefinitions> does not define"
    )]
    UndefinedDeclaredType {
        /// Variable name.
        variable: String,
        /// The undefined type name.
        declared_type: String,
    },
    /// `declaredType` names a `<SimpleType>` of another base type.
    #[error("§2.2.7: variable \"{variable}\" declares type \"{declared_type}\" of another base type")]
    DeclaredTypeMismatch {
        /// Variable name.
        variable: String,
        /// The declared type name.
        declared_type: String,
    },
    /// A Real variable's `unit` is not a `<Unit>`.
    #[error("§2.2.7: variable \"{variable}\" has unit \"{unit}\", which <UnitDefinitions> does not define")]
    UndefinedUnit {
        /// Variable name.
        variable: String,
        /// Undefined unit name.
        unit: String,
    },
    /// A Real variable's `displayUnit` is not a `<DisplayUnit>` of its
    /// (own or declared) unit, or it has no unit.
    #[error("§2.2.7: variable \"{variable}\" has display unit \"{display_unit}\", which its unit does not define")]
    UndefinedDisplayUnit {
        /// Variable name.
        variable: String,
        /// Undefined display unit name.
        display_unit: String,
    },
    /// `min > max`, counting bounds inherited from the declared type.
    #[error("§2.2.7: variable \"{0}\" has min > max")]
    MinExceedsMax(String),
    /// `start` outside `[min, max]`, counting bounds inherited from the declared type.
    #[error("§2.2.7: variable \"{0}\" has a start value outside [min, max]")]
    StartOutOfRange(String),
    /// `derivative` is not the index of a Real variable.
    #[error(
        "§2.2.7: variable \"{variable}\" has derivative=\"{derivative}\", which is not the index of a Real variable"
    )]
    InvalidDerivative {
        /// Variable name.
        variable: String,
        /// The `derivative` attribute.
        derivative: u32,
    },

    /// An `<Unknown>` index outside `1..=number of variables`.
    #[error("§2.2.8: <{list}> has <Unknown index=\"{index}\">, which is no ScalarVariable index")]
    IndexOutOfRange {
        /// The list holding the unknown.
        list: StructureList,
        /// The bad index.
        index: u32,
    },
    /// A `dependencies` entry outside `1..=number of variables`.
    #[error("§2.2.8: <{list}> unknown {index} depends on {dependency}, which is no ScalarVariable index")]
    DependencyOutOfRange {
        /// The list holding the unknown.
        list: StructureList,
        /// The unknown's index.
        index: u32,
        /// The bad dependency.
        dependency: u32,
    },
    /// `dependencies` not strictly ascending.
    #[error("§2.2.8: <{list}> unknown {index} has dependencies that are not strictly ascending")]
    DependenciesNotAscending {
        /// The list holding the unknown.
        list: StructureList,
        /// The unknown's index.
        index: u32,
    },
    /// `dependenciesKind` without `dependencies`.
    #[error("§2.2.8: <{list}> unknown {index} has dependenciesKind but no dependencies")]
    DependenciesKindWithoutDependencies {
        /// The list holding the unknown.
        list: StructureList,
        /// The unknown's index.
        index: u32,
    },
    /// `dependenciesKind` and `dependencies` of different lengths.
    #[error("§2.2.8: <{list}> unknown {index} has {kinds} dependenciesKind entries for {dependencies} dependencies")]
    DependenciesKindLengthMismatch {
        /// The list holding the unknown.
        list: StructureList,
        /// The unknown's index.
        index: u32,
        /// Number of `dependencies`.
        dependencies: usize,
        /// Number of `dependenciesKind` entries.
        kinds: usize,
    },
    /// An `<InitialUnknowns>` dependency kind other than dependent or constant.
    #[error(
        "§2.2.8: <InitialUnknowns> unknown {index} has dependenciesKind \"{kind}\"; only dependent and constant are allowed"
    )]
    IllegalInitialUnknownDependencyKind {
        /// The unknown's index.
        index: u32,
        /// The forbidden kind.
        kind: DependencyKind,
    },
    /// `<Outputs>` is not the list of output variables in ScalarVariable order.
    #[error("§2.2.8: <Outputs> lists indices {actual:?}; the output variables are {expected:?}")]
    OutputsMismatch {
        /// The indices of the variables with causality output, ascending.
        expected: Vec<u32>,
        /// The indices `<Outputs>` lists.
        actual: Vec<u32>,
    },
    /// A `<Derivatives>` entry whose variable has no `derivative` attribute.
    #[error("§2.2.8: <Derivatives> lists variable {0}, which has no derivative attribute")]
    NotAStateDerivative(u32),
    /// A variable listed twice in `<Derivatives>`.
    #[error("§2.2.8: <Derivatives> lists variable {0} more than once")]
    DuplicateDerivative(u32),
    /// `<InitialUnknowns>` is not the required list.
    #[error("§2.2.8: <InitialUnknowns> lists indices {actual:?}; the standard requires {expected:?}")]
    InitialUnknownsMismatch {
        /// Outputs and states/derivatives with initial approx or calculated,
        /// and calculated parameters, ascending.
        expected: Vec<u32>,
        /// The indices `<InitialUnknowns>` lists.
        actual: Vec<u32>,
    },
}

/// Checks `model` against the semantic rules of FMI 2.0 and returns every
/// violation found, in document order; an empty list means none.
pub fn validate(model: &FmiModelDescription) -> Vec<Problem> {
    let mut problems = Vec::new();
    check_units(model, &mut problems);
    check_types(model, &mut problems);
    check_log_categories(model, &mut problems);
    check_default_experiment(model, &mut problems);
    check_variables(model, &mut problems);
    check_model_structure(model, &mut problems);
    problems
}

/// Each name that occurs earlier in `names` too, once per repetition.
fn repeated<'a>(names: impl IntoIterator<Item = &'a str>) -> Vec<String> {
    let mut seen = HashSet::new();
    names.into_iter().filter(|name| !seen.insert(*name)).map(str::to_owned).collect()
}

/// §2.2.2: unit names, and display unit names within a unit, are unique.
fn check_units(model: &FmiModelDescription, problems: &mut Vec<Problem>) {
    let units = &model.unit_definitions;
    problems.extend(repeated(units.iter().map(|u| u.name.as_str())).into_iter().map(Problem::DuplicateUnit));
    for unit in units {
        let names = unit.display_units.iter().map(|d| d.name.as_str());
        problems.extend(
            repeated(names)
                .into_iter()
                .map(|display_unit| Problem::DuplicateDisplayUnit { unit: unit.name.clone(), display_unit }),
        );
    }
}

/// Whether `display_unit` is a `<DisplayUnit>` of the unit named `unit`.
fn defines_display_unit(model: &FmiModelDescription, unit: Option<&str>, display_unit: &str) -> bool {
    unit.and_then(|unit| model.unit_definitions.iter().find(|u| u.name == unit))
        .is_some_and(|unit| unit.display_units.iter().any(|d| d.name == display_unit))
}

fn defines_unit(model: &FmiModelDescription, unit: &str) -> bool {
    model.unit_definitions.iter().any(|u| u.name == unit)
}

fn min_exceeds_max<T: PartialOrd>(min: Option<T>, max: Option<T>) -> bool {
    matches!((min, max), (Some(min), Some(max)) if min > max)
}

/// §2.2.3: type names are unique and differ from variable names;
/// enumerations have items with unique names and values; Real types refer
/// to defined units; `min <= max`.
fn check_types(model: &FmiModelDescription, problems: &mut Vec<Problem>) {
    let types = &model.type_definitions;
    problems.extend(repeated(types.iter().map(|t| t.name.as_str())).into_iter().map(Problem::DuplicateType));
    let variable_names: HashSet<&str> = model.model_variables.iter().map(|v| v.name.as_str()).collect();
    for simple_type in types {
        let type_name = &simple_type.name;
        if variable_names.contains(type_name.as_str()) {
            problems.push(Problem::TypeNameIsVariableName(type_name.clone()));
        }
        match &simple_type.kind {
            SimpleTypeKind::Real(real) => {
                if let Some(unit) = &real.unit
                    && !defines_unit(model, unit)
                {
                    problems.push(Problem::UndefinedTypeUnit { type_name: type_name.clone(), unit: unit.clone() });
                }
                if let Some(display_unit) = &real.display_unit
                    && !defines_display_unit(model, real.unit.as_deref(), display_unit)
                {
                    problems.push(Problem::UndefinedTypeDisplayUnit {
                        type_name: type_name.clone(),
                        display_unit: display_unit.clone(),
                    });
                }
                if min_exceeds_max(real.min, real.max) {
                    problems.push(Problem::TypeMinExceedsMax(type_name.clone()));
                }
            }
            SimpleTypeKind::Integer(integer) => {
                if min_exceeds_max(integer.min, integer.max) {
                    problems.push(Problem::TypeMinExceedsMax(type_name.clone()));
                }
            }
            SimpleTypeKind::Enumeration(enumeration) => {
                if enumeration.items.is_empty() {
                    problems.push(Problem::EmptyEnumeration(type_name.clone()));
                }
                let names = enumeration.items.iter().map(|item| item.name.as_str());
                problems.extend(
                    repeated(names)
                        .into_iter()
                        .map(|item| Problem::DuplicateItemName { type_name: type_name.clone(), item }),
                );
                let mut values = HashSet::new();
                for item in &enumeration.items {
                    if !values.insert(item.value) {
                        problems.push(Problem::DuplicateItemValue { type_name: type_name.clone(), value: item.value });
                    }
                }
            }
            SimpleTypeKind::Boolean | SimpleTypeKind::String => {}
        }
    }
}

/// §2.2.4: category names are unique.
fn check_log_categories(model: &FmiModelDescription, problems: &mut Vec<Problem>) {
    let names = model.log_categories.iter().map(|c| c.name.as_str());
    problems.extend(repeated(names).into_iter().map(Problem::DuplicateLogCategory));
}

/// §2.2.5: the default experiment describes a non-empty interval with a
/// positive tolerance and step size.
fn check_default_experiment(model: &FmiModelDescription, problems: &mut Vec<Problem>) {
    let Some(experiment) = &model.default_experiment else {
        return;
    };
    if let (Some(start_time), Some(stop_time)) = (experiment.start_time, experiment.stop_time)
        && stop_time <= start_time
    {
        problems.push(Problem::StopTimeNotAfterStartTime { start_time, stop_time });
    }
    for (attribute, value) in [("tolerance", experiment.tolerance), ("stepSize", experiment.step_size)] {
        // NaN compares as `None`, so it is reported too.
        if let Some(value) = value
            && value.partial_cmp(&0.0) != Some(Ordering::Greater)
        {
            problems.push(Problem::NonPositiveExperimentAttribute { attribute, value });
        }
    }
}

/// The `initial` values allowed for a causality/variability pair: the cases
/// (A) to (E) of the §2.2.7 table of `initial` values.
#[derive(Debug, Clone, Copy)]
enum InitialRule {
    /// (A): exact only.
    ExactOnly,
    /// (B): approx or calculated; calculated when absent.
    ApproxOrCalculated,
    /// (C): exact, approx or calculated; calculated when absent.
    Any,
    /// (D) inputs, (E) the independent variable: `initial` must be absent.
    Absent,
}

impl InitialRule {
    /// The §2.2.7 table of causality × variability: `None` for the
    /// combinations it forbids, e.g. constant input or discrete parameter.
    fn of(causality: Causality, variability: Variability) -> Option<Self> {
        use Causality as C;
        use Variability as V;
        match (causality, variability) {
            (C::Parameter, V::Fixed | V::Tunable) => Some(Self::ExactOnly),
            (C::CalculatedParameter | C::Local, V::Fixed | V::Tunable) => Some(Self::ApproxOrCalculated),
            (C::Output | C::Local, V::Constant) => Some(Self::ExactOnly),
            (C::Output | C::Local, V::Discrete | V::Continuous) => Some(Self::Any),
            (C::Input, V::Discrete | V::Continuous) | (C::Independent, V::Continuous) => Some(Self::Absent),
            _ => None,
        }
    }

    fn allows(self, initial: Initial) -> bool {
        match self {
            Self::ExactOnly => initial == Initial::Exact,
            Self::ApproxOrCalculated => initial != Initial::Exact,
            Self::Any => true,
            Self::Absent => false,
        }
    }

    fn default_initial(self) -> Option<Initial> {
        match self {
            Self::ExactOnly => Some(Initial::Exact),
            Self::ApproxOrCalculated | Self::Any => Some(Initial::Calculated),
            Self::Absent => None,
        }
    }
}

/// `initial` as given, or the default of §2.2.7 when absent; `None` for
/// inputs, the independent variable and forbidden combinations.
fn effective_initial(variable: &ScalarVariable) -> Option<Initial> {
    let rule = InitialRule::of(variable.causality, variable.variability)?;
    match variable.initial {
        Some(initial) if rule.allows(initial) => Some(initial),
        Some(_) => None,
        None => rule.default_initial(),
    }
}

fn base_type(kind: &VariableKind) -> BaseType {
    match kind {
        VariableKind::Real(_) => BaseType::Real,
        VariableKind::Integer(_) | VariableKind::Enumeration(_) => BaseType::Integer,
        VariableKind::Boolean(_) => BaseType::Boolean,
        VariableKind::String(_) => BaseType::String,
    }
}

fn has_start(kind: &VariableKind) -> bool {
    match kind {
        VariableKind::Real(v) => v.start.is_some(),
        VariableKind::Integer(v) => v.start.is_some(),
        VariableKind::Boolean(v) => v.start.is_some(),
        VariableKind::String(v) => v.start.is_some(),
        VariableKind::Enumeration(v) => v.start.is_some(),
    }
}

fn declared_type(kind: &VariableKind) -> Option<&str> {
    match kind {
        VariableKind::Real(v) => v.declared_type.as_deref(),
        VariableKind::Integer(v) => v.declared_type.as_deref(),
        VariableKind::Boolean(v) => v.declared_type.as_deref(),
        VariableKind::String(v) => v.declared_type.as_deref(),
        VariableKind::Enumeration(v) => Some(&v.declared_type),
    }
}

fn same_base_type(kind: &VariableKind, simple_type: &SimpleTypeKind) -> bool {
    matches!(
        (kind, simple_type),
        (VariableKind::Real(_), SimpleTypeKind::Real(_))
            | (VariableKind::Integer(_), SimpleTypeKind::Integer(_))
            | (VariableKind::Boolean(_), SimpleTypeKind::Boolean)
            | (VariableKind::String(_), SimpleTypeKind::String)
            | (VariableKind::Enumeration(_), SimpleTypeKind::Enumeration(_))
    )
}

/// Whether `start` lies outside the bounds that are given.
fn out_of_range<T: PartialOrd>(start: Option<T>, min: Option<T>, max: Option<T>) -> bool {
    let Some(start) = start else { return false };
    min.is_some_and(|min| start < min) || max.is_some_and(|max| start > max)
}

/// §2.2.7 rules on each `<ScalarVariable>` and across all of them.
fn check_variables(model: &FmiModelDescription, problems: &mut Vec<Problem>) {
    let variables = &model.model_variables;
    if variables.is_empty() {
        problems.push(Problem::NoModelVariables);
    }
    problems
        .extend(repeated(variables.iter().map(|v| v.name.as_str())).into_iter().map(Problem::DuplicateVariableName));

    let mut value_references: HashMap<(BaseType, u32), &str> = HashMap::new();
    let mut independent: Option<&str> = None;
    let types: HashMap<&str, &SimpleType> = model.type_definitions.iter().map(|t| (t.name.as_str(), t)).collect();

    for variable in variables {
        let name = &variable.name;
        let base_type = base_type(&variable.kind);
        match value_references.entry((base_type, variable.value_reference)) {
            Entry::Occupied(first) => problems.push(Problem::SharedValueReference {
                base_type,
                value_reference: variable.value_reference,
                first: (*first.get()).to_owned(),
                second: name.clone(),
            }),
            Entry::Vacant(slot) => {
                slot.insert(name);
            }
        }

        if variable.causality == Causality::Independent {
            match independent {
                Some(first) => {
                    problems.push(Problem::MultipleIndependent { first: first.to_owned(), second: name.clone() })
                }
                None => independent = Some(name),
            }
        }

        if variable.variability == Variability::Continuous && !matches!(variable.kind, VariableKind::Real(_)) {
            problems.push(Problem::ContinuousNotReal(name.clone()));
        }

        check_initial_and_start(variable, problems);

        // The attribute belongs to model exchange (§2.2.7).
        if model.model_exchange.is_none() && variable.can_handle_multiple_set_per_time_instant.is_some() {
            problems.push(Problem::MultipleSetInCoSimulation(name.clone()));
        }

        let declared = match declared_type(&variable.kind) {
            None => None,
            Some(type_name) => match types.get(type_name) {
                None => {
                    problems.push(Problem::UndefinedDeclaredType {
                        variable: name.clone(),
                        declared_type: type_name.to_owned(),
                    });
                    None
                }
                Some(simple_type) if !same_base_type(&variable.kind, &simple_type.kind) => {
                    problems.push(Problem::DeclaredTypeMismatch {
                        variable: name.clone(),
                        declared_type: type_name.to_owned(),
                    });
                    None
                }
                Some(simple_type) => Some(&simple_type.kind),
            },
        };

        check_attributes(model, variable, declared, problems);
    }
}

/// §2.2.7: legal causality/variability/initial combination, and `start`
/// present exactly when the effective `initial` or the causality demand it.
fn check_initial_and_start(variable: &ScalarVariable, problems: &mut Vec<Problem>) {
    let name = &variable.name;
    let (causality, variability) = (variable.causality, variable.variability);
    let Some(rule) = InitialRule::of(causality, variability) else {
        problems.push(Problem::IllegalCausalityVariability { variable: name.clone(), causality, variability });
        return;
    };
    if let Some(initial) = variable.initial
        && !rule.allows(initial)
    {
        problems.push(Problem::IllegalInitial { variable: name.clone(), causality, variability, initial });
        return;
    }
    let has_start = has_start(&variable.kind);
    let initial = effective_initial(variable);
    let needs_start = matches!(initial, Some(Initial::Exact | Initial::Approx)) || causality == Causality::Input;
    let forbids_start = initial == Some(Initial::Calculated) || causality == Causality::Independent;
    if needs_start && !has_start {
        problems.push(Problem::MissingStart(name.clone()));
    }
    if forbids_start && has_start {
        problems.push(Problem::UnexpectedStart(name.clone()));
    }
}

/// §2.2.7: units, display units, bounds and `derivative` of one variable.
/// `declared` is its `<SimpleType>`, when that is defined and matching;
/// attributes the variable leaves out are inherited from it.
fn check_attributes(
    model: &FmiModelDescription,
    variable: &ScalarVariable,
    declared: Option<&SimpleTypeKind>,
    problems: &mut Vec<Problem>,
) {
    let name = &variable.name;
    let (bounds_inverted, start_outside) = match (&variable.kind, declared) {
        (VariableKind::Real(real), declared) => {
            let declared = match declared {
                Some(SimpleTypeKind::Real(declared)) => Some(declared),
                _ => None,
            };
            if let Some(unit) = &real.unit
                && !defines_unit(model, unit)
            {
                problems.push(Problem::UndefinedUnit { variable: name.clone(), unit: unit.clone() });
            }
            if let Some(display_unit) = &real.display_unit {
                let unit = real.unit.as_deref().or(declared.and_then(|d| d.unit.as_deref()));
                if !defines_display_unit(model, unit, display_unit) {
                    problems.push(Problem::UndefinedDisplayUnit {
                        variable: name.clone(),
                        display_unit: display_unit.clone(),
                    });
                }
            }
            if let Some(derivative) = real.derivative
                && !variable_at(&model.model_variables, derivative)
                    .is_some_and(|t| matches!(t.kind, VariableKind::Real(_)))
            {
                problems.push(Problem::InvalidDerivative { variable: name.clone(), derivative });
            }
            let min = real.min.or(declared.and_then(|d| d.min));
            let max = real.max.or(declared.and_then(|d| d.max));
            (min_exceeds_max(min, max), out_of_range(real.start, min, max))
        }
        (VariableKind::Integer(integer), declared) => {
            let declared = match declared {
                Some(SimpleTypeKind::Integer(declared)) => Some(declared),
                _ => None,
            };
            let min = integer.min.or(declared.and_then(|d| d.min));
            let max = integer.max.or(declared.and_then(|d| d.max));
            (min_exceeds_max(min, max), out_of_range(integer.start, min, max))
        }
        (VariableKind::Enumeration(enumeration), _) => (
            min_exceeds_max(enumeration.min, enumeration.max),
            out_of_range(enumeration.start, enumeration.min, enumeration.max),
        ),
        (VariableKind::Boolean(_) | VariableKind::String(_), _) => (false, false),
    };
    if bounds_inverted {
        problems.push(Problem::MinExceedsMax(name.clone()));
    } else if start_outside {
        problems.push(Problem::StartOutOfRange(name.clone()));
    }
}

/// The variable with 1-based ScalarVariable index `index`.
fn variable_at(variables: &[ScalarVariable], index: u32) -> Option<&ScalarVariable> {
    variables.get(usize::try_from(index).ok()?.checked_sub(1)?)
}

/// 1-based ScalarVariable indices of `variables` that satisfy `keep`.
fn indices_where(variables: &[ScalarVariable], keep: impl Fn(&ScalarVariable) -> bool) -> Vec<u32> {
    (1u32..).zip(variables).filter(|(_, v)| keep(v)).map(|(i, _)| i).collect()
}

/// §2.2.8 rules on `<ModelStructure>`.
fn check_model_structure(model: &FmiModelDescription, problems: &mut Vec<Problem>) {
    let variables = &model.model_variables;
    let structure = &model.model_structure;

    for (list, unknowns) in [
        (StructureList::Outputs, &structure.outputs),
        (StructureList::Derivatives, &structure.derivatives),
        (StructureList::InitialUnknowns, &structure.initial_unknowns),
    ] {
        for unknown in unknowns {
            if variable_at(variables, unknown.index).is_none() {
                problems.push(Problem::IndexOutOfRange { list, index: unknown.index });
            }
            check_dependencies(list, unknown, variables, problems);
        }
    }

    // Outputs: exactly the variables with causality output, in
    // ScalarVariable order.
    let expected_outputs = indices_where(variables, |v| v.causality == Causality::Output);
    let outputs: Vec<u32> = structure.outputs.iter().map(|u| u.index).collect();
    if outputs != expected_outputs {
        problems.push(Problem::OutputsMismatch { expected: expected_outputs, actual: outputs });
    }

    // Derivatives: each entry is a state derivative, i.e. has `derivative`.
    let mut listed = HashSet::new();
    let mut states_and_derivatives = HashSet::new();
    for unknown in &structure.derivatives {
        if !listed.insert(unknown.index) {
            problems.push(Problem::DuplicateDerivative(unknown.index));
        }
        match variable_at(variables, unknown.index).map(|v| &v.kind) {
            Some(VariableKind::Real(RealVariable { derivative: Some(state), .. })) => {
                states_and_derivatives.extend([unknown.index, *state]);
            }
            Some(_) => problems.push(Problem::NotAStateDerivative(unknown.index)),
            None => {} // reported as IndexOutOfRange
        }
    }

    // InitialUnknowns: outputs with initial approx/calculated, calculated
    // parameters, and states and state derivatives with initial
    // approx/calculated; no duplicates, in ScalarVariable order.
    let expected_initial_unknowns = (1u32..)
        .zip(variables)
        .filter(|(index, variable)| {
            let computed = matches!(effective_initial(variable), Some(Initial::Approx | Initial::Calculated));
            (variable.causality == Causality::Output && computed)
                || variable.causality == Causality::CalculatedParameter
                || (states_and_derivatives.contains(index) && computed)
        })
        .map(|(index, _)| index)
        .collect::<Vec<_>>();
    let initial_unknowns: Vec<u32> = structure.initial_unknowns.iter().map(|u| u.index).collect();
    if initial_unknowns != expected_initial_unknowns {
        problems
            .push(Problem::InitialUnknownsMismatch { expected: expected_initial_unknowns, actual: initial_unknowns });
    }
}

/// §2.2.8: `dependencies` are valid indices in ascending order,
/// `dependenciesKind` has one entry per dependency, and initial unknowns
/// only use the kinds dependent and constant.
fn check_dependencies(
    list: StructureList,
    unknown: &Unknown,
    variables: &[ScalarVariable],
    problems: &mut Vec<Problem>,
) {
    let index = unknown.index;
    match (&unknown.dependencies, &unknown.dependencies_kind) {
        (None, Some(_)) => problems.push(Problem::DependenciesKindWithoutDependencies { list, index }),
        (Some(dependencies), Some(kinds)) if dependencies.len() != kinds.len() => {
            problems.push(Problem::DependenciesKindLengthMismatch {
                list,
                index,
                dependencies: dependencies.len(),
                kinds: kinds.len(),
            });
        }
        _ => {}
    }
    if let Some(dependencies) = &unknown.dependencies {
        for &dependency in dependencies {
            if variable_at(variables, dependency).is_none() {
                problems.push(Problem::DependencyOutOfRange { list, index, dependency });
            }
        }
        if dependencies.windows(2).any(|pair| pair[0] >= pair[1]) {
            problems.push(Problem::DependenciesNotAscending { list, index });
        }
    }
    if list == StructureList::InitialUnknowns {
        for &kind in unknown.dependencies_kind.iter().flatten() {
            if !matches!(kind, DependencyKind::Dependent | DependencyKind::Constant) {
                problems.push(Problem::IllegalInitialUnknownDependencyKind { index, kind });
            }
        }
    }
}
