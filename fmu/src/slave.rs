//! The safe co-simulation slave behind the FMI layer: loads the compiled
//! model from the FMU's resources, holds the state (θ, ν), the inputs ε
//! and the parameters, and advances them with the core integrator.
//!
//! Every method checks all its arguments before changing anything, so a
//! rejected call leaves the slave as it was. Outputs beyond θ and ν are
//! computed when first read after a change of state, so outputs nobody
//! reads cost nothing.

use std::path::{Path, PathBuf};

use nudyn::dynamics::DynamicsError;
use nudyn::export::{
    DEFAULT_MAX_STEP, DEFAULT_METHOD, DEFAULT_TOLERANCE, ENERGY_PROJECTION_VR, FmuResource, Layout, METHOD_VR,
    RESOURCE_FORMAT, RealVariable, method_of_value, method_value,
};
use nudyn::dynamics::quantities::kinetic_energy;
use nudyn::integrate::{AdvanceError, Carry, Integrator, Method, Settings, Stats, ToleranceRelaxed};
use nudyn::model::{LinkJoint, Model};
use nudyn::workspace::Workspace;

use crate::resource::{ResourceError, check_model};
use crate::snapshot::{Snapshot, SnapshotError};
use crate::state::Phase;
use crate::uri::{UriError, resource_directory};

/// Relative tolerance on currentCommunicationPoint against the slave's time:
/// masters compute communication points in their own way (FMPy: start + n·h).
const TIME_TOLERANCE: f64 = 1e-9;

/// The most internal steps of `max_step` one doStep may ask for: more would
/// keep the host busy for hours (1e300 s, or `max_step` = 1e-300, forever),
/// so such a step is refused up front.
const MAX_INTERNAL_STEPS: f64 = 1e6;

/// The values that determine the slave's future: what an FMU state saves.
#[derive(Clone, Debug, PartialEq)]
pub struct SlaveState {
    /// Current time (s).
    pub time: f64,
    /// Start time of the experiment (s).
    pub start_time: f64,
    /// Stop time, if the master declared one (s).
    pub stop_time: Option<f64>,
    /// Parameter `tolerance`.
    pub tolerance: f64,
    /// Parameter `max_step` (s).
    pub max_step: f64,
    /// Parameter `method`.
    pub method: Method,
    /// Parameter `energy_projection`.
    pub energy_projection: bool,
    /// The integrator's proposed next step and accumulated work.
    pub carry: Carry,
    /// K = ½|ν|² at initialization (J), for the energy residual.
    pub initial_energy: f64,
    /// θ (nq, qpos).
    pub theta: Vec<f64>,
    /// ν (nv).
    pub nu: Vec<f64>,
    /// The inputs ε (nv) as set at the current communication point.
    pub eps: Vec<f64>,
    /// dε/dt (nv) from fmi2SetRealInputDerivatives, for the next step only.
    pub eps_rate: Vec<f64>,
}

impl SlaveState {
    /// The state just after instantiation: qpos0, at rest, no input.
    fn initial(model: &Model) -> Self {
        SlaveState {
            time: 0.0,
            start_time: 0.0,
            stop_time: None,
            tolerance: DEFAULT_TOLERANCE,
            max_step: DEFAULT_MAX_STEP,
            method: DEFAULT_METHOD,
            energy_projection: false,
            carry: Carry::default(),
            initial_energy: 0.0,
            theta: model.qpos0.clone(),
            nu: vec![0.0; model.nv],
            eps: vec![0.0; model.nv],
            eps_rate: vec![0.0; model.nv],
        }
    }
}

/// Refuses fmi2SetupExperiment arguments no run can use: a non-finite
/// start, a tolerance that is not positive, a stop time before the start.
pub fn check_experiment(tolerance: Option<f64>, start_time: f64, stop_time: Option<f64>) -> Result<(), SlaveError> {
    if !start_time.is_finite() {
        return Err(SlaveError::NonFinite { name: "startTime".into(), value: start_time });
    }
    if let Some(tolerance) = tolerance.filter(|t| !(t.is_finite() && *t > 0.0)) {
        return Err(SlaveError::NotPositive { name: "tolerance", value: tolerance });
    }
    if let Some(stop) = stop_time.filter(|s| !(s.is_finite() && *s >= start_time)) {
        return Err(SlaveError::NonFinite { name: format!("stopTime (startTime = {start_time})"), value: stop });
    }
    Ok(())
}

