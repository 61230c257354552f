//! One interface for what an FMU instance runs, the plant or the
//! controller (after the FMI Reference FMUs' `model.h`): each implements
//! [`Component`], with defaults for what it does not provide, and the FMI
//! layer calls it through the generic checks of [`crate::calls`].
//!
//! Errors are split by the phase they belong to: [`crate::load::LoadError`]
//! at instantiation, [`CallError`] for a call that is refused or cannot be
//! answered, [`StepError`] for a step that started and did not complete.

use nudyn::dynamics::DynamicsError;
use nudyn::integrate::{AdvanceError, AutoChoice, AutoMove, StabilityHeld, Stats, ToleranceRelaxed};
use nudyn_contract::capabilities::Capabilities;
use nudyn_contract::plant::method_items;
use nudyn_contract::variable::Kind;

use crate::snapshot::{Snapshot, SnapshotError};
use crate::state::Phase;

/// A Real variable as the checks need it: its name, for messages, and its kind.
#[derive(Clone, Debug, PartialEq)]
pub struct Variable {
    /// The structured name, as in the modelDescription.
    pub name: String,
    /// Causality, variability, range.
    pub kind: Kind,
}

/// What a completed fmi2DoStep did, when the component integrates.
#[derive(Debug)]
pub struct StepReport {
    /// The internal steps taken and rejected.
    pub stats: Stats,
    /// Set when the tolerance had to be relaxed (fmi2Warning).
    pub relaxed: Option<ToleranceRelaxed>,
    /// Set when `method = auto` chose the method in this step.
    pub chose: Option<AutoChoice>,
    /// Set when `method = auto` moved to another method after this step.
    pub moved: Option<AutoMove>,
    /// Set the first time stability held the steps of a method the user named.
    pub held: Option<StabilityHeld>,
}

/// What an FMU instance runs. Methods are called only after the checks of
/// [`crate::calls`] passed: known value references, settable variables,
/// finite values in range, a valid communication step.
pub trait Component {
    /// What the FMU declares it can do (the same value its modelDescription was written from).
    fn capabilities(&self) -> Capabilities;

    /// Back to the state just after loading (fmi2Reset).
    fn reset(&mut self);

    /// The current time (fmi2LastSuccessfulTime).
    fn time(&self) -> f64;

    /// The stop time fmi2SetupExperiment declared, if any.
    fn stop_time(&self) -> Option<f64>;

    /// fmi2SetupExperiment, with arguments already checked.
    fn setup_experiment(&mut self, tolerance: Option<f64>, start_time: f64, stop_time: Option<f64>);

    /// How many event indicators model exchange in FMI 2.0 has.
    fn event_indicator_count(&self) -> usize {
        0
    }

    /// fmi2GetEventIndicators: their values at the current state, into
    /// `out` ([`Component::event_indicator_count`] long).
    fn event_indicators(&mut self, _out: &mut [f64]) -> Result<(), CallError> {
        Ok(())
    }

    /// fmi2NewDiscreteStates: what holds from this event to the next is set
    /// from the state here; whether it was (the derivatives may then jump,
    /// so the host's integrator must start afresh: `fmi2.rs`).
    fn update_discrete_states(&mut self) -> Result<bool, CallError> {
        Ok(false)
    }

    /// fmi2ExitInitializationMode: whatever was set must make a run; the
    /// answer is a note for the log, if the run differs from what the
    /// FMU's own parameters say.
    fn initialize(&mut self) -> Result<Option<String>, CallError>;

    /// The Real variable with value reference `vr`, if there is one.
    fn real_variable(&self, vr: u32) -> Option<Variable>;

    /// The kind of the Real variable with value reference `vr`, if there is
    /// one: the check on every value of fmi2GetReal and fmi2SetReal, which
    /// needs the name only to report a refusal.
    fn real_kind(&self, vr: u32) -> Option<Kind> {
        self.real_variable(vr).map(|variable| variable.kind)
    }

