//! The controller FMU (`nudyn export --controller`): the control law of
//! [`super`] as an FMI 2.0 co-simulation FMU for the same vehicle as the
//! plant FMU, with the plant's variable names so that a master connects
//! them name to name: plant `theta[i]` → controller `theta[i]`, plant
//! `nu[i]` → controller `nu[i]`, controller `eps[i]` → plant `eps[i]`.
//!
//! The controller is a direct-feedthrough algebraic map (θ, ν) ↦ ε with no
//! state: its outputs are `initial="calculated"` and depend on its inputs
//! (`<ModelStructure>` says which), fmi2DoStep only advances time, and a
//! master that sets the inputs may read ε at once, before or without a step.
//! Its parameters are `tunable`: gains and targets may change between steps.
//!
//! Same binary as the plant FMU: it tells the two apart by the resource it
//! finds (`resources/controller.json` here, `resources/model.json` there).

use modeldescription as md;
use serde::{Deserialize, Serialize};

use super::{ControlError, ControlLaw, ControlParameters, Objective};
use crate::export::{
    ExportError, RealVariable, VariableOf, default_experiment, description, every_variable, guid_of, is_c_identifier,
    log_categories, numbered_blocks, variable_at, write_archive,
};
use crate::model::{LinkJoint, Model};
use std::path::Path;

/// Version of the controller resource layout ([`ControllerResource`]).
pub const CONTROLLER_RESOURCE_FORMAT: u32 = 1;

/// Path of the controller resource inside the FMU archive.
pub const CONTROLLER_RESOURCE_PATH: &str = "resources/controller.json";

/// `resources/controller.json`: what the controller FMU loads.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ControllerResource {
    /// [`CONTROLLER_RESOURCE_FORMAT`] of the writer.
    pub format: u32,
    /// The control law.
    pub law: ControlLaw,
    /// The compiled vehicle.
    pub model: Model,
}

/// One Real variable of the controller FMU; indices 0-based (1-based in names).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ControllerVariable {
    /// Parameter `c1[k+1]`: rate gain of dof k.
    RateGain(usize),
    /// Parameter `c2[k+1]`: gain of controlled quantity k.
    TargetGain(usize),
    /// Parameter `target[k+1]` (joint targets) or `target_position[1..3]`,
    /// `target_quaternion[1..4]` (pose target: k = 0..7).
    Target(usize),
    /// Input `theta[k+1]`.
    Theta(usize),
    /// Input `nu[k+1]`.
    Nu(usize),
    /// Output `eps[k+1]`.
    Eps(usize),
    /// Output `potential`: U = ½ ΔYᵀ c₂ ΔY.
    Potential,
    /// Output `target_error[k+1]`: ΔY = Ŷ − Y.
    TargetError(usize),
}

/// The controller's Real variables and value references: consecutive blocks
/// from 1 in the order c1, c2, target, theta, nu, eps, potential, target_error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ControllerLayout {
    /// Number of position coordinates.
    pub nq: usize,
    /// Number of dofs.
    pub nv: usize,
    /// Number of controlled quantities.
    pub ny: usize,
    /// Number of target values.
    pub target_len: usize,
    /// Whether the target is a pose (names target_position, target_quaternion).
    pub pose: bool,
}

impl ControllerLayout {
    /// The layout of the controller of `model` with `law`.
    pub fn new(model: &Model, law: &ControlLaw) -> Self {
        ControllerLayout {
            nq: model.nq,
            nv: model.nv,
            ny: law.ny(),
            target_len: law.target_len(),
            pose: matches!(law.objective, Objective::Pose(_)),
        }
    }

