//! A small but representative co-simulation model description, shared by
//! the tests and by `examples/write_example.rs` (whose output the Python
//! tests check against the official FMI 2.0 schema).

// The tests and the example each use a part of this module.
#![allow(dead_code)]

use modeldescription::*;

/// 1-based ScalarVariable indices of [`arm`]'s variables, for
/// `<ModelStructure>` and `derivative`.
pub mod index {
    pub const TAU: u32 = 2;
    pub const MASS: u32 = 3;
    pub const Q: u32 = 4;
    pub const DQ: u32 = 5;
    pub const DER_DQ: u32 = 6;
    pub const DER_Q: u32 = 7;
    pub const SATURATED: u32 = 10;
    pub const INERTIA: u32 = 11;
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

fn real(unit: &str) -> RealVariable {
    RealVariable { unit: Some(unit.to_owned()), ..RealVariable::default() }
}

fn unit(name: &str, base_unit: BaseUnit, display_units: Vec<DisplayUnit>) -> Unit {
    Unit { name: name.to_owned(), base_unit: Some(base_unit), display_units }
}

fn degrees(name: &str) -> DisplayUnit {
    DisplayUnit { name: name.to_owned(), factor: Some(180.0 / std::f64::consts::PI), offset: None }
}

/// A one-joint arm driven by a torque: independent time, an input,
/// parameters (Real with a declared type, Enumeration, Integer, String),
/// outputs (two continuous states, one discrete Boolean), state
/// derivatives and a calculated parameter, with units, types, log
/// categories, a default experiment and the complete model structure.
/// It satisfies every rule [`validate`] checks.
pub fn arm() -> FmiModelDescription {
    use Causality::*;
    use Variability::*;
    use index::*;

    let q = ScalarVariable {
        description: Some("joint angle".to_owned()),
        initial: Some(Initial::Exact),
        ..variable("q", 3, Output, Continuous, VariableKind::Real(RealVariable { start: Some(0.1), ..real("rad") }))
    };
    let dq = ScalarVariable {
        initial: Some(Initial::Exact),
        ..variable(
            "dq",
            4,
            Output,
            Continuous,
            VariableKind::Real(RealVariable {
                display_unit: Some("deg/s".to_owned()),
                start: Some(0.0),
                ..real("rad/s")
            }),
        )
    };

    FmiModelDescription {
        fmi_version: FmiVersion::Fmi2,
        model_name: "arm".to_owned(),
        guid: "{8c4e810f-3df3-4a00-8276-176fa3c9f000}".to_owned(),
        description: Some("one-joint arm driven by a torque".to_owned()),
        author: None,
        version: Some("0.1.0".to_owned()),
        copyright: None,
        license: Some("MIT".to_owned()),
        generation_tool: Some("nudyn".to_owned()),
        generation_date_and_time: Some("2024-01-31T12:00:00Z".to_owned()),
        variable_naming_convention: Some(VariableNamingConvention::Structured),
        number_of_event_indicators: Some(0),
        model_exchange: None,
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
            unit("rad", BaseUnit { rad: 1, ..BaseUnit::default() }, vec![degrees("deg")]),
            unit("rad/s", BaseUnit { rad: 1, s: -1, ..BaseUnit::default() }, vec![degrees("deg/s")]),
            unit("rad/s2", BaseUnit { rad: 1, s: -2, ..BaseUnit::default() }, vec![]),
            unit("N.m", BaseUnit { kg: 1, m: 2, s: -2, ..BaseUnit::default() }, vec![]),
            unit("kg", BaseUnit { kg: 1, ..BaseUnit::default() }, vec![]),
            unit("kg.m2", BaseUnit { kg: 1, m: 2, ..BaseUnit::default() }, vec![]),
            unit("s", BaseUnit { s: 1, ..BaseUnit::default() }, vec![]),
            unit("degC", BaseUnit { k: 1, offset: Some(273.15), ..BaseUnit::default() }, vec![]),
        ],
        type_definitions: vec![
            SimpleType {
                name: "IntegratorMethod".to_owned(),
                description: Some("fixed-step integrator used inside one communication step".to_owned()),
                kind: SimpleTypeKind::Enumeration(EnumerationType {
                    quantity: None,
                    items: vec![
                        Item { name: "euler".to_owned(), value: 1, description: Some("explicit Euler".to_owned()) },
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
            Category { name: "logStatusError".to_owned(), description: Some("errors".to_owned()) },
            Category { name: "logAll".to_owned(), description: None },
        ],
        default_experiment: Some(DefaultExperiment {
            start_time: Some(0.0),
            stop_time: Some(10.0),
            tolerance: Some(1e-6),
            step_size: Some(1e-3),
        }),
        model_variables: vec![
            variable("time", 0, Independent, Continuous, VariableKind::Real(real("s"))),
            variable("tau", 1, Input, Continuous, VariableKind::Real(RealVariable { start: Some(0.0), ..real("N.m") })),
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
            q,
            dq,
            variable(
                "der(dq)",
                5,
                Local,
                Continuous,
                VariableKind::Real(RealVariable { derivative: Some(DQ), ..real("rad/s2") }),
            ),
            variable(
                "der(q)",
                6,
                Local,
                Continuous,
                VariableKind::Real(RealVariable { derivative: Some(Q), ..real("rad/s") }),
            ),
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
                VariableKind::Integer(IntegerVariable { min: Some(1), start: Some(1), ..IntegerVariable::default() }),
            ),
            variable("saturated", 0, Output, Discrete, VariableKind::Boolean(BooleanVariable::default())),
            variable("inertia", 7, CalculatedParameter, Fixed, VariableKind::Real(real("kg.m2"))),
            variable(
                "label",
                0,
                Parameter,
                Fixed,
                VariableKind::String(StringVariable { declared_type: None, start: Some("arm <1> & \"2\"".to_owned()) }),
            ),
        ],
        model_structure: ModelStructure {
            outputs: vec![
                Unknown::new(Q),
                Unknown {
                    index: DQ,
                    dependencies: Some(vec![DQ]),
                    dependencies_kind: Some(vec![DependencyKind::Constant]),
                },
                Unknown { index: SATURATED, dependencies: Some(vec![]), dependencies_kind: Some(vec![]) },
            ],
            derivatives: vec![
                Unknown {
                    index: DER_DQ,
                    dependencies: Some(vec![TAU, Q, DQ]),
                    dependencies_kind: Some(vec![
                        DependencyKind::Constant,
                        DependencyKind::Dependent,
                        DependencyKind::Dependent,
                    ]),
                },
                Unknown::new(DER_Q),
            ],
            initial_unknowns: vec![
                Unknown::new(DER_DQ),
                Unknown::new(DER_Q),
                Unknown::new(SATURATED),
                Unknown {
                    index: INERTIA,
                    dependencies: Some(vec![MASS]),
                    dependencies_kind: Some(vec![DependencyKind::Dependent]),
                },
            ],
        },
    }
}