    /// Takes Real values that passed every check (fmi2SetReal).
    fn set_reals(&mut self, vrs: &[u32], values: &[f64]);

    /// Computes what reading `vrs` needs (known variables), once per change;
    /// a message is a warning the call completes with.
    fn prepare_reals(&mut self, vrs: &[u32]) -> Result<Option<String>, CallError>;

    /// The value of the known Real variable `vr`, after [`Component::prepare_reals`].
    fn real_value(&self, vr: u32) -> f64;

    /// fmi2GetInteger.
    fn get_integer(&self, vrs: &[u32], _values: &mut [i32]) -> Result<(), CallError> {
        none_of("Integer", vrs)
    }

    /// fmi2SetInteger; `initialized`: after fmi2ExitInitializationMode.
    fn set_integer(&mut self, vrs: &[u32], _values: &[i32], _initialized: bool) -> Result<(), CallError> {
        none_of("Integer", vrs)
    }

    /// fmi2GetBoolean.
    fn get_boolean(&self, vrs: &[u32], _values: &mut [bool]) -> Result<(), CallError> {
        none_of("Boolean", vrs)
    }

    /// fmi2SetBoolean; `initialized`: after fmi2ExitInitializationMode.
    fn set_boolean(&mut self, vrs: &[u32], _values: &[bool], _initialized: bool) -> Result<(), CallError> {
        none_of("Boolean", vrs)
    }

    /// Takes first derivatives of inputs that passed every check
    /// (fmi2SetRealInputDerivatives; only with canInterpolateInputs).
    fn set_input_derivatives(&mut self, _vrs: &[u32], _values: &[f64]) -> Result<(), CallError> {
        Err(CallError::NotProvided("canInterpolateInputs"))
    }

    /// Computes the time derivatives of the state outputs (only with maxOutputDerivativeOrder ≥ 1).
    fn prepare_output_derivatives(&mut self) -> Result<(), CallError> {
        Err(CallError::NotProvided("maxOutputDerivativeOrder"))
    }

    /// The time derivative of the state output `vr`, after [`Component::prepare_output_derivatives`].
    fn output_derivative(&self, _vr: u32) -> f64 {
        f64::NAN
    }

    /// Refuses a step size this component cannot take, beyond the generic checks.
    fn check_step_size(&self, _step: f64) -> Result<(), CallError> {
        Ok(())
    }

    /// fmi2DoStep from the communication point `time` (checked to be the
    /// current time) by `step`; a component that integrates reports what it did.
    fn do_step(&mut self, time: f64, step: f64) -> Result<Option<StepReport>, StepError>;

    /// Whether the instance cannot go on (fmi2Terminated status).
    fn failed_for_good(&self) -> bool {
        false
    }

    /// Model exchange: the number of continuous states; `None` when the
    /// component does not serve model exchange.
    fn continuous_state_count(&self) -> Option<usize> {
        None
    }

    /// fmi2SetTime: the time at which the host evaluates next.
    fn set_time(&mut self, _time: f64) {}

    /// fmi2GetContinuousStates into `x` (checked to have the count).
    fn continuous_states(&self, _x: &mut [f64]) {}

    /// fmi2SetContinuousStates from `x` (checked: the count, finite values).
    fn set_continuous_states(&mut self, _x: &[f64]) {}

    /// Computes dx/dt at the current time, states and inputs (fmi2GetDerivatives).
    fn prepare_derivatives(&mut self) -> Result<(), CallError> {
        Err(CallError::NotProvided("model exchange"))
    }

    /// dx[i]/dt, after [`Component::prepare_derivatives`].
    fn derivative(&self, _i: usize) -> f64 {
        f64::NAN
    }

    /// Whether it computes partial derivatives, or why not
    /// ([`CallError::NoPartials`]); asked before any argument is read.
    fn partials(&self) -> Result<(), CallError> {
        Err(CallError::NoPartials("this component computes none".into()))
    }

