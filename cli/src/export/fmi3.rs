//! The FMI 3.0 modelDescription of a nudyn FMU, written from the same
//! contract as the FMI 2.0 one: the contract's FMI 3.0 table
//! ([`Fmi3Variables`]) groups the scalar variables into arrays (or, with
//! `--fmi3-scalars`, keeps each a scalar), and each array takes its kind
//! and start values from its elements (which share a kind by construction)
//! and the descriptions of its elements.

use modeldescription::fmi3 as md3;
use nudyn_contract::fmi3::{Fmi3Variable, Fmi3Variables, TIME_NAME, TIME_VR, ValueType};
use nudyn_contract::log::LogCategory;
use nudyn_contract::variable::{Causality, Kind, Range, Variability};
use nudyn_contract::{DEFAULT_STEP_SIZE, DEFAULT_STOP_TIME};

use super::Header;

/// One FMI 2.0 Real variable as the FMI 3.0 writer needs it.
pub struct RealScalar {
    /// Its kind.
    pub kind: Kind,
    /// Its start value, if it has one.
    pub start: Option<f64>,
    /// Its description.
    pub description: String,
}

/// The enumeration and Boolean variables of an FMU (the plant's `method`
/// and `energy_projection`), written by the caller that knows them.
pub struct Others {
    /// `<EnumerationType>`s.
    pub enumeration_types: Vec<md3::EnumerationType>,
    /// The variables, for the table's enumeration and Boolean value references.
    pub variables: Vec<md3::Variable>,
    /// Whether parameters change what the FMU computes (the controller's
    /// gains), so that in Initialization Mode, where they are knowns, every
    /// calculated unknown depends on all knowns; else (the plant's, which
    /// set how it integrates) on the same knowns as after it.
    pub parameters_change_values: bool,
}

/// The description of `time`, the independent variable.
pub const TIME_DESCRIPTION: &str = "simulation time (s)";

/// FMI's causality and initial of a variable of `kind` (the same words in FMI 2.0 and 3.0).
pub fn causality(kind: Kind) -> (&'static str, Option<&'static str>) {
    match kind.causality {
        Causality::Parameter => ("parameter", Some("exact")),
        Causality::Input => ("input", None),
        Causality::Output if kind.exact_start => ("output", Some("exact")),
        Causality::Output => ("output", Some("calculated")),
        Causality::Local => ("local", Some("calculated")),
    }
}

/// FMI's variability of a variable of `kind`.
pub fn variability(kind: Kind) -> &'static str {
    match kind.variability {
        Variability::Fixed => "fixed",
        Variability::Tunable => "tunable",
        Variability::Continuous => "continuous",
    }
}

/// The description of `variable` from its `elements`': "[1] …; [2] …" for an array.
pub fn description(variable: &Fmi3Variable, elements: &[RealScalar]) -> String {
    if variable.array {
        let each: Vec<String> =
            elements.iter().enumerate().map(|(k, e)| format!("[{}] {}", k + 1, e.description)).collect();
        each.join("; ")
    } else {
        elements[0].description.clone()
    }
}

/// The `<Float64>` of a variable of the table, from its elements.
fn float64(variable: &Fmi3Variable, real: &impl Fn(u32) -> RealScalar) -> md3::Float64 {
    let elements: Vec<RealScalar> = variable.elements().map(real).collect();
    let kind = elements[0].kind;
    let (causality, initial) = causality(kind);
    let start: Option<Vec<f64>> = elements.iter().map(|e| e.start).collect();
    let description = description(variable, &elements);
    md3::Float64 {
        name: variable.name.clone(),
        value_reference: variable.value_reference,
        description: Some(description),
        causality: causality.into(),
        variability: variability(kind).into(),
        initial: initial.map(Into::into),
        unit: None,
        min: (kind.range == Range::NonNegative).then_some(0.0),
        start,
        derivative: variable.derivative_of,
        dimensions: if variable.array { vec![md3::Dimension { start: variable.len as u64 }] } else { Vec::new() },
    }
}

