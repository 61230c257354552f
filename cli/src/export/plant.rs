//! The plant FMU's modelDescription, rendered from the contract's
//! variable table (`nudyn_contract::plant::TABLE`).

use std::path::Path;

use modeldescription as md;
use modeldescription::fmi3 as md3;
use nudyn::integrate::MethodSetting;
use nudyn::model::Model;
use nudyn_contract::blocks::Shape;
use nudyn_contract::plant::{
    ENERGY_PROJECTION_NAME, ENERGY_PROJECTION_VR, Element, Layout, METHOD_NAME, METHOD_TYPE, METHOD_VR,
    OptionalOutputs, PlantResource, RealVariable, capabilities, method_value,
};
use nudyn_contract::resource::Resource;
use nudyn_contract::variable::Causality;

use super::documentation::Row;
use super::{
    Document, ExportError, FmiVersion, Header, PlatformBinary, check_model_identifier, documentation, fmi3,
    fmu_archive, generation_date_and_time, real_variable, write_file,
};

/// What `nudyn export` is asked for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ExportOptions {
    /// The model identifier: the shared library's name, a C identifier.
    pub model_identifier: String,
    /// The optional outputs.
    pub outputs: OptionalOutputs,
    /// The FMI version.
    pub fmi_version: FmiVersion,
}

/// What the plant's modelDescription says of the FMU as a whole.
fn header(model: &Model, options: &ExportOptions, guid: &str) -> Header {
    Header {
        model_name: if model.name.is_empty() { options.model_identifier.clone() } else { model.name.clone() },
        guid: guid.to_string(),
        description: match model.constraints.summary() {
            None => format!(
                "diagonalized dynamics of the vehicle '{}' (nq = {}, nv = {}): nu' + C(theta, nu) = eps",
                model.name, model.nq, model.nv
            ),
            Some(constraints) => format!(
                "diagonalized dynamics of the vehicle '{}' (nq = {}, nv = {}): nu' + C(theta, nu) = eps + eps_c; {}",
                model.name, model.nq, model.nv, constraints
            ),
        },
        model_identifier: options.model_identifier.clone(),
        capabilities: capabilities(options.outputs),
        event_indicators: Layout::new(model, options.outputs).event_indicator_count(),
        generated: generation_date_and_time(),
    }
}

const METHOD_DESCRIPTION: &str = "integration method";

const ENERGY_PROJECTION_DESCRIPTION: &str = "rescale nu after each internal step so that the kinetic energy follows \
     the work done (keeps K exactly when no force acts)";

/// The item description of `method` in the enumeration type.
fn method_item_description(method: MethodSetting) -> String {
    format!("{} (Munthe-Kaas on rotations)", method.description())
}

/// The FMI 2.0 Real `vr` of the plant FMU of `resource` (whose layout is `layout`), as the writers need it.
fn real_scalar(resource: &PlantResource, layout: &Layout, vr: u32) -> fmi3::RealScalar {
    let element = layout.element(vr).expect("the table's Reals are the layout's");
    fmi3::RealScalar {
        kind: element.kind(),
        start: resource.start(&element),
        description: element.description(&resource.model),
    }
}

/// The documentation page's rows of the plant FMU of `resource` in `version`, from its table.
fn rows(resource: &PlantResource, version: FmiVersion) -> Vec<Row> {
    let layout = resource.layout();
    let method_start = method_value(resource.method).to_string();
    let real = |vr: u32| real_scalar(resource, &layout, vr);
    match version {
        FmiVersion::Fmi2 => {
            let parameters = [
                Row::fixed_parameter(METHOD_NAME, METHOD_VR, method_start, METHOD_DESCRIPTION),
                Row::fixed_parameter(
                    ENERGY_PROJECTION_NAME,
                    ENERGY_PROJECTION_VR,
                    false.to_string(),
                    ENERGY_PROJECTION_DESCRIPTION,
                ),
            ];
            let reals = layout.elements().map(|e| Row::real(e.name(), e.value_reference, real(e.value_reference)));
            parameters.into_iter().chain(reals).collect()
        }
        FmiVersion::Fmi3 => {
            let table = resource.fmi3_variables();
            let vr = |name: &str| table.value_reference(name).expect("the plant's table has it");
            let parameters = [
                Row::time(),
                Row::fixed_parameter(METHOD_NAME, vr(METHOD_NAME), method_start, METHOD_DESCRIPTION),
                Row::fixed_parameter(
                    ENERGY_PROJECTION_NAME,
                    vr(ENERGY_PROJECTION_NAME),
                    false.to_string(),
                    ENERGY_PROJECTION_DESCRIPTION,
                ),
            ];
            parameters.into_iter().chain(Row::float64s(&table, real)).collect()
        }
    }
}

