//! `validate` accepts a correct model and reports each FMI 2.0 rule
//! violation, one case per rule, without follow-on reports.

use crate::common;

use crate::common::index::*;
use modeldescription::*;

/// The problems `validate` finds after `change` is applied to the valid
/// model of `common::arm`.
fn problems_after(change: impl FnOnce(&mut FmiModelDescription)) -> Vec<Problem> {
    let mut model = common::arm();
    change(&mut model);
    validate(&model)
}

fn variable<'a>(model: &'a mut FmiModelDescription, name: &str) -> &'a mut ScalarVariable {
    model.model_variables.iter_mut().find(|v| v.name == name).unwrap()
}

fn real<'a>(model: &'a mut FmiModelDescription, name: &str) -> &'a mut RealVariable {
    match &mut variable(model, name).kind {
        VariableKind::Real(real) => real,
        other => panic!("{name} is not Real: {other:?}"),
    }
}

fn integer<'a>(model: &'a mut FmiModelDescription, name: &str) -> &'a mut IntegerVariable {
    match &mut variable(model, name).kind {
        VariableKind::Integer(integer) => integer,
        other => panic!("{name} is not Integer: {other:?}"),
    }
}

fn simple_type<'a>(model: &'a mut FmiModelDescription, name: &str) -> &'a mut SimpleTypeKind {
    &mut model.type_definitions.iter_mut().find(|t| t.name == name).unwrap().kind
}

fn enumeration_items(model: &mut FmiModelDescription) -> &mut Vec<Item> {
    match simple_type(model, "IntegratorMethod") {
        SimpleTypeKind::Enumeration(enumeration) => &mut enumeration.items,
        other => panic!("not an enumeration: {other:?}"),
    }
}

fn mass_type(model: &mut FmiModelDescription) -> &mut RealType {
    match simple_type(model, "Mass") {
        SimpleTypeKind::Real(real) => real,
        other => panic!("not Real: {other:?}"),
    }
}

fn unknown(list: &mut [Unknown], index: u32) -> &mut Unknown {
    list.iter_mut().find(|u| u.index == index).unwrap()
}

fn name(text: &str) -> String {
    text.to_owned()
}

#[test]
fn correct_model_has_no_problems() {
    assert_eq!(validate(&common::arm()), vec![]);
}

#[test]
fn correct_model_read_back_has_no_problems() {
    let xml = to_xml(&common::arm()).unwrap();
    assert_eq!(validate(&from_xml(&xml).unwrap()), vec![]);
}

#[test]
fn problem_messages_cite_the_standard() {
    let problems = problems_after(|m| {
        m.model_variables[1].name = name("time");
        m.unit_definitions.push(m.unit_definitions[0].clone());
        m.model_structure.outputs.clear();
    });
    assert_eq!(problems.len(), 3, "{problems:?}");
    for problem in problems {
        assert!(problem.to_string().starts_with("§2.2."), "{problem}");
    }
}

// §2.2.7 / schema: at least one variable.
#[test]
fn no_variables() {
    let problems = problems_after(|m| {
        m.model_variables.clear();
        m.model_structure = ModelStructure::default();
    });
    assert_eq!(problems, vec![Problem::NoModelVariables]);
}

// §2.2.2
#[test]
fn duplicate_unit() {
    let problems = problems_after(|m| m.unit_definitions.push(m.unit_definitions[0].clone()));
    assert_eq!(problems, vec![Problem::DuplicateUnit(name("rad"))]);
}

#[test]
fn duplicate_display_unit() {
    let problems = problems_after(|m| {
        let rad = &mut m.unit_definitions[0];
        rad.display_units.push(rad.display_units[0].clone());
    });
    assert_eq!(problems, vec![Problem::DuplicateDisplayUnit { unit: name("rad"), display_unit: name("deg") }]);
}

// §2.2.3
#[test]
fn duplicate_type() {
    let problems = problems_after(|m| m.type_definitions.push(m.type_definitions[1].clone()));
    assert_eq!(problems, vec![Problem::DuplicateType(name("Mass"))]);
}