    fn blocks(&self) -> impl Iterator<Item = (u32, usize, VariableOf<ControllerVariable>)> {
        let blocks: [(usize, VariableOf<ControllerVariable>); 8] = [
            (self.nv, ControllerVariable::RateGain),
            (self.ny, ControllerVariable::TargetGain),
            (self.target_len, ControllerVariable::Target),
            (self.nq, ControllerVariable::Theta),
            (self.nv, ControllerVariable::Nu),
            (self.nv, ControllerVariable::Eps),
            (1, |_| ControllerVariable::Potential),
            (self.ny, ControllerVariable::TargetError),
        ];
        numbered_blocks(1, blocks)
    }

    /// The variable with value reference `vr`, if any.
    pub fn variable(&self, vr: u32) -> Option<ControllerVariable> {
        variable_at(self.blocks(), vr)
    }

    /// All Real variables with their value references, in order.
    pub fn variables(&self) -> impl Iterator<Item = (u32, ControllerVariable)> {
        every_variable(self.blocks())
    }

    /// The structured, 1-based name of `variable`.
    pub fn name(&self, variable: ControllerVariable) -> String {
        match variable {
            ControllerVariable::RateGain(k) => format!("c1[{}]", k + 1),
            ControllerVariable::TargetGain(k) => format!("c2[{}]", k + 1),
            ControllerVariable::Target(k) if self.pose && k < 3 => format!("target_position[{}]", k + 1),
            ControllerVariable::Target(k) if self.pose => format!("target_quaternion[{}]", k - 2),
            ControllerVariable::Target(k) => format!("target[{}]", k + 1),
            ControllerVariable::Theta(k) => format!("theta[{}]", k + 1),
            ControllerVariable::Nu(k) => format!("nu[{}]", k + 1),
            ControllerVariable::Eps(k) => format!("eps[{}]", k + 1),
            ControllerVariable::Potential => "potential".into(),
            ControllerVariable::TargetError(k) => format!("target_error[{}]", k + 1),
        }
    }
}

/// The controller FMU's GUID (see [`crate::export::guid`]).
pub fn controller_guid(resource_json: &[u8], layout: &ControllerLayout) -> String {
    guid_of(resource_json, layout.variables().map(|(vr, v)| (vr, layout.name(v))))
}

/// What controlled quantity k is, and its unit, for descriptions.
fn quantity(model: &Model, law: &ControlLaw, k: usize) -> (String, &'static str, &'static str) {
    const AXES: [&str; 3] = ["x", "y", "z"];
    match &law.objective {
        Objective::Joints(joints) => {
            let joint = &joints[k];
            let slide = model.links.iter().any(|l| l.qpos_adr == joint.qpos_adr && l.joint == LinkJoint::Slide);
            let (kind, unit, gain_unit) = if slide { ("slide", "m", "N/m") } else { ("hinge", "rad", "N*m/rad") };
            (format!("{kind} joint '{}'", joint.name), unit, gain_unit)
        }
        Objective::Pose(frame) if k < 3 => {
            (format!("position {} of body '{}' in world", AXES[k], frame.body), "m", "N/m")
        }
        Objective::Pose(frame) => (
            format!("rotation of body '{}' about the target frame's {} axis", frame.body, AXES[k - 3]),
            "rad",
            "N*m/rad",
        ),
    }
}

