//! The controller: the noninteracting control law of `nudyn::control` as
//! an FMU component (`nudyn export --controller`), a direct-feedthrough map
//! from its inputs (θ, ν) to its output ε with tunable gains and targets.
//! It has no state: fmi2DoStep only advances time, and the outputs are
//! computed when read after any change of inputs or parameters.

use nudyn::control::{ControlError, ControlLaw, ControlParameters, ControlWorkspace};
use nudyn::model::{LinkJoint, Model};
use nudyn_contract::capabilities::Capabilities;
use nudyn_contract::controller::{CAPABILITIES, ControllerLayout, ControllerResource, ControllerVariable};
use nudyn_contract::variable::Kind;

use crate::component::{CallError, Component, StepError, StepReport, Variable};

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
    /// θ as the law reads it: a zero quaternion as the identity.
    theta_read: Vec<f64>,
    /// Input ν (nv).
    nu: Vec<f64>,
    time: f64,
    stop_time: Option<f64>,
    /// Whether `cws` holds the law at the current inputs and parameters.
    evaluated: bool,
}

impl Controller {
    /// Why the resource's law does not fit its model, if it does not (a
    /// hand-edited resource): checked before anything is sized by it.
    pub fn law_mismatch(resource: &ControllerResource) -> Option<String> {
        resource.law.mismatch(&resource.model)
    }

    /// The controller of a resource whose law fits its model ([`Controller::law_mismatch`]).
    pub fn new(resource: ControllerResource) -> Result<Controller, ControlError> {
        let layout = resource.layout();
        let ControllerResource { law, model, .. } = resource;
        let defaults = law.default_parameters(&model)?;
        Ok(Controller {
            cws: ControlWorkspace::new(&model, &law),
            parameters: defaults.clone(),
            defaults,
            theta: model.qpos0.clone(),
            theta_read: model.qpos0.clone(),
            nu: vec![0.0; model.nv],
            time: 0.0,
            stop_time: None,
            evaluated: false,
            layout,
            model,
            law,
        })
    }

    fn variable(&self, vr: u32) -> ControllerVariable {
        self.layout.variable(vr).expect("checked by the caller")
    }

    /// Copies θ into `theta_read`, a quaternion of zeros as the identity
    /// (MuJoCo's reading of one): a master that starts its connections at 0
    /// (FMPy's SSP runner) hands the controller such a θ before the plant's
    /// first output reaches it. Returns the warning that says so.
    fn read_theta(&mut self) -> Option<String> {
        self.theta_read.copy_from_slice(&self.theta);
        let mut zero = Vec::new();
        // A free joint's rotation is a ball link of its own.
        for link in self.model.links.iter().filter(|link| link.joint == LinkJoint::Ball) {
            let start = link.qpos_adr;
            let quaternion = &mut self.theta_read[start..start + 4];
            if quaternion.iter().all(|&c| c == 0.0) {
                quaternion.copy_from_slice(&[1.0, 0.0, 0.0, 0.0]);
                zero.push(format!("theta[{}] to theta[{}] (joint '{}')", start + 1, start + 4, link.joint_name));
            }
        }
        let verb = if zero.len() == 1 { "is" } else { "are each" };
        (!zero.is_empty())
            .then(|| format!("{} {verb} a zero quaternion, read as the identity as MuJoCo reads one", zero.join(", ")))
    }
}

impl Component for Controller {
    fn capabilities(&self) -> Capabilities {
        CAPABILITIES
    }

    fn reset(&mut self) {
        self.parameters.clone_from(&self.defaults);
        self.theta.clone_from(&self.model.qpos0);
        self.nu.fill(0.0);
        self.time = 0.0;
        self.stop_time = None;
        self.evaluated = false;
    }

    fn time(&self) -> f64 {
        self.time
    }

    fn stop_time(&self) -> Option<f64> {
        self.stop_time
    }

    /// The start time becomes the current time; the tolerance has no use here.
    fn setup_experiment(&mut self, _tolerance: Option<f64>, start_time: f64, stop_time: Option<f64>) {
        self.time = start_time;
        self.stop_time = stop_time;
    }

    /// The parameters must make a law (a target quaternion set to zero is
    /// refused here, not at the first output).
    fn initialize(&mut self) -> Result<Option<String>, CallError> {
        self.parameters.check(&self.model, &self.law).map_err(CallError::Control)?;
        Ok(None)
    }

    fn dependencies(&self, vr: u32) -> Option<Vec<u32>> {
        self.layout.dependency_vrs(vr)
    }

    fn real_variable(&self, vr: u32) -> Option<Variable> {
        self.layout.element(vr).map(|e| Variable { name: e.name(), kind: e.kind() })
    }

    fn real_kind(&self, vr: u32) -> Option<Kind> {
        self.layout.element(vr).map(|e| e.kind())
    }

    fn set_reals(&mut self, vrs: &[u32], values: &[f64]) {
        for (&vr, &value) in vrs.iter().zip(values) {
            match self.variable(vr) {
                ControllerVariable::RateGain(k) => self.parameters.c1[k] = value,
                ControllerVariable::TargetGain(k) => self.parameters.c2[k] = value,
                ControllerVariable::Target(k) => self.parameters.target[k] = value,
                ControllerVariable::Theta(k) => self.theta[k] = value,
                ControllerVariable::Nu(k) => self.nu[k] = value,
                variable => unreachable!("{variable:?} is a calculated output: the caller refuses it"),
            }
        }
        self.evaluated = false;
    }

    /// Outputs are the law at the current inputs and parameters (direct
    /// feedthrough: no step needed after fmi2SetReal).
    fn prepare_reals(&mut self, vrs: &[u32]) -> Result<Option<String>, CallError> {
        let needs_outputs = vrs.iter().any(|&vr| {
            matches!(
                self.variable(vr),
                ControllerVariable::Eps(_) | ControllerVariable::Potential | ControllerVariable::TargetError(_)
            )
        });
        let mut warning = None;
        if needs_outputs && !self.evaluated {
            self.parameters.check(&self.model, &self.law).map_err(CallError::Control)?;
            warning = self.read_theta();
            self.cws
                .evaluate(&self.model, &self.law, &self.parameters, &self.theta_read, &self.nu)
                .map_err(CallError::Control)?;
            self.evaluated = true;
        }
        Ok(warning)
    }

    fn real_value(&self, vr: u32) -> f64 {
        match self.variable(vr) {
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

    /// Time advances; the outputs stay the law at the current inputs.
    fn do_step(&mut self, time: f64, step: f64) -> Result<Option<StepReport>, StepError> {
        self.time = time + step;
        Ok(None)
    }
}