#[test]
fn type_named_like_a_variable() {
    let problems = problems_after(|m| {
        m.type_definitions[1].name = name("m");
        real(m, "m").declared_type = Some(name("m"));
    });
    assert_eq!(problems, vec![Problem::TypeNameIsVariableName(name("m"))]);
}

#[test]
fn enumeration_without_items() {
    let problems = problems_after(|m| enumeration_items(m).clear());
    assert_eq!(problems, vec![Problem::EmptyEnumeration(name("IntegratorMethod"))]);
}

#[test]
fn duplicate_item_name() {
    let problems = problems_after(|m| enumeration_items(m)[1].name = name("euler"));
    assert_eq!(problems, vec![Problem::DuplicateItemName { type_name: name("IntegratorMethod"), item: name("euler") }]);
}

#[test]
fn duplicate_item_value() {
    let problems = problems_after(|m| enumeration_items(m)[1].value = 1);
    assert_eq!(problems, vec![Problem::DuplicateItemValue { type_name: name("IntegratorMethod"), value: 1 }]);
}

#[test]
fn type_with_undefined_unit() {
    let problems = problems_after(|m| mass_type(m).unit = Some(name("g")));
    assert_eq!(problems, vec![Problem::UndefinedTypeUnit { type_name: name("Mass"), unit: name("g") }]);
}

#[test]
fn type_with_undefined_display_unit() {
    let problems = problems_after(|m| mass_type(m).display_unit = Some(name("lb")));
    assert_eq!(problems, vec![Problem::UndefinedTypeDisplayUnit { type_name: name("Mass"), display_unit: name("lb") }]);
}

#[test]
fn type_with_min_above_max() {
    let problems = problems_after(|m| {
        m.type_definitions.push(SimpleType {
            name: name("Count"),
            description: None,
            kind: SimpleTypeKind::Integer(IntegerType { quantity: None, min: Some(5), max: Some(1) }),
        })
    });
    assert_eq!(problems, vec![Problem::TypeMinExceedsMax(name("Count"))]);
}

// §2.2.4
#[test]
fn duplicate_log_category() {
    let problems = problems_after(|m| m.log_categories[1].name = name("logStatusError"));
    assert_eq!(problems, vec![Problem::DuplicateLogCategory(name("logStatusError"))]);
}

// §2.2.5
#[test]
fn stop_time_not_after_start_time() {
    let problems = problems_after(|m| m.default_experiment.as_mut().unwrap().stop_time = Some(0.0));
    assert_eq!(problems, vec![Problem::StopTimeNotAfterStartTime { start_time: 0.0, stop_time: 0.0 }]);
}

#[test]
fn non_positive_step_size_and_tolerance() {
    let problems = problems_after(|m| {
        let experiment = m.default_experiment.as_mut().unwrap();
        experiment.tolerance = Some(-1e-6);
        experiment.step_size = Some(0.0);
    });
    assert_eq!(
        problems,
        vec![
            Problem::NonPositiveExperimentAttribute { attribute: "tolerance", value: -1e-6 },
            Problem::NonPositiveExperimentAttribute { attribute: "stepSize", value: 0.0 },
        ]
    );
}

// §2.2.7: names and value references.
#[test]
fn duplicate_variable_name() {
    let problems = problems_after(|m| variable(m, "steps").name = name("q"));
    assert_eq!(problems, vec![Problem::DuplicateVariableName(name("q"))]);
}

#[test]
fn shared_value_reference_within_a_base_type() {
    // An Enumeration is accessed with fmi2GetInteger, so it shares the
    // Integer references; the arm model already reuses 0 across base types.
    let problems = problems_after(|m| variable(m, "steps").value_reference = 0);
    assert_eq!(
        problems,
        vec![Problem::SharedValueReference {
            base_type: BaseType::Integer,
            value_reference: 0,
            first: name("integrator"),
            second: name("steps"),
        }]
    );
}