/// The description of `variable` in modelDescription.xml.
fn controller_description(model: &Model, law: &ControlLaw, variable: ControllerVariable) -> String {
    const QUATERNION: [&str; 4] = ["w", "x", "y", "z"];
    match variable {
        ControllerVariable::RateGain(k) => format!("rate gain c1 of dof {} (1/s): eps[{0}] = -c1[{0}] nu[{0}] + ...", k + 1),
        ControllerVariable::TargetGain(k) => {
            let (what, _, unit) = quantity(model, law, k);
            format!("gain c2 on the error of the {what} ({unit})")
        }
        ControllerVariable::Target(k) => match &law.objective {
            Objective::Pose(frame) if k < 3 => {
                format!("target position {} of body '{}' in world (m)", ["x", "y", "z"][k], frame.body)
            }
            Objective::Pose(frame) => format!(
                "target orientation of body '{}', quaternion {} (body to world; normalized when used) (1)",
                frame.body,
                QUATERNION[k - 3]
            ),
            Objective::Joints(_) => {
                let (what, unit, _) = quantity(model, law, k);
                format!("target of the {what} ({unit})")
            }
        },
        ControllerVariable::Theta(k) => format!("input: {}", description(model, RealVariable::Theta(k))),
        ControllerVariable::Nu(k) => format!("input: {}", description(model, RealVariable::Nu(k))),
        ControllerVariable::Eps(k) => {
            format!("output: {} = -c1 nu + l J^T c2 (Yhat - Y)", description(model, RealVariable::Eps(k)))
        }
        ControllerVariable::Potential => "potential 1/2 sum c2 (Yhat - Y)^2 of the configuration term (J)".into(),
        ControllerVariable::TargetError(k) => {
            let (what, unit, _) = quantity(model, law, k);
            match &law.objective {
                Objective::Pose(_) if k >= 3 => {
                    format!("error Yhat - Y = -phi, phi = log(Rhat^T R): {what} relative to the target ({unit})")
                }
                _ => format!("error Yhat - Y of the {what} ({unit})"),
            }
        }
    }
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
        .variables()
        .map(|(vr, variable)| {
            use md::{Causality::*, Initial::*, Variability::*};
            let (causality, variability, initial, start, min) = match variable {
                ControllerVariable::RateGain(k) => (Parameter, Tunable, Some(Exact), Some(defaults.c1[k]), Some(0.0)),
                ControllerVariable::TargetGain(k) => (Parameter, Tunable, Some(Exact), Some(defaults.c2[k]), Some(0.0)),
                ControllerVariable::Target(k) => (Parameter, Tunable, Some(Exact), Some(defaults.target[k]), None),
                ControllerVariable::Theta(k) => (Input, Continuous, None, Some(model.qpos0[k]), None),
                ControllerVariable::Nu(_) => (Input, Continuous, None, Some(0.0), None),
                _ => (Output, Continuous, Some(Calculated), None, None),
            };
            md::ScalarVariable {
                name: layout.name(variable),
                value_reference: vr,
                description: Some(controller_description(model, law, variable)),
                causality,
                variability,
                initial,
                can_handle_multiple_set_per_time_instant: None,
                kind: md::VariableKind::Real(md::RealVariable { start, min, ..Default::default() }),
            }
        })
        .collect();

    // Value references start at 1 in variable order, so index = vr.
    let indices = |pick: fn(&ControllerVariable) -> bool| -> Vec<u32> {
        layout.variables().filter(|(_, v)| pick(v)).map(|(vr, _)| vr).collect()
    };
    let theta = indices(|v| matches!(v, ControllerVariable::Theta(_)));
    let theta_and_nu = indices(|v| matches!(v, ControllerVariable::Theta(_) | ControllerVariable::Nu(_)));
    let mut outputs = Vec::new();
    let mut initial_unknowns = Vec::new();
    for (vr, variable) in layout.variables() {
        let dependencies = match variable {
            ControllerVariable::Eps(_) => theta_and_nu.clone(),
            ControllerVariable::Potential | ControllerVariable::TargetError(_) => theta.clone(),
            _ => continue,
        };
        outputs.push(md::Unknown { index: vr, dependencies: Some(dependencies), dependencies_kind: None });
        initial_unknowns.push(md::Unknown::new(vr));
    }
    let target = match &law.objective {
        Objective::Joints(joints) => format!("the {} hinge and slide joint values", joints.len()),
        Objective::Pose(frame) => format!("the pose of body '{}'", frame.body),
    };

    md::FmiModelDescription {
        fmi_version: md::FmiVersion::Fmi2,
        model_name: format!("{}_controller", if model.name.is_empty() { model_identifier } else { &model.name }),
        guid: guid.to_string(),
        description: Some(format!(
            "noninteracting controller of the vehicle '{}' (nq = {}, nv = {}): \
             eps = -c1 nu + l(theta) J^T(theta) c2 (Yhat - Y(theta)), Y = {target}",
            model.name, model.nq, model.nv
        )),
        author: None,
        version: None,
        copyright: None,
        license: None,
        generation_tool: Some(format!("nudyn {}", env!("CARGO_PKG_VERSION"))),
        generation_date_and_time: None,
        variable_naming_convention: Some(md::VariableNamingConvention::Structured),
        number_of_event_indicators: None,
        co_simulation: md::CoSimulation {
            model_identifier: model_identifier.to_string(),
            needs_execution_tool: false,
            can_handle_variable_communication_step_size: true,
            can_interpolate_inputs: false,
            max_output_derivative_order: 0,
            can_run_asynchronuously: false,
            can_be_instantiated_only_once_per_process: false,
            can_not_use_memory_management_functions: true,
            // Nothing to save: the outputs are a function of inputs and parameters.
            can_get_and_set_fmu_state: false,
            can_serialize_fmu_state: false,
            provides_directional_derivative: false,
        },
        unit_definitions: Vec::new(),
        type_definitions: Vec::new(),
        log_categories: log_categories(),
        default_experiment: Some(default_experiment()),
        model_variables,
        model_structure: md::ModelStructure { outputs, derivatives: Vec::new(), initial_unknowns },
    }
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

/// The controller resource's bytes.
pub fn controller_resource_json(model: &Model, law: &ControlLaw) -> Result<Vec<u8>, ExportError> {
    let resource = ControllerResource { format: CONTROLLER_RESOURCE_FORMAT, law: law.clone(), model: model.clone() };
    Ok(serde_json::to_vec(&resource)?)
}

/// Writes the controller FMU `out` for `model` with `law`; `binary` is the
/// `nudyn_fmu` cdylib, as for the plant.
pub fn write_controller_fmu(
    model: &Model,
    law: &ControlLaw,
    model_identifier: &str,
    binary: &Path,
    out: &Path,
) -> Result<(), ControllerExportError> {
    if !is_c_identifier(model_identifier) {
        return Err(ExportError::ModelIdentifier(model_identifier.to_string()).into());
    }
    let defaults = law.default_parameters(model)?;
    let resource = controller_resource_json(model, law)?;
    let guid = controller_guid(&resource, &ControllerLayout::new(model, law));
    let description = controller_model_description(model, law, &defaults, model_identifier, &guid);
    write_archive(&description, (CONTROLLER_RESOURCE_PATH, &resource), binary, out)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_references_are_consecutive_and_decode() {
        let layout = ControllerLayout { nq: 14, nv: 13, ny: 6, target_len: 7, pose: true };
        let all: Vec<(u32, ControllerVariable)> = layout.variables().collect();
        assert_eq!(all.len(), 13 + 6 + 7 + 14 + 13 + 13 + 1 + 6);
        for (k, &(vr, variable)) in all.iter().enumerate() {
            assert_eq!(vr, k as u32 + 1);
            assert_eq!(layout.variable(vr), Some(variable));
        }
        assert_eq!(layout.variable(0), None);
        assert_eq!(layout.variable(all.len() as u32 + 1), None);
        let names: Vec<String> = all.iter().map(|&(_, v)| layout.name(v)).collect();
        for name in ["c1[13]", "c2[6]", "target_position[3]", "target_quaternion[1]", "target_quaternion[4]", "theta[14]", "nu[1]", "eps[13]", "potential", "target_error[6]"] {
            assert!(names.iter().any(|n| n == name), "{name} missing from {names:?}");
        }
        let joints = ControllerLayout { nq: 4, nv: 4, ny: 3, target_len: 3, pose: false };
        assert_eq!(joints.name(ControllerVariable::Target(2)), "target[3]");
    }
}
