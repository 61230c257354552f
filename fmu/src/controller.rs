//! The safe slave of a controller FMU (`nudyn export --controller`): the
//! noninteracting control law of `nudyn::control` as a direct-feedthrough
//! map from its inputs (θ, ν) to its output ε, with tunable gains and
//! targets. It has no state: fmi2DoStep only advances time, and the outputs
//! are computed when read after any change of inputs or parameters.
//!
//! As in the plant slave, every method checks all its arguments before
//! changing anything, so a refused call leaves the slave as it was.

use std::path::{Path, PathBuf};

use nudyn::control::export::{
    CONTROLLER_RESOURCE_FORMAT, ControllerLayout, ControllerResource, ControllerVariable, controller_guid,
};
use nudyn::control::{ControlLaw, ControlParameters, ControlWorkspace, Objective};
use nudyn::model::{LinkJoint, Model};

use crate::resource::check_model;
use crate::slave::{SlaveError, check_communication_step, check_experiment};

/// File name of the controller resource in the resources directory.
pub const CONTROLLER_RESOURCE_FILE: &str = "controller.json";

/// Why a law does not fit its model, if it does not (a corrupted or
/// hand-edited resource must be refused at instantiation, not crash later).
fn law_problem(model: &Model, law: &ControlLaw) -> Option<String> {
    match &law.objective {
        Objective::Joints(joints) if joints.is_empty() => Some("no joint has a target".into()),
        Objective::Joints(joints) => joints.iter().find_map(|joint| {
            let fits = model.links.iter().any(|l| {
                l.qpos_adr == joint.qpos_adr
                    && l.dof_adr == joint.dof_adr
                    && matches!(l.joint, LinkJoint::Hinge | LinkJoint::Slide)
            });
            (!fits).then(|| format!("joint '{}' is not a hinge or slide of the model", joint.name))
        }),
        Objective::Pose(frame) if frame.link >= model.links.len() => {
            Some(format!("body '{}' is on link {}, the model has {}", frame.body, frame.link, model.links.len()))
        }
        Objective::Pose(frame) => {
            let numbers = frame.offset.rot.iter().chain(frame.offset.trans.iter());
            numbers.clone().any(|x| !x.is_finite()).then(|| format!("body '{}' has a non-finite offset", frame.body))
        }
    }
}

/// One controller instance.
pub struct Controller {
    model: Model,
    law: ControlLaw,
    layout: ControllerLayout,
    cws: ControlWorkspace,
    /// The parameters' start values (fmi2Reset returns to them).
    defaults: ControlParameters,
    parameters: ControlParameters,
    /// Input θ (nq).
    theta: Vec<f64>,
    /// Input ν (nv).
    nu: Vec<f64>,
    time: f64,
    stop_time: Option<f64>,
    /// Whether `cws` holds the law at the current inputs and parameters.
    evaluated: bool,
}

impl Controller {
    /// Loads `controller.json` from the resources directory `directory` and
    /// checks `guid` against it.
    pub fn load(directory: &Path, guid: &str) -> Result<Controller, SlaveError> {
        let path: PathBuf = directory.join(CONTROLLER_RESOURCE_FILE);
        let bytes = std::fs::read(&path).map_err(|source| SlaveError::ReadResource { path: path.clone(), source })?;
        let resource: ControllerResource =
            serde_json::from_slice(&bytes).map_err(|source| SlaveError::ParseResource { path: path.clone(), source })?;
        if resource.format != CONTROLLER_RESOURCE_FORMAT {
            return Err(SlaveError::ResourceFormat { path, found: resource.format });
        }
        check_model(&resource.model).map_err(|source| SlaveError::BadModel { path: path.clone(), source })?;
        let ControllerResource { law, model, .. } = resource;
        if let Some(reason) = law_problem(&model, &law) {
            return Err(SlaveError::BadLaw { path, reason });
        }
        let layout = ControllerLayout::new(&model, &law);
        let actual = controller_guid(&bytes, &layout);
        if actual != guid {
            return Err(SlaveError::Guid { given: guid.to_string(), actual });
        }
        let defaults = law.default_parameters(&model).map_err(SlaveError::Control)?;
        Ok(Controller {
            cws: ControlWorkspace::new(&model, &law),
            parameters: defaults.clone(),
            defaults,
            theta: model.qpos0.clone(),
            nu: vec![0.0; model.nv],
            time: 0.0,
            stop_time: None,
            evaluated: false,
            layout,
            model,
            law,
        })
    }

    /// Back to the state just after loading (fmi2Reset).
    pub fn reset(&mut self) {
        self.parameters.clone_from(&self.defaults);
        self.theta.clone_from(&self.model.qpos0);
        self.nu.fill(0.0);
        self.time = 0.0;
        self.stop_time = None;
        self.evaluated = false;
    }

    /// fmi2SetupExperiment: the start time becomes the current time. The
    /// tolerance has no use here but is checked like the plant's.
    pub fn setup_experiment(&mut self, tolerance: Option<f64>, start_time: f64, stop_time: Option<f64>) -> Result<(), SlaveError> {
        check_experiment(tolerance, start_time, stop_time)?;
        self.time = start_time;
        self.stop_time = stop_time;
        Ok(())
    }

    /// fmi2ExitInitializationMode: the parameters must make a law (a target
    /// quaternion set to zero is refused here, not at the first output).
    pub fn initialize(&mut self) -> Result<(), SlaveError> {
        self.parameters.check(&self.model, &self.law).map_err(SlaveError::Control)
    }