    /// `sensitivity` = J `seed`: the directional derivative of `unknowns`
    /// along `seed` of `knowns` (FMI 2.0 value references; `seed` finite,
    /// one per known, `sensitivity` one per unknown).
    fn directional_derivative(
        &mut self,
        _unknowns: &[u32],
        _knowns: &[u32],
        _seed: &[f64],
        _sensitivity: &mut [f64],
    ) -> Result<(), CallError> {
        self.partials()
    }

    /// `sensitivity` = Jᵀ `seed`: the adjoint derivative (`seed` one per
    /// unknown, `sensitivity` one per known).
    fn adjoint_derivative(
        &mut self,
        _unknowns: &[u32],
        _knowns: &[u32],
        _seed: &[f64],
        _sensitivity: &mut [f64],
    ) -> Result<(), CallError> {
        self.partials()
    }

    /// The knowns (FMI 2.0 Real value references) the output or state
    /// derivative `vr` depends on, as the modelDescription declares them.
    fn dependencies(&self, vr: u32) -> Option<Vec<u32>>;

    /// A new FMU state, taken in `phase` (only with canGetAndSetFMUstate).
    fn snapshot(&self, _phase: Phase) -> Result<Snapshot, CallError> {
        Err(CallError::NoFmuState)
    }

    /// Saves the state into an existing FMU state.
    fn save(&self, _phase: Phase, _snapshot: &mut Snapshot) -> Result<(), CallError> {
        Err(CallError::NoFmuState)
    }

    /// Restores an FMU state.
    fn restore(&mut self, _snapshot: &Snapshot) -> Result<(), CallError> {
        Err(CallError::NoFmuState)
    }

    /// Reads a serialized FMU state of this FMU.
    fn deserialize(&self, _bytes: &[u8]) -> Result<Snapshot, CallError> {
        Err(CallError::NoFmuState)
    }
}

/// A type of which the component has no variables: any value reference is unknown.
fn none_of(kind: &'static str, vrs: &[u32]) -> Result<(), CallError> {
    match vrs.first() {
        Some(&vr) => Err(CallError::UnknownValueReference { vr, kind }),
        None => Ok(()),
    }
}

