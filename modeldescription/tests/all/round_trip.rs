//! Writing a model description and reading it back gives the same model;
//! reading accepts the schema's other spellings and defaults.

use crate::common;

use modeldescription::*;

#[test]
fn written_document_reads_back_equal() {
    let model = common::arm();
    let xml = to_xml(&model).unwrap();
    assert_eq!(from_xml(&xml).unwrap(), model, "document:\n{xml}");
}

#[test]
fn model_without_optional_parts_reads_back_equal() {
    let mut model = common::arm();
    model.description = None;
    model.version = None;
    model.license = None;
    model.generation_tool = None;
    model.generation_date_and_time = None;
    model.variable_naming_convention = None;
    model.number_of_event_indicators = None;
    model.unit_definitions.clear();
    model.type_definitions.clear();
    model.log_categories.clear();
    model.default_experiment = None;
    model.model_variables.truncate(2); // time and the input tau
    model.model_structure = ModelStructure::default();
    for variable in &mut model.model_variables {
        if let VariableKind::Real(real) = &mut variable.kind {
            real.unit = None;
        }
    }
    let xml = to_xml(&model).unwrap();
    assert_eq!(from_xml(&xml).unwrap(), model, "document:\n{xml}");
}

/// A model whose only variable is a parameter with the given Real start.
fn with_real_start(start: f64) -> FmiModelDescription {
    let mut model = common::arm();
    model.model_variables.truncate(3); // ..., the mass parameter m
    let VariableKind::Real(real) = &mut model.model_variables[2].kind else { unreachable!() };
    real.start = Some(start);
    model
}

fn read_back_start(start: f64) -> f64 {
    let xml = to_xml(&with_real_start(start)).unwrap();
    let model = from_xml(&xml).unwrap();
    let VariableKind::Real(real) = &model.model_variables[2].kind else { unreachable!() };
    real.start.unwrap()
}

#[test]
fn floats_round_trip_bit_for_bit() {
    let values = [
        0.0,
        -0.0,
        0.1,
        1.0 / 3.0,
        -2.5e-7,
        1e-300,
        f64::MIN_POSITIVE,
        5e-324, // smallest subnormal
        f64::MAX,
        f64::MIN,
        1e16,
        123456789.125,
        std::f64::consts::PI,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    for value in values {
        let back = read_back_start(value);
        assert_eq!(back.to_bits(), value.to_bits(), "{value:e} came back as {back:e}");
    }
    assert!(read_back_start(f64::NAN).is_nan());
}

#[test]
fn floats_are_written_short_and_as_xsd_doubles() {
    let written = |start| to_xml(&with_real_start(start)).unwrap();
    // Shortest round-trip decimal, exponent notation far from 1, and the
    // xs:double spellings of the special values.
    for (value, spelling) in [
        (0.1, "start=\"0.1\""),
        (1.5, "start=\"1.5\""),
        (-3.0, "start=\"-3\""),
        (1e-300, "start=\"1e-300\""),
        (6.02214076e23, "start=\"6.02214076e23\""),
        (f64::INFINITY, "start=\"INF\""),
        (f64::NEG_INFINITY, "start=\"-INF\""),
        (f64::NAN, "start=\"NaN\""),
    ] {
        let xml = written(value);
        assert!(xml.contains(spelling), "{value:e} should be written as {spelling}:\n{xml}");
    }
}

#[test]
fn text_with_xml_special_characters_round_trips() {
    let mut model = common::arm();
    model.description = Some("a < b && c > \"d\" 'e'".to_owned());
    let xml = to_xml(&model).unwrap();
    assert_eq!(from_xml(&xml).unwrap().description, model.description);
}

/// A minimal document in another tool's style: attribute defaults left
/// out, XSD booleans as 1/0, ModelExchange and VendorAnnotations present.
const FOREIGN_DOCUMENT: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="m" guid="{0}">
  <ModelExchange modelIdentifier="m"/>
  <CoSimulation modelIdentifier="m" canHandleVariableCommunicationStepSize="1"/>
  <VendorAnnotations><Tool name="t"/></VendorAnnotations>
  <ModelVariables>
    <ScalarVariable name="x" valueReference="0">
      <Real derivative="2"/>
    </ScalarVariable>
    <ScalarVariable name="u" valueReference="1" causality="input">
      <Boolean start="0"/>
    </ScalarVariable>
  </ModelVariables>
  <ModelStructure/>
</fmiModelDescription>
"#;

#[test]
fn reading_applies_schema_defaults() {
    let model = from_xml(FOREIGN_DOCUMENT).unwrap();
    assert!(model.co_simulation.can_handle_variable_communication_step_size);
    assert!(!model.co_simulation.can_interpolate_inputs);
    assert_eq!(model.co_simulation.max_output_derivative_order, 0);
    assert_eq!(model.variable_naming_convention, None);
    let [x, u] = &model.model_variables[..] else { panic!("two variables expected") };
    assert_eq!((x.causality, x.variability, x.initial), (Causality::Local, Variability::Continuous, None));
    assert_eq!(x.kind, VariableKind::Real(RealVariable { derivative: Some(2), ..RealVariable::default() }));
    assert_eq!(u.causality, Causality::Input);
    assert_eq!(u.kind, VariableKind::Boolean(BooleanVariable { declared_type: None, start: Some(false) }));
    assert_eq!(model.model_structure, ModelStructure::default());
}

#[test]
fn reading_rejects_other_fmi_versions() {
    let fmi3 = FOREIGN_DOCUMENT.replace("fmiVersion=\"2.0\"", "fmiVersion=\"3.0\"");
    assert!(matches!(from_xml(&fmi3), Err(Error::Read(_))));
}

#[test]
fn reading_rejects_misspelled_values() {
    let misspelled = FOREIGN_DOCUMENT.replace("causality=\"input\"", "causality=\"Input\"");
    assert!(matches!(from_xml(&misspelled), Err(Error::Read(_))));
    let bad_double = FOREIGN_DOCUMENT.replace("derivative=\"2\"", "start=\"1,5\"");
    assert!(matches!(from_xml(&bad_double), Err(Error::Read(_))));
}

#[test]
fn reading_rejects_a_missing_required_attribute() {
    let no_guid = FOREIGN_DOCUMENT.replace(" guid=\"{0}\"", "");
    assert!(matches!(from_xml(&no_guid), Err(Error::Read(_))));
}