/// The typed FMI 3.0 modelDescription of the plant FMU (not yet validated).
pub fn model_description3(resource: &PlantResource, options: &ExportOptions, guid: &str) -> md3::Fmi3ModelDescription {
    let model = &resource.model;
    let layout = resource.layout();
    let table = resource.fmi3_variables();
    let method_type = md3::EnumerationType {
        name: METHOD_TYPE.into(),
        description: Some(METHOD_DESCRIPTION.into()),
        items: MethodSetting::ALL
            .iter()
            .map(|&method| md3::Item {
                name: method.name().into(),
                value: i64::from(method_value(method)),
                description: Some(method_item_description(method)),
            })
            .collect(),
    };
    let vr = |name: &str| table.value_reference(name).expect("the plant's table has it");
    let method = md3::Variable::Enumeration(md3::Enumeration {
        name: METHOD_NAME.into(),
        value_reference: vr(METHOD_NAME),
        description: Some(METHOD_DESCRIPTION.into()),
        causality: "parameter".into(),
        variability: "fixed".into(),
        initial: Some("exact".into()),
        declared_type: METHOD_TYPE.into(),
        start: Some(i64::from(method_value(resource.method))),
    });
    let energy_projection = md3::Variable::Boolean(md3::Boolean {
        name: ENERGY_PROJECTION_NAME.into(),
        value_reference: vr(ENERGY_PROJECTION_NAME),
        description: Some(ENERGY_PROJECTION_DESCRIPTION.into()),
        causality: "parameter".into(),
        variability: "fixed".into(),
        initial: Some("exact".into()),
        start: Some(false),
    });
    let others = fmi3::Others {
        enumeration_types: vec![method_type],
        variables: vec![method, energy_projection],
        parameters_change_values: false,
    };
    let real = |vr: u32| real_scalar(resource, &layout, vr);
    let dependencies = |vr| layout.dependency_vrs(vr);
    fmi3::model_description(header(model, options, guid), &table, real, dependencies, others)
}