/// The FMI 3.0 modelDescription of an FMU whose variables are `table`,
/// whose FMI 2.0 Real `vr` is `real(vr)` and depends on the knowns
/// `dependencies(vr)` (the contract's), with `others` beside them.
pub fn model_description(
    header: Header,
    table: &Fmi3Variables,
    real: impl Fn(u32) -> RealScalar,
    dependencies: impl Fn(u32) -> Option<Vec<u32>>,
    others: Others,
) -> md3::Fmi3ModelDescription {
    let time = md3::Variable::Float64(md3::Float64 {
        name: TIME_NAME.into(),
        value_reference: TIME_VR,
        description: Some(TIME_DESCRIPTION.into()),
        causality: "independent".into(),
        variability: "continuous".into(),
        initial: None,
        unit: None,
        min: None,
        start: None,
        derivative: None,
        dimensions: Vec::new(),
    });
    let mut variables = vec![time];
    variables.extend(others.variables);
    let floats: Vec<md3::Float64> =
        table.iter().filter(|v| v.value_type == ValueType::Float64).map(|v| float64(v, &real)).collect();

    let unknown = |float: &md3::Float64| md3::Unknown {
        value_reference: float.value_reference,
        dependencies: table.known_variables(float.value_reference, &dependencies).and_then(super::listed),
    };
    let mut structure = md3::ModelStructure::default();
    let event_indicators =
        table.iter().filter(|v| v.value_type == ValueType::Float64 && real(v.first).kind.event_indicator);
    structure.event_indicators = event_indicators
        .map(|v| md3::Unknown {
            value_reference: v.value_reference,
            dependencies: table.known_variables(v.value_reference, &dependencies).and_then(super::listed),
        })
        .collect();
    for float in &floats {
        if float.causality == "output" {
            structure.outputs.push(unknown(float));
        } else if float.derivative.is_some() {
            structure.continuous_state_derivatives.push(unknown(float));
        } else {
            continue;
        }
        if float.initial.as_deref() == Some("calculated") {
            let initial = match others.parameters_change_values {
                true => md3::Unknown { value_reference: float.value_reference, dependencies: None },
                false => unknown(float),
            };
            structure.initial_unknowns.push(initial);
        }
    }
    variables.extend(floats.into_iter().map(md3::Variable::Float64));

    let capabilities = header.capabilities;
    let model_exchange = capabilities.model_exchange.then(|| md3::ModelExchange {
        model_identifier: header.model_identifier.clone(),
        // No step events.
        needs_completed_integrator_step: false,
        can_get_and_set_fmu_state: capabilities.can_get_and_set_fmu_state,
        can_serialize_fmu_state: capabilities.can_serialize_fmu_state,
        provides_directional_derivatives: capabilities.provides_directional_derivative,
        provides_adjoint_derivatives: capabilities.provides_directional_derivative,
        provides_per_element_dependencies: true,
    });
    let co_simulation = md3::CoSimulation {
        model_identifier: header.model_identifier.clone(),
        can_get_and_set_fmu_state: capabilities.can_get_and_set_fmu_state,
        can_serialize_fmu_state: capabilities.can_serialize_fmu_state,
        provides_directional_derivatives: capabilities.provides_directional_derivative,
        provides_adjoint_derivatives: capabilities.provides_directional_derivative,
        provides_per_element_dependencies: true,
        can_handle_variable_communication_step_size: capabilities.can_handle_variable_communication_step_size,
        max_output_derivative_order: capabilities.max_output_derivative_order,
        provides_intermediate_update: false,
        might_return_early_from_do_step: false,
        has_event_mode: false,
    };
    md3::Fmi3ModelDescription {
        fmi_version: "3.0".into(),
        model_name: header.model_name,
        instantiation_token: header.guid,
        description: Some(header.description),
        generation_tool: Some(format!("nudyn {}", env!("CARGO_PKG_VERSION"))),
        generation_date_and_time: Some(header.generated),
        variable_naming_convention: Some("structured".into()),
        model_exchange,
        co_simulation: Some(co_simulation),
        type_definitions: (!others.enumeration_types.is_empty())
            .then_some(md3::TypeDefinitions { enumeration_types: others.enumeration_types }),
        log_categories: LogCategory::ALL
            .iter()
            .map(|c| modeldescription::Category { name: c.name().into(), description: Some(c.description().into()) })
            .collect(),
        default_experiment: Some(modeldescription::DefaultExperiment {
            start_time: Some(0.0),
            stop_time: Some(DEFAULT_STOP_TIME),
            // As for FMI 2.0: the `tolerance` parameter stays in charge unless the importer says otherwise.
            tolerance: None,
            step_size: Some(DEFAULT_STEP_SIZE),
        }),
        model_variables: md3::ModelVariables { variables },
        model_structure: structure,
    }
}