    fn variable(&self, vr: u32) -> Result<ControllerVariable, SlaveError> {
        self.layout.variable(vr).ok_or(SlaveError::UnknownValueReference { vr, kind: "Real" })
    }

    /// fmi2SetReal: parameters (tunable) and inputs, at any time the state
    /// machine allows; outputs never. NaN and ±Inf are out of range
    /// (fmi2Discard), and so are negative gains.
    pub fn set_real(&mut self, vrs: &[u32], values: &[f64]) -> Result<(), SlaveError> {
        for (&vr, &value) in vrs.iter().zip(values) {
            let variable = self.variable(vr)?;
            let name = || self.layout.name(variable);
            if matches!(variable, ControllerVariable::Eps(_) | ControllerVariable::Potential | ControllerVariable::TargetError(_)) {
                return Err(SlaveError::NotSettable { name: name(), vr, when: "at all: it is a calculated output" });
            }
            if !value.is_finite() {
                return Err(SlaveError::NonFinite { name: name(), value });
            }
            if matches!(variable, ControllerVariable::RateGain(_) | ControllerVariable::TargetGain(_)) && value < 0.0 {
                return Err(SlaveError::Negative { name: name(), value });
            }
        }
        for (&vr, &value) in vrs.iter().zip(values) {
            match self.layout.variable(vr).expect("checked above") {
                ControllerVariable::RateGain(k) => self.parameters.c1[k] = value,
                ControllerVariable::TargetGain(k) => self.parameters.c2[k] = value,
                ControllerVariable::Target(k) => self.parameters.target[k] = value,
                ControllerVariable::Theta(k) => self.theta[k] = value,
                ControllerVariable::Nu(k) => self.nu[k] = value,
                _ => unreachable!("outputs are refused above"),
            }
        }
        self.evaluated = false;
        Ok(())
    }

    /// fmi2GetReal. Outputs are the law at the current inputs and
    /// parameters (direct feedthrough: no step needed after fmi2SetReal).
    pub fn get_real(&mut self, vrs: &[u32], values: &mut [f64]) -> Result<(), SlaveError> {
        let mut needs_outputs = false;
        for &vr in vrs {
            let variable = self.variable(vr)?;
            needs_outputs |= matches!(
                variable,
                ControllerVariable::Eps(_) | ControllerVariable::Potential | ControllerVariable::TargetError(_)
            );
        }
        if needs_outputs && !self.evaluated {
            self.parameters.check(&self.model, &self.law).map_err(SlaveError::Control)?;
            self.cws
                .evaluate(&self.model, &self.law, &self.parameters, &self.theta, &self.nu)
                .map_err(SlaveError::Control)?;
            self.evaluated = true;
        }
        // As in the plant: an output that overflowed is refused, never handed out.
        if let Some(&vr) = vrs.iter().find(|&&vr| !self.value(vr).is_finite()) {
            let name = self.layout.name(self.variable(vr)?);
            return Err(SlaveError::NonFiniteOutput { name, value: self.value(vr) });
        }
        for (value, &vr) in values.iter_mut().zip(vrs) {
            *value = self.value(vr);
        }
        Ok(())
    }

    /// The value of variable `vr` (known to exist; outputs evaluated).
    fn value(&self, vr: u32) -> f64 {
        match self.layout.variable(vr).expect("checked by the caller") {
            ControllerVariable::RateGain(k) => self.parameters.c1[k],
            ControllerVariable::TargetGain(k) => self.parameters.c2[k],
            ControllerVariable::Target(k) => self.parameters.target[k],
            ControllerVariable::Theta(k) => self.theta[k],
            ControllerVariable::Nu(k) => self.nu[k],
            ControllerVariable::Eps(k) => self.cws.eps[k],
            ControllerVariable::Potential => self.cws.potential,
            ControllerVariable::TargetError(k) => self.cws.error[k],
        }
    }

    /// fmi2SetRealInputDerivatives: canInterpolateInputs="false".
    pub fn set_input_derivatives(&mut self, vrs: &[u32]) -> Result<(), SlaveError> {
        self.no_derivative(vrs, "input")
    }

    /// fmi2GetRealOutputDerivatives: maxOutputDerivativeOrder="0".
    pub fn get_output_derivatives(&mut self, vrs: &[u32]) -> Result<(), SlaveError> {
        self.no_derivative(vrs, "output")
    }

    /// Refuses derivatives of the variables `vrs` (an empty list is no call).
    fn no_derivative(&self, vrs: &[u32], what: &'static str) -> Result<(), SlaveError> {
        match vrs.first() {
            Some(&vr) => {
                let name = self.layout.name(self.variable(vr)?);
                Err(SlaveError::NoDerivative { name, vr, what })
            }
            None => Ok(()),
        }
    }

    /// Refuses a non-finite communication point (no tolerance compares it).
    pub fn check_step_arguments(&self, time: f64) -> Result<(), SlaveError> {
        if !time.is_finite() {
            return Err(SlaveError::CommunicationPoint { expected: self.time, found: time });
        }
        Ok(())
    }

    /// fmi2DoStep: the same checks as the plant's; then time advances. The
    /// outputs stay the law at the current inputs.
    pub fn do_step(&mut self, time: f64, step: f64) -> Result<(), SlaveError> {
        check_communication_step(self.time, self.stop_time, time, step)?;
        self.time = time + step;
        Ok(())
    }

    /// The current time (fmi2LastSuccessfulTime).
    pub fn time(&self) -> f64 {
        self.time
    }
}
