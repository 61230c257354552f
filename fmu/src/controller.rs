//! The controller: the noninteracting control law of `nudyn::control` as
//! an FMU component (`nudyn export --controller`), a direct-feedthrough map
//! from its inputs (θ, ν) to its output ε with tunable gains and targets.
//! It has no state: fmi2DoStep only advances time, and the outputs are
//! computed when read after any change of inputs or parameters.

use std::path::Path;

use nudyn::control::{ControlLaw, ControlParameters, ControlWorkspace};
use nudyn::model::Model;
use nudyn_contract::capabilities::Capabilities;
use nudyn_contract::controller::{CAPABILITIES, ControllerLayout, ControllerResource, ControllerVariable};

use crate::component::{CallError, Component, LoadError, Loaded, StepError, StepReport, Variable};

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
    /// Refuses a law that does not fit its model (a corrupted or
    /// hand-edited resource), before anything is sized by it.
    pub fn check_law(resource: &ControllerResource, path: &Path) -> Result<(), LoadError> {
        match resource.law.mismatch(&resource.model) {
            Some(reason) => Err(LoadError::BadLaw { path: path.to_path_buf(), reason }),
            None => Ok(()),
        }
    }

    /// The controller of a loaded resource (checked with [`Controller::check_law`]).
    pub fn load(loaded: Loaded<ControllerResource>) -> Result<Controller, LoadError> {
        let Loaded { resource, path, .. } = loaded;
        let layout = resource.layout();
        let ControllerResource { law, model, .. } = resource;
        let defaults = law.default_parameters(&model).map_err(|e| LoadError::BadLaw { path, reason: e.to_string() })?;
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

    fn variable(&self, vr: u32) -> ControllerVariable {
        self.layout.variable(vr).expect("checked by the caller")
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
    fn initialize(&mut self) -> Result<(), CallError> {
        self.parameters.check(&self.model, &self.law).map_err(CallError::Control)
    }

    fn dependencies(&self, vr: u32) -> Option<Vec<u32>> {
        self.layout.dependency_vrs(vr)
    }

    fn real_variable(&self, vr: u32) -> Option<Variable> {
        self.layout.variable(vr).map(|v| Variable { name: self.layout.name(v), kind: v.kind() })
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
    fn prepare_reals(&mut self, vrs: &[u32]) -> Result<(), CallError> {
        let needs_outputs = vrs.iter().any(|&vr| {
            matches!(
                self.variable(vr),
                ControllerVariable::Eps(_) | ControllerVariable::Potential | ControllerVariable::TargetError(_)
            )
        });
        if needs_outputs && !self.evaluated {
            self.parameters.check(&self.model, &self.law).map_err(CallError::Control)?;
            self.cws
                .evaluate(&self.model, &self.law, &self.parameters, &self.theta, &self.nu)
                .map_err(CallError::Control)?;
            self.evaluated = true;
        }
        Ok(())
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
