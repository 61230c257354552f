//! Prints the model description of a small but representative co-simulation
//! FMU: a one-joint arm with a torque input, angle/rate outputs, parameters,
//! an integrator-method enumeration, units, a default experiment and the
//! model structure. The Python tests validate this output against the
//! official FMI 2.0 schema.
//!
//!     cargo run -q -p modeldescription --example write_example

use modeldescription::*;

fn real(unit: &str, start: Option<f64>) -> VariableKind {
    VariableKind::Real(RealVariable {
        unit: Some(unit.to_owned()),
        start,
        ..RealVariable::default()
    })
}

fn variable(
    name: &str,
    value_reference: u32,
    causality: Causality,
    variability: Variability,
    kind: VariableKind,
) -> ScalarVariable {
    ScalarVariable {
        name: name.to_owned(),
        value_reference,
        description: None,
        causality,
        variability,
        initial: None,
        can_handle_multiple_set_per_time_instant: None,
        kind,
    }
}

fn main() -> Result<(), Error> {
    use Causality::*;
    use Variability::*;

    let mut angle = variable("q", 3, Output, Continuous, real("rad", Some(0.1)));
    angle.initial = Some(Initial::Exact);
    angle.description = Some("joint angle".to_owned());
    let rate = variable("dq", 4, Output, Continuous, real("rad/s", Some(0.0)));
    let mut rate = ScalarVariable {
        initial: Some(Initial::Exact),
        ..rate
    };
    if let VariableKind::Real(r) = &mut rate.kind {
        r.display_unit = Some("deg/s".to_owned());
    }
    let mut acceleration = variable("der(dq)", 5, Local, Continuous, real("rad/s2", None));
    if let VariableKind::Real(r) = &mut acceleration.kind {
        r.derivative = Some(5);
    }
    let mut velocity = variable("der(q)", 6, Local, Continuous, real("rad/s", None));
    if let VariableKind::Real(r) = &mut velocity.kind {
        r.derivative = Some(4);
    }

    let model = FmiModelDescription {
        fmi_version: FmiVersion::Fmi2,
        model_name: "arm".to_owned(),
        guid: "{8c4e810f-3df3-4a00-8276-176fa3c9f000}".to_owned(),
        description: Some("one-joint arm driven by a torque".to_owned()),
        author: None,
        version: Some("0.1.0".to_owned()),
        copyright: None,
        license: Some("MIT".to_owned()),
        generation_tool: Some("nudyn modeldescription example".to_owned()),
        generation_date_and_time: Some("2024-01-31T12:00:00Z".to_owned()),
        variable_naming_convention: Some(VariableNamingConvention::Structured),
        number_of_event_indicators: Some(0),
        co_simulation: CoSimulation {
            model_identifier: "arm".to_owned(),
            needs_execution_tool: false,
            can_handle_variable_communication_step_size: true,
            can_interpolate_inputs: false,
            max_output_derivative_order: 0,
            can_run_asynchronuously: false,
            can_be_instantiated_only_once_per_process: false,
            can_not_use_memory_management_functions: true,
            can_get_and_set_fmu_state: false,
            can_serialize_fmu_state: false,
            provides_directional_derivative: false,
        },
        unit_definitions: vec![
            Unit {
                name: "rad".to_owned(),
                base_unit: Some(BaseUnit {
                    rad: 1,
                    ..BaseUnit::default()
                }),
                display_units: vec![DisplayUnit {
                    name: "deg".to_owned(),
                    factor: Some(180.0 / std::f64::consts::PI),
                    offset: None,
                }],
            },
            Unit {
                name: "rad/s".to_owned(),
                base_unit: Some(BaseUnit {
                    rad: 1,
                    s: -1,
                    ..BaseUnit::default()
                }),
                display_units: vec![DisplayUnit {
                    name: "deg/s".to_owned(),
                    factor: Some(180.0 / std::f64::consts::PI),
                    offset: None,
                }],
            },
            Unit {
                name: "rad/s2".to_owned(),
                base_unit: Some(BaseUnit {
                    rad: 1,
                    s: -2,
                    ..BaseUnit::default()
                }),
                display_units: vec![],
            },
            Unit {
                name: "N.m".to_owned(),
                base_unit: Some(BaseUnit {
                    kg: 1,
                    m: 2,
                    s: -2,
                    ..BaseUnit::default()
                }),
                display_units: vec![],
            },
            Unit {
                name: "kg".to_owned(),
                base_unit: Some(BaseUnit {
                    kg: 1,
                    ..BaseUnit::default()
                }),
                display_units: vec![],
            },
            Unit {
                name: "s".to_owned(),
                base_unit: Some(BaseUnit {
                    s: 1,
                    ..BaseUnit::default()
                }),
                display_units: vec![],
            },
        ],
        type_definitions: vec![
            SimpleType {
                name: "IntegratorMethod".to_owned(),
                description: Some(
                    "fixed-step integrator used inside one communication step".to_owned(),
                ),
                kind: SimpleTypeKind::Enumeration(EnumerationType {
                    quantity: None,
                    items: vec![
                        Item {
                            name: "euler".to_owned(),
                            value: 1,
                            description: Some("explicit Euler".to_owned()),
                        },
                        Item {
                            name: "rk4".to_owned(),
                            value: 2,
                            description: Some("classical Runge-Kutta".to_owned()),
                        },
                    ],
                }),
            },
            SimpleType {
                name: "Mass".to_owned(),
                description: None,
                kind: SimpleTypeKind::Real(RealType {
                    quantity: Some("Mass".to_owned()),
                    unit: Some("kg".to_owned()),
                    min: Some(0.0),
                    ..RealType::default()
                }),
            },
        ],
        log_categories: vec![
            Category {
                name: "logStatusError".to_owned(),
                description: Some("errors".to_owned()),
            },
            Category {
                name: "logAll".to_owned(),
                description: None,
            },
        ],
        default_experiment: Some(DefaultExperiment {
            start_time: Some(0.0),
            stop_time: Some(10.0),
            tolerance: Some(1e-6),
            step_size: Some(1e-3),
        }),
        model_variables: vec![
            variable("time", 0, Independent, Continuous, real("s", None)),
            variable("tau", 1, Input, Continuous, real("N.m", Some(0.0))),
            variable(
                "m",
                2,
                Parameter,
                Fixed,
                VariableKind::Real(RealVariable {
                    declared_type: Some("Mass".to_owned()),
                    start: Some(1.5),
                    ..RealVariable::default()
                }),
            ),
            angle,
            rate,
            acceleration,
            velocity,
            variable(
                "integrator",
                0,
                Parameter,
                Fixed,
                VariableKind::Enumeration(EnumerationVariable {
                    declared_type: "IntegratorMethod".to_owned(),
                    quantity: None,
                    min: None,
                    max: None,
                    start: Some(2),
                }),
            ),
            variable(
                "steps",
                1,
                Parameter,
                Tunable,
                VariableKind::Integer(IntegerVariable {
                    start: Some(1),
                    min: Some(1),
                    ..IntegerVariable::default()
                }),
            ),
            variable(
                "saturated",
                0,
                Output,
                Discrete,
                VariableKind::Boolean(BooleanVariable::default()),
            ),
        ],
        model_structure: ModelStructure {
            outputs: vec![
                Unknown::new(4),
                Unknown {
                    index: 5,
                    dependencies: Some(vec![5]),
                    dependencies_kind: Some(vec![DependencyKind::Constant]),
                },
                Unknown {
                    index: 10,
                    dependencies: Some(vec![]),
                    dependencies_kind: Some(vec![]),
                },
            ],
            derivatives: vec![
                Unknown {
                    index: 6,
                    dependencies: Some(vec![2, 4, 5]),
                    dependencies_kind: Some(vec![
                        DependencyKind::Constant,
                        DependencyKind::Dependent,
                        DependencyKind::Dependent,
                    ]),
                },
                Unknown::new(7),
            ],
            initial_unknowns: vec![Unknown::new(6), Unknown::new(7), Unknown::new(10)],
        },
    };

    let problems = validate(&model);
    assert!(
        problems.is_empty(),
        "the example breaks FMI 2.0 rules: {problems:#?}"
    );
    print!("{}", to_xml(&model)?);
    Ok(())
}
