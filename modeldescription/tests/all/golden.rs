//! The written document uses the exact element names, attribute names and
//! value spellings of the FMI 2.0 schema (fmi2ModelDescription.xsd and the
//! files it includes), in the order its `xs:sequence`s require.

use crate::common;

use modeldescription::*;

fn arm_xml() -> String {
    to_xml(&common::arm()).unwrap()
}

#[track_caller]
fn assert_contains(xml: &str, expected: &str) {
    assert!(xml.contains(expected), "expected `{expected}` in:\n{xml}");
}

#[test]
fn document_starts_with_the_xml_declaration_and_the_fmi2_root() {
    let xml = arm_xml();
    let mut lines = xml.lines();
    assert_eq!(lines.next(), Some(r#"<?xml version="1.0" encoding="UTF-8"?>"#));
    assert!(
        lines.next().unwrap().starts_with(r#"<fmiModelDescription fmiVersion="2.0" modelName="arm" guid="{8c4e810f-"#)
    );
    assert!(xml.ends_with("</fmiModelDescription>\n"));
}

#[test]
fn model_attributes_use_fmi_names() {
    let xml = arm_xml();
    for expected in [
        r#"description="one-joint arm driven by a torque""#,
        r#"version="0.1.0""#,
        r#"license="MIT""#,
        r#"generationTool="nudyn""#,
        r#"generationDateAndTime="2024-01-31T12:00:00Z""#,
        r#"variableNamingConvention="structured""#,
        r#"numberOfEventIndicators="0""#,
    ] {
        assert_contains(&xml, expected);
    }
    // None is left out, not written empty.
    assert!(!xml.contains("author="), "{xml}");
    assert!(!xml.contains("copyright="), "{xml}");
}

#[test]
fn co_simulation_capabilities_use_fmi_names_and_xsd_booleans() {
    assert_contains(
        &arm_xml(),
        concat!(
            r#"<CoSimulation modelIdentifier="arm" needsExecutionTool="false" "#,
            r#"canHandleVariableCommunicationStepSize="true" canInterpolateInputs="false" "#,
            r#"maxOutputDerivativeOrder="0" canRunAsynchronuously="false" "#,
            r#"canBeInstantiatedOnlyOncePerProcess="false" canNotUseMemoryManagementFunctions="true" "#,
            r#"canGetAndSetFMUstate="false" canSerializeFMUstate="false" "#,
            r#"providesDirectionalDerivative="false"/>"#,
        ),
    );
}

#[test]
fn units_write_only_non_default_exponents() {
    let xml = arm_xml();
    assert_contains(&xml, r#"<UnitDefinitions>"#);
    assert_contains(&xml, r#"<Unit name="N.m">"#);
    assert_contains(&xml, r#"<BaseUnit kg="1" m="2" s="-2"/>"#);
    assert_contains(&xml, r#"<BaseUnit s="-1" rad="1"/>"#);
    assert_contains(&xml, r#"<BaseUnit K="1" offset="273.15"/>"#);
    assert_contains(&xml, r#"<DisplayUnit name="deg" factor="57.29577951308232"/>"#);
}

#[test]
fn type_definitions_hold_an_enumeration_with_items() {
    let xml = arm_xml();
    assert_contains(&xml, r#"<SimpleType name="IntegratorMethod" description="#);
    assert_contains(&xml, r#"<Item name="euler" value="1" description="explicit Euler"/>"#);
    assert_contains(&xml, r#"<Real quantity="Mass" unit="kg" min="0"/>"#);
    assert_contains(&xml, r#"<Enumeration declaredType="IntegratorMethod" start="2"/>"#);
}

#[test]
fn log_categories_and_default_experiment() {
    let xml = arm_xml();
    assert_contains(&xml, r#"<Category name="logStatusError" description="errors"/>"#);
    assert_contains(&xml, r#"<DefaultExperiment startTime="0" stopTime="10" tolerance="1e-6" stepSize="0.001"/>"#);
}

#[test]
fn scalar_variables_use_fmi_attribute_names() {
    let xml = arm_xml();
    assert_contains(
        &xml,
        r#"<ScalarVariable name="q" valueReference="3" description="joint angle" causality="output" variability="continuous" initial="exact">"#,
    );
    assert_contains(&xml, r#"<Real unit="rad/s" displayUnit="deg/s" start="0"/>"#);
    assert_contains(&xml, r#"<Real unit="rad/s2" derivative="5"/>"#);
    assert_contains(&xml, r#"<Real declaredType="Mass" start="1.5"/>"#);
    assert_contains(&xml, r#"<Integer min="1" start="1"/>"#);
    assert_contains(&xml, r#"<Boolean/>"#);
    assert_contains(&xml, r#"<String start="arm &lt;1&gt; &amp; &quot;2&quot;"/>"#);
    // An input takes no initial attribute.
    assert_contains(
        &xml,
        r#"<ScalarVariable name="tau" valueReference="1" causality="input" variability="continuous">"#,
    );
}

/// Every value of the schema's enumerations, as the schema spells it.
#[test]
fn enumeration_values_use_schema_spellings() {
    let mut model = common::arm();
    let template = model.model_variables[1].clone();
    let causalities = [
        (Causality::Parameter, "parameter"),
        (Causality::CalculatedParameter, "calculatedParameter"),
        (Causality::Input, "input"),
        (Causality::Output, "output"),
        (Causality::Local, "local"),
        (Causality::Independent, "independent"),
    ];
    let variabilities = [
        (Variability::Constant, "constant"),
        (Variability::Fixed, "fixed"),
        (Variability::Tunable, "tunable"),
        (Variability::Discrete, "discrete"),
        (Variability::Continuous, "continuous"),
    ];
    let initials = [(Initial::Exact, "exact"), (Initial::Approx, "approx"), (Initial::Calculated, "calculated")];
    let kinds = [
        (DependencyKind::Dependent, "dependent"),
        (DependencyKind::Constant, "constant"),
        (DependencyKind::Fixed, "fixed"),
        (DependencyKind::Tunable, "tunable"),
        (DependencyKind::Discrete, "discrete"),
    ];
    model.model_variables = causalities
        .iter()
        .zip(variabilities.iter().cycle())
        .zip(initials.iter().cycle())
        .map(|(((causality, _), (variability, _)), (initial, _))| ScalarVariable {
            causality: *causality,
            variability: *variability,
            initial: Some(*initial),
            ..template.clone()
        })
        .collect();
    model.model_structure.outputs[0].dependencies = Some(vec![1; kinds.len()]);
    model.model_structure.outputs[0].dependencies_kind = Some(kinds.iter().map(|(kind, _)| *kind).collect());
    model.variable_naming_convention = Some(VariableNamingConvention::Flat);
    let xml = to_xml(&model).unwrap();

    for (causality, spelling) in causalities {
        assert_contains(&xml, &format!(r#"causality="{spelling}""#));
        assert_eq!(causality.to_string(), spelling);
    }
    for (variability, spelling) in variabilities {
        assert_contains(&xml, &format!(r#"variability="{spelling}""#));
        assert_eq!(variability.to_string(), spelling);
    }
    for (initial, spelling) in initials {
        assert_contains(&xml, &format!(r#"initial="{spelling}""#));
        assert_eq!(initial.to_string(), spelling);
    }
    assert_contains(&xml, r#"dependencies="1 1 1 1 1" dependenciesKind="dependent constant fixed tunable discrete""#);
    for (kind, spelling) in kinds {
        assert_eq!(kind.to_string(), spelling);
    }
    assert_contains(&xml, r#"variableNamingConvention="flat""#);
}

#[test]
fn model_structure_lists_unknowns_with_dependency_lists() {
    let xml = arm_xml();
    assert_contains(&xml, "<ModelStructure>\n    <Outputs>\n      <Unknown index=\"4\"/>");
    assert_contains(
        &xml,
        r#"<Unknown index="6" dependencies="2 4 5" dependenciesKind="constant dependent dependent"/>"#,
    );
    // An empty list means "depends on no known" and must stay distinct from
    // an absent attribute ("depends on all knowns").
    assert_contains(&xml, r#"<Unknown index="10" dependencies="" dependenciesKind=""/>"#);
    assert_contains(&xml, "<InitialUnknowns>");
}

#[test]
fn elements_follow_the_schema_sequence() {
    let xml = arm_xml();
    let order = [
        "<CoSimulation ",
        "<UnitDefinitions>",
        "<TypeDefinitions>",
        "<LogCategories>",
        "<DefaultExperiment ",
        "<ModelVariables>",
        "<ModelStructure>",
        "<Outputs>",
        "<Derivatives>",
        "<InitialUnknowns>",
    ];
    let positions: Vec<usize> =
        order.iter().map(|tag| xml.find(tag).unwrap_or_else(|| panic!("{tag} missing"))).collect();
    assert!(positions.is_sorted(), "{order:?} out of order:\n{xml}");
}

#[test]
fn empty_lists_leave_their_wrapper_elements_out() {
    // The schema requires at least one child in each of these wrappers.
    let mut model = common::arm();
    model.unit_definitions.clear();
    model.type_definitions.clear();
    model.log_categories.clear();
    model.model_structure = ModelStructure::default();
    let xml = to_xml(&model).unwrap();
    for absent in
        ["<UnitDefinitions", "<TypeDefinitions", "<LogCategories", "<Outputs", "<Derivatives", "<InitialUnknowns"]
    {
        assert!(!xml.contains(absent), "{absent} written:\n{xml}");
    }
    assert_contains(&xml, "<ModelStructure/>");
}