// §2.2.7: causality × variability table.
#[test]
fn constant_input() {
    let problems = problems_after(|m| variable(m, "tau").variability = Variability::Constant);
    assert_eq!(
        problems,
        vec![Problem::IllegalCausalityVariability {
            variable: name("tau"),
            causality: Causality::Input,
            variability: Variability::Constant,
        }]
    );
}

#[test]
fn continuous_parameter() {
    let problems = problems_after(|m| variable(m, "m").variability = Variability::Continuous);
    assert_eq!(
        problems,
        vec![Problem::IllegalCausalityVariability {
            variable: name("m"),
            causality: Causality::Parameter,
            variability: Variability::Continuous,
        }]
    );
}

// §2.2.7: initial table.
#[test]
fn input_with_initial() {
    let problems = problems_after(|m| variable(m, "tau").initial = Some(Initial::Exact));
    assert_eq!(
        problems,
        vec![Problem::IllegalInitial {
            variable: name("tau"),
            causality: Causality::Input,
            variability: Variability::Continuous,
            initial: Initial::Exact,
        }]
    );
}

#[test]
fn parameter_with_initial_approx() {
    let problems = problems_after(|m| variable(m, "m").initial = Some(Initial::Approx));
    assert_eq!(
        problems,
        vec![Problem::IllegalInitial {
            variable: name("m"),
            causality: Causality::Parameter,
            variability: Variability::Fixed,
            initial: Initial::Approx,
        }]
    );
}

// §2.2.7: start.
#[test]
fn input_without_start() {
    let problems = problems_after(|m| real(m, "tau").start = None);
    assert_eq!(problems, vec![Problem::MissingStart(name("tau"))]);
}

#[test]
fn exact_continuous_output_without_start() {
    let problems = problems_after(|m| real(m, "q").start = None);
    assert_eq!(problems, vec![Problem::MissingStart(name("q"))]);
}

#[test]
fn parameter_without_start() {
    let problems = problems_after(|m| integer(m, "steps").start = None);
    assert_eq!(problems, vec![Problem::MissingStart(name("steps"))]);
}

#[test]
fn calculated_variable_with_start() {
    let problems = problems_after(|m| real(m, "inertia").start = Some(0.5));
    assert_eq!(problems, vec![Problem::UnexpectedStart(name("inertia"))]);
}

#[test]
fn independent_variable_with_start() {
    let problems = problems_after(|m| real(m, "time").start = Some(0.0));
    assert_eq!(problems, vec![Problem::UnexpectedStart(name("time"))]);
}

// §2.2.7: variability, independent variable, Model Exchange attributes.
#[test]
fn continuous_boolean() {
    let problems = problems_after(|m| variable(m, "saturated").variability = Variability::Continuous);
    assert_eq!(problems, vec![Problem::ContinuousNotReal(name("saturated"))]);
}

#[test]
fn two_independent_variables() {
    let problems = problems_after(|m| {
        let mut second_time = m.model_variables[0].clone();
        second_time.name = name("t2");
        second_time.value_reference = 100;
        m.model_variables.push(second_time);
    });
    assert_eq!(problems, vec![Problem::MultipleIndependent { first: name("time"), second: name("t2") }]);
}

#[test]
fn multiple_set_per_time_instant_in_co_simulation() {
    let problems = problems_after(|m| variable(m, "tau").can_handle_multiple_set_per_time_instant = Some(false));
    assert_eq!(problems, vec![Problem::MultipleSetInCoSimulation(name("tau"))]);
}

// §2.2.7: declared types and units.
#[test]
fn undefined_declared_type() {
    let problems = problems_after(|m| real(m, "m").declared_type = Some(name("Weight")));
    assert_eq!(problems, vec![Problem::UndefinedDeclaredType { variable: name("m"), declared_type: name("Weight") }]);
}

