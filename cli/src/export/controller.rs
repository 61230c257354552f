//! The controller FMU's modelDescription (`nudyn export --controller`),
//! rendered from the contract's controller table (`CONTROLLER_TABLE`). Same binary as the plant FMU: it tells the
//! two apart by the resource file it finds.

use std::path::Path;

use modeldescription as md;
use nudyn::control::{ControlError, ControlLaw, ControlParameters, Objective};
use nudyn::model::Model;
use nudyn_contract::controller::{CAPABILITIES, ControllerLayout, ControllerResource};
use nudyn_contract::resource::Resource;

use super::documentation::Row;
use super::{
    Document, ExportError, FmiVersion, Header, PlatformBinary, check_model_identifier, documentation, fmi3,
    fmu_archive, generation_date_and_time, real_variable, write_file,
};

/// What the controller's modelDescription says of the FMU as a whole.
fn header(model: &Model, law: &ControlLaw, model_identifier: &str, guid: &str) -> Header {
    let target = match &law.objective {
        Objective::Joints(joints) => format!("the {} hinge and slide joint values", joints.len()),
        Objective::Pose(frame) => format!("the pose of body '{}'", frame.body),
    };
    Header {
        model_name: format!("{}_controller", if model.name.is_empty() { model_identifier } else { &model.name }),
        guid: guid.to_string(),
        description: format!(
            "noninteracting controller of the vehicle '{}' (nq = {}, nv = {}): \
             eps = -c1 nu + l(theta) J^T(theta) c2 (Yhat - Y(theta)), Y = {target}",
            model.name, model.nq, model.nv
        ),
        model_identifier: model_identifier.to_string(),
        capabilities: CAPABILITIES,
        event_indicators: 0,
        generated: generation_date_and_time(),
    }
}

/// The Real `vr` of the controller FMU (whose layout is `layout`), as the writers need it.
fn real_scalar(
    model: &Model,
    law: &ControlLaw,
    layout: &ControllerLayout,
    defaults: &ControlParameters,
    vr: u32,
) -> fmi3::RealScalar {
    let element = layout.element(vr).expect("the table's Reals are the layout's");
    fmi3::RealScalar {
        kind: element.kind(),
        start: element.start(model, defaults),
        description: element.description(model, law),
    }
}

/// The documentation page's rows of the controller FMU of `resource` in `version`.
fn rows(resource: &ControllerResource, defaults: &ControlParameters, version: FmiVersion) -> Vec<Row> {
    let (model, law, layout) = (&resource.model, &resource.law, resource.layout());
    let real = |vr: u32| real_scalar(model, law, &layout, defaults, vr);
    match version {
        FmiVersion::Fmi2 => {
            layout.elements().map(|e| Row::real(e.name(), e.value_reference, real(e.value_reference))).collect()
        }
        FmiVersion::Fmi3 => [Row::time()].into_iter().chain(Row::float64s(&resource.fmi3_variables(), real)).collect(),
    }
}

/// The typed FMI 3.0 modelDescription of the controller FMU (not yet validated).
pub fn controller_model_description3(
    resource: &ControllerResource,
    defaults: &ControlParameters,
    model_identifier: &str,
    guid: &str,
) -> md::fmi3::Fmi3ModelDescription {
    let (model, law) = (&resource.model, &resource.law);
    let layout = resource.layout();
    let real = |vr: u32| real_scalar(model, law, &layout, defaults, vr);
    let others = fmi3::Others { enumeration_types: Vec::new(), variables: Vec::new(), parameters_change_values: true };
    let (table, dependencies) = (resource.fmi3_variables(), |vr| layout.dependency_vrs(vr));
    fmi3::model_description(header(model, law, model_identifier, guid), &table, real, dependencies, others)
}

/// The typed modelDescription of the controller FMU (validated when written).
pub fn controller_model_description(
    model: &Model,
    law: &ControlLaw,
    defaults: &ControlParameters,
    model_identifier: &str,
    guid: &str,
) -> md::FmiModelDescription {
    let layout = ControllerLayout::new(model, law);
    let model_variables: Vec<md::ScalarVariable> = layout
        .elements()
        .map(|e| {
            let (vr, description) = (e.value_reference, e.description(model, law));
            real_variable(e.name(), vr, description, e.kind(), e.start(model, defaults))
        })
        .collect();

    // Value references start at 1 in variable order, so index = vr.
    let resource = ControllerResource::new(model.clone(), law.clone());
    let mut outputs = Vec::new();
    let mut initial_unknowns = Vec::new();
    for (vr, _) in layout.variables() {
        if let Some(dependencies) = resource.dependencies(vr) {
            outputs.push(md::Unknown { index: vr, dependencies: super::listed(dependencies), dependencies_kind: None });
            initial_unknowns.push(md::Unknown::new(vr));
        }
    }
    let header = header(model, law, model_identifier, guid);
    let structure = md::ModelStructure { outputs, derivatives: Vec::new(), initial_unknowns };
    header.into_model_description(Vec::new(), model_variables, structure)
}

/// Why a controller FMU cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum ControllerExportError {
    /// The law cannot be built for this vehicle.
    #[error(transparent)]
    Control(#[from] ControlError),
    /// The archive cannot be written.
    #[error(transparent)]
    Export(#[from] ExportError),
}

/// Writes the controller FMU `out` for `model` with `law`; `binaries` are
/// the `nudyn_fmu` cdylib built for each platform, as for the plant;
/// `fmi3_scalars`: FMI 3.0 variables all scalars, for hosts without arrays.
pub fn write_controller_fmu(
    model: &Model,
    law: &ControlLaw,
    model_identifier: &str,
    fmi_version: FmiVersion,
    fmi3_scalars: bool,
    binaries: &[PlatformBinary],
    out: &Path,
) -> Result<(), ControllerExportError> {
    let bytes = controller_fmu(model, law, model_identifier, fmi_version, fmi3_scalars, binaries, out)?;
    Ok(write_file(out, &bytes)?)
}

/// The bytes of the controller FMU [`write_controller_fmu`] writes, built
/// in memory (`out` names it in messages).
pub fn controller_fmu(
    model: &Model,
    law: &ControlLaw,
    model_identifier: &str,
    fmi_version: FmiVersion,
    fmi3_scalars: bool,
    binaries: &[PlatformBinary],
    out: &Path,
) -> Result<Vec<u8>, ControllerExportError> {
    check_model_identifier(model_identifier)?;
    let defaults = law.default_parameters(model)?;
    let resource = ControllerResource { fmi3_scalars, ..ControllerResource::new(model.clone(), law.clone()) };
    let bytes = resource.to_json().map_err(ExportError::from)?;
    let guid = resource.guid(&bytes);
    let description = match fmi_version {
        FmiVersion::Fmi2 => {
            Document::Fmi2(controller_model_description(model, law, &defaults, model_identifier, &guid))
        }
        FmiVersion::Fmi3 => {
            Document::Fmi3(controller_model_description3(&resource, &defaults, model_identifier, &guid))
        }
    };
    let documentation =
        documentation::index_html(model, &description, &rows(&resource, &defaults, fmi_version), "controller");
    Ok(fmu_archive::<ControllerResource>(&description, &bytes, &documentation, binaries, out)?)
}