/// Refuses an fmi2DoStep from a communication point other than the
/// instance's time `now`, by a step that is not positive and finite, or
/// past the stop time.
pub fn check_communication_step(now: f64, stop_time: Option<f64>, time: f64, step: f64) -> Result<(), SlaveError> {
    if (time - now).abs() > TIME_TOLERANCE * now.abs().max(1.0) {
        return Err(SlaveError::CommunicationPoint { expected: now, found: time });
    }
    if !(step.is_finite() && step > 0.0) {
        return Err(SlaveError::StepSize(step));
    }
    if let Some(stop_time) = stop_time.filter(|&stop| time + step > stop + TIME_TOLERANCE * stop.abs().max(1.0)) {
        return Err(SlaveError::PastStopTime { time, step, stop_time });
    }
    Ok(())
}

/// What a completed fmi2DoStep did.
#[derive(Debug)]
pub struct StepReport {
    /// The internal steps taken and rejected.
    pub stats: Stats,
    /// Set when the tolerance had to be relaxed (fmi2Warning).
    pub relaxed: Option<ToleranceRelaxed>,
}

/// Why a slave call is refused or failed.
#[derive(Debug, thiserror::Error)]
pub enum SlaveError {
    /// The resource location is unusable.
    #[error(transparent)]
    Uri(#[from] UriError),
    /// The compiled model cannot be read.
    #[error("cannot read the compiled model {path}: {source}")]
    ReadResource {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The compiled model cannot be parsed.
    #[error("{path} is not a nudyn FMU resource: {source}")]
    ParseResource {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: serde_json::Error,
    },
    /// Written by an exporter with another resource format.
    #[error("{path} has resource format {found}, this binary reads format {RESOURCE_FORMAT}")]
    ResourceFormat {
        /// The file.
        path: PathBuf,
        /// Its format.
        found: u32,
    },
    /// The compiled model is inconsistent (a corrupted or foreign resource).
    #[error("{path} does not hold a consistent compiled model: {source}")]
    BadModel {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        source: ResourceError,
    },
    /// The GUID passed to fmi2Instantiate is not this FMU's.
    #[error("fmuGUID '{given}' does not match the FMU's resources, whose GUID is '{actual}'")]
    Guid {
        /// The GUID given.
        given: String,
        /// The GUID of the resources.
        actual: String,
    },
    /// No variable of this type has the value reference.
    #[error("unknown value reference {vr} for a variable of type {kind}")]
    UnknownValueReference {
        /// The value reference.
        vr: u32,
        /// The FMI base type asked for.
        kind: &'static str,
    },
    /// The variable cannot be set now.
    #[error("{name} (value reference {vr}) cannot be set {when}")]
    NotSettable {
        /// Variable name.
        name: String,
        /// Its value reference.
        vr: u32,
        /// When it was tried.
        when: &'static str,
    },
    /// A value that must be finite is not.
    #[error("{name} = {value} is not finite")]
    NonFinite {
        /// Variable name.
        name: String,
        /// The value.
        value: f64,
    },
    /// An output that is not finite at the current (finite) state.
    #[error("{name} = {value} is not finite at the current state: no value is returned")]
    NonFiniteOutput {
        /// Variable name.
        name: String,
        /// The value.
        value: f64,
    },
    /// A parameter value outside its range.
    #[error("{name} = {value} must be positive")]
    NotPositive {
        /// Parameter name.
        name: &'static str,
        /// The value.
        value: f64,
    },
    /// A `method` value that is not an item of the enumeration.
    #[error("method = {0} is not an item of the enumeration ({items})", items = method_items())]
    UnknownMethod(i32),
    /// The initial state (θ, ν) set by the master cannot be used.
    #[error("the initial state cannot be used: {0}")]
    InitialState(DynamicsError),
    /// An output could not be evaluated at the current state.
    #[error("the outputs cannot be evaluated at the current state: {0}")]
    Evaluate(DynamicsError),
    /// currentCommunicationPoint is not the slave's time.
    #[error("expected currentCommunicationPoint = {expected} but was {found}")]
    CommunicationPoint {
        /// The slave's time.
        expected: f64,
        /// The argument.
        found: f64,
    },
    /// A step size that is not positive and finite.
    #[error("communicationStepSize = {0} must be positive and finite")]
    StepSize(f64),
    /// The step needs more internal steps than [`MAX_INTERNAL_STEPS`].
    #[error("communicationStepSize = {step} with max_step = {max_step} needs {needed:e} internal steps, more than {MAX_INTERNAL_STEPS:e}")]
    TooLong {
        /// The step.
        step: f64,
        /// The parameter max_step.
        max_step: f64,
        /// step / max_step.
        needed: f64,
    },
    /// The step would pass the declared stop time.
    #[error("the step from t = {time} by {step} passes stopTime = {stop_time}")]
    PastStopTime {
        /// Start of the step.
        time: f64,
        /// Its size.
        step: f64,
        /// The stop time of fmi2SetupExperiment.
        stop_time: f64,
    },
    /// The integration stopped inside the step: the slave stays where it stopped.
    #[error("the step from t = {time} by {step} stopped at t = {reached}: {source}", reached = source.reached())]
    StepFailed {
        /// Start of the step.
        time: f64,
        /// Its size.
        step: f64,
        /// The cause, with the time reached.
        source: AdvanceError,
    },
    /// An input or output derivative of an order other than 1.
    #[error("derivative order {order} of {name} is not supported (only order 1)")]
    DerivativeOrder {
        /// Variable name.
        name: String,
        /// The order asked for.
        order: i32,
    },
    /// A derivative asked of something that is not a theta/nu output or an eps input.
    #[error("{name} (value reference {vr}) has no {what} derivative")]
    NoDerivative {
        /// Variable name.
        name: String,
        /// Its value reference.
        vr: u32,
        /// "input" or "output".
        what: &'static str,
    },
    /// An FMU state that cannot be restored.
    #[error(transparent)]
    Snapshot(#[from] SnapshotError),
    /// A gain that must not be negative.
    #[error("{name} = {value} must be non-negative")]
    Negative {
        /// Variable name.
        name: String,
        /// The value.
        value: f64,
    },
    /// The controller resource holds a law that does not fit its model.
    #[error("{path} does not hold a consistent control law: {reason}")]
    BadLaw {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The control law cannot be evaluated at the current inputs and parameters.
    #[error("the controller cannot be evaluated: {0}")]
    Control(nudyn::control::ControlError),
    /// FMU states asked of an FMU that declares canGetAndSetFMUstate="false".
    #[error("this FMU has no FMU states (canGetAndSetFMUstate=\"false\"): its outputs depend on its inputs and parameters only")]
    NoFmuState,
}

/// "1 = rk4, 2 = dopri5, ...", for messages.
fn method_items() -> String {
    Method::ALL.iter().map(|&m| format!("{} = {}", method_value(m), m.name())).collect::<Vec<_>>().join(", ")
}

impl SlaveError {
    /// Whether the failure is fmi2Discard (the step failed, the instance is
    /// intact) rather than fmi2Error.
    pub fn is_discard(&self) -> bool {
        matches!(self, SlaveError::StepFailed { .. })
    }

    /// Whether a value was refused for being outside its range (not finite,
    /// not positive, not an enumeration item): fmi2Discard from fmi2SetXXX.
    pub fn is_out_of_range(&self) -> bool {
        matches!(
            self,
            SlaveError::NonFinite { .. }
                | SlaveError::NotPositive { .. }
                | SlaveError::Negative { .. }
                | SlaveError::UnknownMethod(_)
        )
    }
}

/// How far the workspace holds the passes for the current (θ, ν, ε).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Evaluated {
    Nothing,
    /// θ̇ (qvel) and, if it is an output, the momentum.
    Velocity,
    /// ν̇ too.
    Acceleration,
}

/// One co-simulation slave.
pub struct Slave {
    model: Model,
    layout: Layout,
    guid: String,
    ws: Workspace,
    integrator: Integrator,
    state: SlaveState,
    evaluated: Evaluated,
    /// Momentum at the current state, when `evaluated` ≥ Velocity and it is an output.
    momentum: [f64; 6],
    /// Set when a step failed on a non-finite state: the master should stop
    /// (fmi2GetBooleanStatus(fmi2Terminated)).
    failed_for_good: bool,
    /// The tolerance fmi2SetupExperiment passed, if it passed one: it
    /// replaces the `tolerance` parameter at initialization.
    experiment_tolerance: Option<f64>,
}

impl Slave {
    /// Loads the FMU's compiled model from the resource location and checks
    /// `guid` against it.
    pub fn load(resource_location: &str, guid: &str) -> Result<Slave, SlaveError> {
        let path = resource_directory(resource_location)?.join(Path::new("model.json"));
        let bytes = std::fs::read(&path).map_err(|source| SlaveError::ReadResource { path: path.clone(), source })?;
        let resource: FmuResource =
            serde_json::from_slice(&bytes).map_err(|source| SlaveError::ParseResource { path: path.clone(), source })?;
        if resource.format != RESOURCE_FORMAT {
            return Err(SlaveError::ResourceFormat { path, found: resource.format });
        }
        // Before anything sized by nq or nv (the GUID's variable list, the workspace).
        check_model(&resource.model).map_err(|source| SlaveError::BadModel { path: path.clone(), source })?;
        let layout = Layout::new(&resource.model, resource.outputs);
        let actual = nudyn::export::guid(&bytes, &layout);
        if actual != guid {
            return Err(SlaveError::Guid { given: guid.to_string(), actual });
        }
        let model = resource.model;
        Ok(Slave {
            layout,
            guid: actual,
            ws: model.workspace(),
            integrator: Integrator::new(&model, DEFAULT_METHOD),
            state: SlaveState::initial(&model),
            evaluated: Evaluated::Nothing,
            momentum: [0.0; 6],
            failed_for_good: false,
            experiment_tolerance: None,
            model,
        })
    }

    /// Back to the state just after loading (fmi2Reset).
    pub fn reset(&mut self) {
        self.state = SlaveState::initial(&self.model);
        self.evaluated = Evaluated::Nothing;
        self.failed_for_good = false;
        self.experiment_tolerance = None;
    }

    /// fmi2SetupExperiment: the start time becomes the current time.
    pub fn setup_experiment(
        &mut self,
        tolerance: Option<f64>,
        start_time: f64,
        stop_time: Option<f64>,
    ) -> Result<(), SlaveError> {
        check_experiment(tolerance, start_time, stop_time)?;
        self.experiment_tolerance = tolerance;
        self.state.start_time = start_time;
        self.state.time = start_time;
        self.state.stop_time = stop_time;
        Ok(())
    }

    /// fmi2ExitInitializationMode: checks the initial state set by the
    /// master and normalizes its quaternions, as MuJoCo does. A tolerance
    /// from fmi2SetupExperiment takes the place of the `tolerance`
    /// parameter, which then reads back the tolerance in effect.
    pub fn initialize(&mut self) -> Result<(), SlaveError> {
        self.ws.set_configuration(&self.model, &self.state.theta).map_err(SlaveError::InitialState)?;
        self.ws.set_nu(&self.model, &self.state.nu).map_err(SlaveError::InitialState)?;
        self.state.theta.copy_from_slice(self.ws.theta.as_slice());
        if let Some(tolerance) = self.experiment_tolerance {
            self.state.tolerance = tolerance;
        }
        self.state.carry = Carry::default();
        self.state.initial_energy = kinetic_energy(&self.state.nu);
        self.integrator.set_method(self.state.method);
        self.evaluated = Evaluated::Nothing;
        Ok(())
    }

    /// The variable of Real value reference `vr`.
    fn real_variable(&self, vr: u32) -> Result<RealVariable, SlaveError> {
        self.layout.real_variable(vr).ok_or(SlaveError::UnknownValueReference { vr, kind: "Real" })
    }

    /// fmi2SetReal. `initialized`: after fmi2ExitInitializationMode, when
    /// only the inputs may change (θ and ν have initial="exact": settable
    /// until then, which is how a master chooses the initial state).
    pub fn set_real(&mut self, vrs: &[u32], values: &[f64], initialized: bool) -> Result<(), SlaveError> {
        for (&vr, &value) in vrs.iter().zip(values) {
            let variable = self.real_variable(vr)?;
            let refusal = match variable {
                RealVariable::Eps(_) => None,
                RealVariable::Tolerance | RealVariable::MaxStep | RealVariable::Theta(_) | RealVariable::Nu(_) => {
                    initialized.then_some("after initialization")
                }
                _ => Some("at all: it is a calculated output"),
            };
            if let Some(when) = refusal {
                return Err(SlaveError::NotSettable { name: variable.name(), vr, when });
            }
            if !value.is_finite() {
                return Err(SlaveError::NonFinite { name: variable.name(), value });
            }
            if matches!(variable, RealVariable::Tolerance | RealVariable::MaxStep) && value <= 0.0 {
                let name = if variable == RealVariable::Tolerance { "tolerance" } else { "max_step" };
                return Err(SlaveError::NotPositive { name, value });
            }
        }
        for (&vr, &value) in vrs.iter().zip(values) {
            let s = &mut self.state;
            match self.layout.real_variable(vr).expect("checked above") {
                RealVariable::Tolerance => s.tolerance = value,
                RealVariable::MaxStep => s.max_step = value,
                RealVariable::Eps(k) => s.eps[k] = value,
                RealVariable::Theta(k) => s.theta[k] = value,
                RealVariable::Nu(k) => s.nu[k] = value,
                _ => unreachable!("only settable variables pass the check above"),
            }
        }
        self.evaluated = Evaluated::Nothing;
        Ok(())
    }

    /// Runs the passes needed for outputs beyond θ and ν, once per state.
    fn evaluate(&mut self, needed: Evaluated) -> Result<(), SlaveError> {
        if self.evaluated >= needed {
            return Ok(());
        }
        let (model, s) = (&self.model, &self.state);
        self.ws.set_configuration(model, &s.theta).map_err(SlaveError::Evaluate)?;
        self.ws.set_nu(model, &s.nu).map_err(SlaveError::Evaluate)?;
        if self.layout.outputs.momentum {
            let momentum = self.ws.momentum(model).map_err(SlaveError::Evaluate)?;
            self.momentum.iter_mut().zip(momentum.iter()).for_each(|(m, x)| *m = *x);
        }
        self.evaluated = Evaluated::Velocity;
        if needed == Evaluated::Acceleration {
            self.ws.compute_nu_dot(model, &s.eps).map_err(SlaveError::Evaluate)?;
            self.evaluated = Evaluated::Acceleration;
        }
        Ok(())
    }

    /// fmi2GetReal.
    pub fn get_real(&mut self, vrs: &[u32], values: &mut [f64]) -> Result<(), SlaveError> {
        let variables = vrs.iter().map(|&vr| self.real_variable(vr));
        if let Some(Err(e)) = variables.clone().find(Result::is_err) {
            return Err(e);
        }
        if variables.clone().flatten().any(|v| matches!(v, RealVariable::Qvel(_) | RealVariable::Momentum(_))) {
            self.evaluate(Evaluated::Velocity)?;
        }
        // First every value is computed and checked, then written: a value
        // that overflowed (½|ν|² of a huge ν, ν·ε of a huge ε) is refused,
        // never handed out, and the importer's buffer is left as it was.
        if let Some((vr, value)) = vrs.iter().map(|&vr| (vr, self.real_value(vr))).find(|(_, v)| !v.is_finite()) {
            let name = self.layout.real_variable(vr).expect("checked above").name();
            return Err(SlaveError::NonFiniteOutput { name, value });
        }
        for (value, &vr) in values.iter_mut().zip(vrs) {
            *value = self.real_value(vr);
        }
        Ok(())
    }

    /// The value of Real variable `vr` (known to exist; evaluated as needed).
    fn real_value(&self, vr: u32) -> f64 {
        let s = &self.state;
        match self.layout.real_variable(vr).expect("checked by the caller") {
            RealVariable::Tolerance => s.tolerance,
            RealVariable::MaxStep => s.max_step,
            RealVariable::Eps(k) => s.eps[k],
            RealVariable::Theta(k) => s.theta[k],
            RealVariable::Nu(k) => s.nu[k],
            RealVariable::Qvel(k) => self.ws.qvel[k],
            RealVariable::KineticEnergy => kinetic_energy(&s.nu),
            RealVariable::Power => s.nu.iter().zip(&s.eps).map(|(n, e)| n * e).sum(),
            RealVariable::Momentum(k) => self.momentum[k],
            RealVariable::EnergyResidual => kinetic_energy(&s.nu) - s.initial_energy - s.carry.work,
        }
    }

    /// fmi2GetInteger: the enumeration parameter `method`.
    pub fn get_integer(&self, vrs: &[u32], values: &mut [i32]) -> Result<(), SlaveError> {
        if let Some(&vr) = vrs.iter().find(|&&vr| vr != METHOD_VR) {
            return Err(SlaveError::UnknownValueReference { vr, kind: "Integer" });
        }
        values.iter_mut().for_each(|v| *v = method_value(self.state.method));
        Ok(())
    }

    /// fmi2GetBoolean: the value of the only Boolean variable, the
    /// parameter `energy_projection`, once `vrs` are checked to name it.
    pub fn get_boolean(&self, vrs: &[u32]) -> Result<bool, SlaveError> {
        if let Some(&vr) = vrs.iter().find(|&&vr| vr != ENERGY_PROJECTION_VR) {
            return Err(SlaveError::UnknownValueReference { vr, kind: "Boolean" });
        }
        Ok(self.state.energy_projection)
    }

    /// fmi2SetBoolean: `energy_projection`, before initialization.
    pub fn set_boolean(&mut self, vrs: &[u32], values: &[bool], initialized: bool) -> Result<(), SlaveError> {
        for &vr in vrs {
            if vr != ENERGY_PROJECTION_VR {
                return Err(SlaveError::UnknownValueReference { vr, kind: "Boolean" });
            }
            if initialized {
                return Err(SlaveError::NotSettable { name: "energy_projection".into(), vr, when: "after initialization" });
            }
        }
        if let Some(&value) = values.last() {
            self.state.energy_projection = value;
        }
        Ok(())
    }

    /// fmi2SetInteger: `method`, before initialization, to an item of its enumeration.
    pub fn set_integer(&mut self, vrs: &[u32], values: &[i32], initialized: bool) -> Result<(), SlaveError> {
        for (&vr, &value) in vrs.iter().zip(values) {
            if vr != METHOD_VR {
                return Err(SlaveError::UnknownValueReference { vr, kind: "Integer" });
            }
            if initialized {
                return Err(SlaveError::NotSettable { name: "method".into(), vr, when: "after initialization" });
            }
            if method_of_value(value).is_none() {
                return Err(SlaveError::UnknownMethod(value));
            }
        }
        if let Some(method) = values.last().and_then(|&v| method_of_value(v)) {
            self.state.method = method;
        }
        Ok(())
    }

    /// fmi2SetRealInputDerivatives: dε/dt for the next step (order 1 only).
    pub fn set_input_derivatives(&mut self, vrs: &[u32], orders: &[i32], values: &[f64]) -> Result<(), SlaveError> {
        for ((&vr, &order), &value) in vrs.iter().zip(orders).zip(values) {
            let variable = self.real_variable(vr)?;
            if !matches!(variable, RealVariable::Eps(_)) {
                return Err(SlaveError::NoDerivative { name: variable.name(), vr, what: "input" });
            }
            if order != 1 {
                return Err(SlaveError::DerivativeOrder { name: variable.name(), order });
            }
            if !value.is_finite() {
                return Err(SlaveError::NonFinite { name: format!("der({})", variable.name()), value });
            }
        }
        for (&vr, &value) in vrs.iter().zip(values) {
            if let Some(RealVariable::Eps(k)) = self.layout.real_variable(vr) {
                self.state.eps_rate[k] = value;
            }
        }
        Ok(())
    }

    /// fmi2GetRealOutputDerivatives (order 1): d(theta)/dt, the qpos rate
    /// (q̇ = ½ q ⊗ (0, ω) for quaternions), and d(nu)/dt = ν̇ at the current ε.
    pub fn get_output_derivatives(&mut self, vrs: &[u32], orders: &[i32], values: &mut [f64]) -> Result<(), SlaveError> {
        for (&vr, &order) in vrs.iter().zip(orders) {
            let variable = self.real_variable(vr)?;
            if !matches!(variable, RealVariable::Theta(_) | RealVariable::Nu(_)) {
                return Err(SlaveError::NoDerivative { name: variable.name(), vr, what: "output" });
            }
            if order != 1 {
                return Err(SlaveError::DerivativeOrder { name: variable.name(), order });
            }
        }
        self.evaluate(Evaluated::Acceleration)?;
        let derivative = |vr: u32| match self.layout.real_variable(vr) {
            Some(RealVariable::Theta(k)) => self.qpos_rate(k),
            Some(RealVariable::Nu(k)) => self.ws.nu_dot[k],
            _ => unreachable!("checked above"),
        };
        // As in get_real: an overflowed derivative is refused, not handed out.
        if let Some((vr, value)) = vrs.iter().map(|&vr| (vr, derivative(vr))).find(|(_, v)| !v.is_finite()) {
            let name = format!("der({})", self.layout.real_variable(vr).expect("checked above").name());
            return Err(SlaveError::NonFiniteOutput { name, value });
        }
        for (value, &vr) in values.iter_mut().zip(vrs) {
            *value = derivative(vr);
        }
        Ok(())
    }

    /// d(qpos[k])/dt from the workspace's θ̇ (passes 0–2 done).
    fn qpos_rate(&self, k: usize) -> f64 {
        let link = self
            .model
            .links
            .iter()
            .rev()
            .find(|l| l.qpos_adr <= k)
            .expect("every coordinate belongs to a link");
        let (q, w) = (&self.ws.theta.as_slice()[link.qpos_adr..], &self.ws.qvel.as_slice()[link.dof_adr..]);
        match (link.joint, k - link.qpos_adr) {
            (LinkJoint::Ball, 0) => -0.5 * (q[1] * w[0] + q[2] * w[1] + q[3] * w[2]),
            (LinkJoint::Ball, 1) => 0.5 * (q[0] * w[0] + q[2] * w[2] - q[3] * w[1]),
            (LinkJoint::Ball, 2) => 0.5 * (q[0] * w[1] + q[3] * w[0] - q[1] * w[2]),
            (LinkJoint::Ball, _) => 0.5 * (q[0] * w[2] + q[1] * w[1] - q[2] * w[0]),
            (_, i) => w[i],
        }
    }

    /// fmi2DoStep: integrates from `time` to `time + step` with the chosen
    /// method (internal steps independent of the communication step), with
    /// ε(t) = ε + dε/dt·(t − time); the ramp applies to this step only.
    /// If the integration stops inside the step, the state stays at the
    /// last successful internal step and the time says where. A step that
    /// completed only by relaxing the tolerance says so.
    pub fn do_step(&mut self, time: f64, step: f64) -> Result<StepReport, SlaveError> {
        let s = &mut self.state;
        check_communication_step(s.time, s.stop_time, time, step)?;
        let settings = Settings { tolerance: s.tolerance, max_step: s.max_step, energy_projection: s.energy_projection };
        let (eps, eps_rate) = (&s.eps, &s.eps_rate);
        let applied = |t_stage: f64, out: &mut [f64]| {
            for ((o, e), r) in out.iter_mut().zip(eps).zip(eps_rate) {
                *o = e + r * (t_stage - time);
            }
        };
        let (model, ws, integrator) = (&self.model, &mut self.ws, &mut self.integrator);
        let relaxation_before = s.carry.relaxation;
        let result =
            integrator.advance(model, ws, &mut s.theta, &mut s.nu, (time, time + step), &settings, &mut s.carry, applied);
        self.evaluated = Evaluated::Nothing;
        match result {
            Ok(stats) => {
                s.time = time + step;
                s.eps_rate.fill(0.0);
                let relaxed = s.carry.relaxed_since(relaxation_before, time, s.tolerance);
                Ok(StepReport { stats, relaxed })
            }
            Err(source) => {
                s.time = source.reached();
                self.failed_for_good = source.is_non_finite();
                Err(SlaveError::StepFailed { time, step, source })
            }
        }
    }

    /// Refuses what [`Slave::do_step`] does not check (it is called first):
    /// a non-finite communication point, which no tolerance compares with
    /// the slave's time, and a finite step that would take more than
    /// [`MAX_INTERNAL_STEPS`] internal steps.
    pub fn check_step_arguments(&self, time: f64, step: f64) -> Result<(), SlaveError> {
        if !time.is_finite() {
            return Err(SlaveError::CommunicationPoint { expected: self.state.time, found: time });
        }
        let max_step = self.state.max_step;
        let needed = step / max_step;
        if step.is_finite() && needed > MAX_INTERNAL_STEPS {
            return Err(SlaveError::TooLong { step, max_step, needed });
        }
        Ok(())
    }

    /// The current time (fmi2LastSuccessfulTime).
    pub fn time(&self) -> f64 {
        self.state.time
    }

    /// Whether the slave cannot go on (fmi2Terminated status).
    pub fn failed_for_good(&self) -> bool {
        self.failed_for_good
    }

    /// Saves the state, taken in `phase`, into `snapshot` (reusing its buffers).
    pub fn save(&self, phase: Phase, snapshot: &mut Snapshot) {
        snapshot.phase = phase;
        snapshot.guid.clone_from(&self.guid);
        snapshot.state.clone_from(&self.state);
    }

    /// A new snapshot of the state, taken in `phase`.
    pub fn snapshot(&self, phase: Phase) -> Snapshot {
        Snapshot { phase, guid: self.guid.clone(), state: self.state.clone() }
    }

    /// Restores a saved state; a state of another FMU is refused.
    pub fn restore(&mut self, snapshot: &Snapshot) -> Result<(), SlaveError> {
        let (nq, nv) = (snapshot.state.theta.len(), snapshot.state.nu.len());
        if snapshot.guid != self.guid {
            return Err(SnapshotError::ForeignGuid { found: snapshot.guid.clone(), expected: self.guid.clone() }.into());
        }
        if (nq, nv) != (self.model.nq, self.model.nv) {
            let (expected_nq, expected_nv) = (self.model.nq, self.model.nv);
            return Err(SnapshotError::Sizes { nq, nv, expected_nq, expected_nv }.into());
        }
        self.state.clone_from(&snapshot.state);
        self.integrator.set_method(self.state.method);
        self.evaluated = Evaluated::Nothing;
        self.failed_for_good = false;
        Ok(())
    }

    /// Reads a serialized state of this FMU.
    pub fn deserialize(&self, bytes: &[u8]) -> Result<Snapshot, SlaveError> {
        Ok(Snapshot::deserialize(bytes, &self.guid, self.model.nq, self.model.nv)?)
    }
}