#[test]
fn declared_type_of_another_base_type() {
    let problems = problems_after(|m| integer(m, "steps").declared_type = Some(name("Mass")));
    assert_eq!(problems, vec![Problem::DeclaredTypeMismatch { variable: name("steps"), declared_type: name("Mass") }]);
}

#[test]
fn undefined_unit() {
    let problems = problems_after(|m| real(m, "q").unit = Some(name("deg")));
    assert_eq!(problems, vec![Problem::UndefinedUnit { variable: name("q"), unit: name("deg") }]);
}

#[test]
fn undefined_display_unit() {
    let problems = problems_after(|m| real(m, "q").display_unit = Some(name("grad")));
    assert_eq!(problems, vec![Problem::UndefinedDisplayUnit { variable: name("q"), display_unit: name("grad") }]);
}

#[test]
fn display_unit_of_the_declared_types_unit() {
    // m has no unit of its own: its display unit must belong to Mass's unit.
    let problems = problems_after(|m| real(m, "m").display_unit = Some(name("deg")));
    assert_eq!(problems, vec![Problem::UndefinedDisplayUnit { variable: name("m"), display_unit: name("deg") }]);
}

// §2.2.7: bounds.
#[test]
fn min_above_max() {
    let problems = problems_after(|m| {
        let steps = integer(m, "steps");
        steps.min = Some(3);
        steps.max = Some(2);
    });
    assert_eq!(problems, vec![Problem::MinExceedsMax(name("steps"))]);
}

#[test]
fn start_below_min_of_declared_type() {
    let problems = problems_after(|m| real(m, "m").start = Some(-1.0));
    assert_eq!(problems, vec![Problem::StartOutOfRange(name("m"))]);
}

// §2.2.7: derivative.
#[test]
fn derivative_of_a_non_real_variable() {
    let problems = problems_after(|m| real(m, "der(q)").derivative = Some(8));
    assert_eq!(problems, vec![Problem::InvalidDerivative { variable: name("der(q)"), derivative: 8 }]);
}

#[test]
fn derivative_out_of_range() {
    let problems = problems_after(|m| real(m, "der(q)").derivative = Some(0));
    assert_eq!(problems, vec![Problem::InvalidDerivative { variable: name("der(q)"), derivative: 0 }]);
}

// §2.2.8: indices and dependencies.
#[test]
fn unknown_index_out_of_range() {
    let problems = problems_after(|m| m.model_structure.derivatives.push(Unknown::new(0)));
    assert_eq!(problems, vec![Problem::IndexOutOfRange { list: StructureList::Derivatives, index: 0 }]);
}

#[test]
fn dependency_out_of_range() {
    let problems =
        problems_after(|m| unknown(&mut m.model_structure.derivatives, DER_DQ).dependencies = Some(vec![TAU, Q, 13]));
    assert_eq!(
        problems,
        vec![Problem::DependencyOutOfRange { list: StructureList::Derivatives, index: DER_DQ, dependency: 13 }]
    );
}

#[test]
fn dependencies_not_ascending() {
    let problems =
        problems_after(|m| unknown(&mut m.model_structure.derivatives, DER_DQ).dependencies = Some(vec![Q, TAU, DQ]));
    assert_eq!(problems, vec![Problem::DependenciesNotAscending { list: StructureList::Derivatives, index: DER_DQ }]);
}

#[test]
fn dependencies_kind_without_dependencies() {
    let problems = problems_after(|m| unknown(&mut m.model_structure.outputs, DQ).dependencies = None);
    assert_eq!(
        problems,
        vec![Problem::DependenciesKindWithoutDependencies { list: StructureList::Outputs, index: DQ }]
    );
}

#[test]
fn dependencies_kind_of_other_length() {
    let problems = problems_after(|m| {
        unknown(&mut m.model_structure.derivatives, DER_DQ).dependencies_kind.as_mut().unwrap().pop();
    });
    assert_eq!(
        problems,
        vec![Problem::DependenciesKindLengthMismatch {
            list: StructureList::Derivatives,
            index: DER_DQ,
            dependencies: 3,
            kinds: 2,
        }]
    );
}