/// Why a call is refused, or cannot be answered at the current state.
#[derive(Debug, thiserror::Error)]
pub enum CallError {
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
        /// Variable or argument name.
        name: String,
        /// The value.
        value: f64,
    },
    /// A finite value outside the variable's range.
    #[error("{name} = {value} must be {must}")]
    OutOfRange {
        /// Variable or argument name.
        name: String,
        /// The value.
        value: f64,
        /// "positive" or "non-negative".
        must: &'static str,
    },
    /// An array of continuous states or derivatives of the wrong length.
    #[error("{what} has {found} entries, but the FMU has {expected} continuous states")]
    StateCount {
        /// The argument.
        what: &'static str,
        /// Its length.
        found: usize,
        /// The number of continuous states.
        expected: usize,
    },
    /// A continuous state that is NaN or ±Inf.
    #[error("continuous state x[{index}] = {value} is not finite")]
    NonFiniteState {
        /// 0-based index into x.
        index: usize,
        /// The value.
        value: f64,
    },
    /// Event indicators asked in a number other than the FMU's.
    #[error("ni = {found}, but the FMU has {expected} event indicators")]
    EventIndicators {
        /// ni.
        found: usize,
        /// The FMU's count.
        expected: usize,
    },
    /// A stop time before the start time.
    #[error("stopTime = {stop_time} is before startTime = {start_time}")]
    StopBeforeStart {
        /// startTime.
        start_time: f64,
        /// stopTime.
        stop_time: f64,
    },
    /// A `method` value that is not an item of the enumeration.
    #[error("method = {0} is not an item of the enumeration ({items})", items = method_items())]
    UnknownMethod(i32),
    /// An output that is not finite at the current (finite) state.
    #[error("{name} = {value} is not finite at the current state: no value is returned")]
    NonFiniteOutput {
        /// Variable name.
        name: String,
        /// The value.
        value: f64,
    },
    /// The initial state (θ, ν) set by the master cannot be used.
    #[error("the initial state cannot be used: {0}")]
    InitialState(DynamicsError),
    /// An output could not be evaluated at the current state.
    #[error("the outputs cannot be evaluated at the current state: {0}")]
    Evaluate(DynamicsError),
    /// The control law cannot be evaluated at the current inputs and parameters.
    #[error("the controller cannot be evaluated: {0}")]
    Control(nudyn::control::ControlError),
    /// currentCommunicationPoint is not the instance's time.
    #[error("expected currentCommunicationPoint = {expected} but was {found}")]
    CommunicationPoint {
        /// The instance's time.
        expected: f64,
        /// The argument.
        found: f64,
    },
    /// A step size that is not positive and finite.
    #[error("communicationStepSize = {0} must be positive and finite")]
    StepSize(f64),
    /// The step needs more internal steps than the plant allows in one call.
    #[error(
        "communicationStepSize = {step} with steps of at most {max_step} s (max_step) needs {needed:e} internal steps, \
         more than the {limit:e} one fmi2DoStep may take: a larger max_step or a shorter communication step lets it through",
        step = .0.interval, max_step = .0.max_step, needed = .0.needed, limit = nudyn::integrate::MAX_STEPS as f64
    )]
    TooLong(nudyn::integrate::IntervalTooLong),
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
    /// An input or output derivative of an order the FMU does not serve.
    #[error("derivative order {order} of {name} is not supported (only order 1)")]
    DerivativeOrder {
        /// Variable name.
        name: String,
        /// The order asked for.
        order: i32,
    },
    /// A derivative asked of a variable that has none.
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
    /// FMU states asked of an FMU that declares canGetAndSetFMUstate="false".
    #[error(
        "this FMU has no FMU states (canGetAndSetFMUstate=\"false\"): its outputs depend on its inputs and parameters only"
    )]
    NoFmuState,
    /// Partial derivatives asked of an FMU that declares none, and why.
    #[error(
        "directional and adjoint derivatives are not provided (providesDirectionalDerivative=\"false\" in the \
         modelDescription): {0}"
    )]
    NoPartials(String),
    /// Partial derivatives asked at a state on a switch of the constraint
    /// forces, where they are one-sided (which switches).
    #[error("the partial derivatives are one-sided at this state: {0}")]
    OneSided(String),
    /// A variable passed as a known or an unknown that cannot be one.
    #[error("{name} (value reference {vr}) is not {role}")]
    NotPartial {
        /// Variable name.
        name: String,
        /// Its value reference.
        vr: u32,
        /// What it was passed as, and what can be.
        role: &'static str,
    },
    /// A function whose capability flag the FMU does not declare.
    #[error("not provided: the FMU does not declare {0}")]
    NotProvided(&'static str),
}

impl CallError {
    /// Whether a value was refused for being outside its range (not finite,
    /// not positive, not an enumeration item): fmi2Discard from fmi2SetXXX
    /// (FMI 2.0 §2.1.3, footnote 3).
    pub fn is_out_of_range(&self) -> bool {
        matches!(
            self,
            CallError::NonFinite { .. }
                | CallError::OutOfRange { .. }
                | CallError::UnknownMethod(_)
                | CallError::NonFiniteState { .. }
        )
    }
}

/// A step that started and stopped inside the interval: the instance stays
/// where it stopped, and the time says where (fmi2Discard).
#[derive(Debug, thiserror::Error)]
#[error("the step from t = {time} by {step} stopped at t = {reached}: {source}", reached = source.reached())]
pub struct StepError {
    /// Start of the step.
    pub time: f64,
    /// Its size.
    pub step: f64,
    /// The cause, with the time reached.
    pub source: AdvanceError,
}