/// The typed modelDescription of the plant FMU (not yet validated).
pub fn model_description(resource: &PlantResource, options: &ExportOptions, guid: &str) -> md::FmiModelDescription {
    let model = &resource.model;
    let layout = Layout::new(model, options.outputs);
    let method = md::ScalarVariable {
        name: METHOD_NAME.into(),
        value_reference: METHOD_VR,
        description: Some(METHOD_DESCRIPTION.into()),
        causality: md::Causality::Parameter,
        variability: md::Variability::Fixed,
        initial: Some(md::Initial::Exact),
        can_handle_multiple_set_per_time_instant: None,
        kind: md::VariableKind::Enumeration(md::EnumerationVariable {
            declared_type: METHOD_TYPE.into(),
            quantity: None,
            min: None,
            max: None,
            start: Some(method_value(resource.method)),
        }),
    };
    let energy_projection = md::ScalarVariable {
        name: ENERGY_PROJECTION_NAME.into(),
        value_reference: ENERGY_PROJECTION_VR,
        description: Some(ENERGY_PROJECTION_DESCRIPTION.into()),
        causality: md::Causality::Parameter,
        variability: md::Variability::Fixed,
        initial: Some(md::Initial::Exact),
        can_handle_multiple_set_per_time_instant: None,
        kind: md::VariableKind::Boolean(md::BooleanVariable { start: Some(false), ..Default::default() }),
    };
    let reals: Vec<Element> = layout.elements().collect();
    // 1-based ScalarVariable indices, as <ModelStructure> and `derivative` refer to them: the
    // Reals' value references run from 1 in ScalarVariable order, after method and energy_projection.
    let index_of = |vr: u32| 2 + vr;
    let index_of_variable = |variable: RealVariable| index_of(layout.value_reference(variable).expect("listed"));
    // A derivative's state: the element of the same index of the array it differentiates.
    let state_of = |element: &Element| {
        (element.entry.shape == Shape::Derivative).then(|| {
            let state = layout.elements().find(|state| {
                state.entry.shape == Shape::Array
                    && state.entry.name == element.entry.name
                    && state.index == element.index
            });
            index_of(state.expect("the state precedes its derivative").value_reference)
        })
    };
    let scalar_variables = reals.iter().map(|element| {
        let vr = element.value_reference;
        let mut scalar =
            real_variable(element.name(), vr, element.description(model), element.kind(), resource.start(element));
        if let md::VariableKind::Real(real) = &mut scalar.kind {
            real.derivative = state_of(element);
        }
        scalar
    });
    let model_variables: Vec<md::ScalarVariable> =
        [method, energy_projection].into_iter().chain(scalar_variables).collect();

    let mut outputs = Vec::new();
    let mut derivatives = Vec::new();
    let mut initial_unknowns = Vec::new();
    for element in &reals {
        let kind = element.kind();
        let unknown = md::Unknown {
            index: index_of(element.value_reference),
            dependencies: layout
                .dependencies(element.variable())
                .and_then(|knowns| super::listed(knowns.into_iter().map(index_of_variable).collect())),
            dependencies_kind: None,
        };
        if !kind.exact_start && (kind.causality == Causality::Output || element.entry.shape == Shape::Derivative) {
            // Calculated outputs and the derivatives are initial unknowns,
            // the same functions of θ and ν (exact start values there) and
            // the inputs as after initialization.
            initial_unknowns.push(unknown.clone());
        }
        if kind.causality == Causality::Output {
            outputs.push(unknown);
        } else if element.entry.shape == Shape::Derivative {
            derivatives.push(unknown);
        }
    }

    let method_type = md::SimpleType {
        name: METHOD_TYPE.into(),
        description: Some(METHOD_DESCRIPTION.into()),
        kind: md::SimpleTypeKind::Enumeration(md::EnumerationType {
            quantity: None,
            items: MethodSetting::ALL
                .iter()
                .map(|&method| md::Item {
                    name: method.name().into(),
                    value: method_value(method),
                    description: Some(method_item_description(method)),
                })
                .collect(),
        }),
    };
    let header = header(model, options, guid);
    let structure = md::ModelStructure { outputs, derivatives, initial_unknowns };
    header.into_model_description(vec![method_type], model_variables, structure)
}

/// Writes the plant FMU `out` of `model`: modelDescription.xml (validated
/// first), the `nudyn_fmu` cdylib built for each platform of `binaries`
/// (e.g. `binaries/linux64/<modelIdentifier>.so`), `resources/model.json`
/// and `documentation/index.html`.
pub fn write_fmu(
    model: &Model,
    options: &ExportOptions,
    binaries: &[PlatformBinary],
    out: &Path,
) -> Result<(), ExportError> {
    write_plant_fmu(&PlantResource::new(model.clone(), options.outputs), options, binaries, out)
}

/// Writes the plant FMU `out` of `resource` (its model, optional outputs
/// and start values) as [`write_fmu`] does.
pub fn write_plant_fmu(
    resource: &PlantResource,
    options: &ExportOptions,
    binaries: &[PlatformBinary],
    out: &Path,
) -> Result<(), ExportError> {
    write_file(out, &plant_fmu(resource, options, binaries, out)?)
}

/// The bytes of the plant FMU of `resource`, built in memory (`out` names
/// it in messages): for a file of its own or an entry of a system file.
pub fn plant_fmu(
    resource: &PlantResource,
    options: &ExportOptions,
    binaries: &[PlatformBinary],
    out: &Path,
) -> Result<Vec<u8>, ExportError> {
    check_model_identifier(&options.model_identifier)?;
    let bytes = resource.to_json()?;
    let guid = resource.guid(&bytes);
    let description = match options.fmi_version {
        FmiVersion::Fmi2 => Document::Fmi2(model_description(resource, options, &guid)),
        FmiVersion::Fmi3 => Document::Fmi3(model_description3(resource, options, &guid)),
    };
    let documentation =
        documentation::index_html(&resource.model, &description, &rows(resource, options.fmi_version), "plant");
    fmu_archive::<PlantResource>(&description, &bytes, &documentation, binaries, out)
}