#[test]
fn initial_unknown_with_tunable_dependency_kind() {
    let problems = problems_after(|m| {
        unknown(&mut m.model_structure.initial_unknowns, INERTIA).dependencies_kind =
            Some(vec![DependencyKind::Tunable]);
    });
    assert_eq!(
        problems,
        vec![Problem::IllegalInitialUnknownDependencyKind { index: INERTIA, kind: DependencyKind::Tunable }]
    );
}

// §2.2.8: Outputs.
#[test]
fn outputs_out_of_order() {
    let problems = problems_after(|m| m.model_structure.outputs.swap(0, 1));
    assert_eq!(
        problems,
        vec![Problem::OutputsMismatch { expected: vec![Q, DQ, SATURATED], actual: vec![DQ, Q, SATURATED] }]
    );
}

#[test]
fn output_missing_from_outputs() {
    let problems = problems_after(|m| {
        m.model_structure.outputs.pop();
    });
    assert_eq!(problems, vec![Problem::OutputsMismatch { expected: vec![Q, DQ, SATURATED], actual: vec![Q, DQ] }]);
}

#[test]
fn non_output_in_outputs() {
    let problems = problems_after(|m| m.model_structure.outputs.push(Unknown::new(INERTIA)));
    assert_eq!(
        problems,
        vec![Problem::OutputsMismatch { expected: vec![Q, DQ, SATURATED], actual: vec![Q, DQ, SATURATED, INERTIA] }]
    );
}

// §2.2.8: Derivatives.
#[test]
fn derivatives_entry_without_derivative_attribute() {
    let problems = problems_after(|m| m.model_structure.derivatives.push(Unknown::new(Q)));
    assert_eq!(problems, vec![Problem::NotAStateDerivative(Q)]);
}

#[test]
fn derivative_listed_twice() {
    let problems = problems_after(|m| m.model_structure.derivatives.push(Unknown::new(DER_Q)));
    assert_eq!(problems, vec![Problem::DuplicateDerivative(DER_Q)]);
}

// §2.2.8: InitialUnknowns.
#[test]
fn calculated_parameter_missing_from_initial_unknowns() {
    let problems = problems_after(|m| {
        m.model_structure.initial_unknowns.pop();
    });
    assert_eq!(
        problems,
        vec![Problem::InitialUnknownsMismatch {
            expected: vec![DER_DQ, DER_Q, SATURATED, INERTIA],
            actual: vec![DER_DQ, DER_Q, SATURATED],
        }]
    );
}

#[test]
fn approx_state_missing_from_initial_unknowns() {
    // q is an output and a state; with initial="approx" it becomes an
    // initial unknown.
    let problems = problems_after(|m| variable(m, "q").initial = Some(Initial::Approx));
    assert_eq!(
        problems,
        vec![Problem::InitialUnknownsMismatch {
            expected: vec![Q, DER_DQ, DER_Q, SATURATED, INERTIA],
            actual: vec![DER_DQ, DER_Q, SATURATED, INERTIA],
        }]
    );
}

#[test]
fn exact_output_in_initial_unknowns() {
    let problems = problems_after(|m| m.model_structure.initial_unknowns.insert(0, Unknown::new(Q)));
    assert_eq!(
        problems,
        vec![Problem::InitialUnknownsMismatch {
            expected: vec![DER_DQ, DER_Q, SATURATED, INERTIA],
            actual: vec![Q, DER_DQ, DER_Q, SATURATED, INERTIA],
        }]
    );
}

#[test]
fn initial_unknowns_out_of_order() {
    let problems = problems_after(|m| m.model_structure.initial_unknowns.swap(0, 1));
    assert_eq!(
        problems,
        vec![Problem::InitialUnknownsMismatch {
            expected: vec![DER_DQ, DER_Q, SATURATED, INERTIA],
            actual: vec![DER_Q, DER_DQ, SATURATED, INERTIA],
        }]
    );
}
