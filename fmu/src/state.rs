//! The FMI 2.0 state machines of co-simulation (§4.2.4) and model exchange
//! (§3.2.3), which FMI 3.0's follow for what nudyn serves (§4.2, §3.2): the instance's states and, per function, the states it may be
//! called in. The two machines share instantiated, initializationMode,
//! terminated and error; stepComplete and stepFailed belong to
//! co-simulation, eventMode and continuousTimeMode to model exchange, so
//! one table serves both (a model-exchange function is refused in every
//! co-simulation state, and the other way round).
//!
//! doStep is synchronous (canRunAsynchronuously="false"), so the states
//! stepInProgress and stepCanceled are never entered and not modelled.

/// Where an instance is in its life.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// After fmi2Instantiate or fmi2Reset.
    Instantiated,
    /// Between fmi2EnterInitializationMode and fmi2ExitInitializationMode.
    InitializationMode,
    /// Initialized, and the last step (if any) succeeded: slaveInitialized/stepComplete.
    StepComplete,
    /// The last doStep returned fmi2Discard.
    StepFailed,
    /// After fmi2Terminate: values stay readable.
    Terminated,
    /// A function returned fmi2Error: only inspection, reset and free remain.
    Error,
    /// A function returned fmi2Fatal: only free remains.
    Fatal,
    /// Model exchange: after fmi2ExitInitializationMode or fmi2EnterEventMode.
    EventMode,
    /// Model exchange: after fmi2EnterContinuousTimeMode, while the host integrates.
    ContinuousTimeMode,
}

impl Phase {
    /// Every state, in the order of their codes (written into serialized FMU
    /// states: a new state takes the next code, none is renumbered).
    pub const ALL: [Phase; 9] = [
        Phase::Instantiated,
        Phase::InitializationMode,
        Phase::StepComplete,
        Phase::StepFailed,
        Phase::Terminated,
        Phase::Error,
        Phase::Fatal,
        Phase::EventMode,
        Phase::ContinuousTimeMode,
    ];

    const fn bit(self) -> u16 {
        1 << self as u16
    }

    /// The state's code in serialized FMU states.
    pub fn code(self) -> u8 {
        self as u8
    }

    /// The state of a code, if there is one.
    pub fn from_code(code: u8) -> Option<Phase> {
        Phase::ALL.get(usize::from(code)).copied()
    }

    /// The spec's name of the state, for messages.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Instantiated => "instantiated",
            Phase::InitializationMode => "initializationMode",
            Phase::StepComplete => "stepComplete",
            Phase::StepFailed => "stepFailed",
            Phase::Terminated => "terminated",
            Phase::Error => "error",
            Phase::Fatal => "fatal",
            Phase::EventMode => "eventMode",
            Phase::ContinuousTimeMode => "continuousTimeMode",
        }
    }

    /// FMI 3.0's name of the state, for messages (co-simulation's states
    /// are called stepMode and stepDiscarded there).
    pub fn fmi3_name(self) -> &'static str {
        match self {
            Phase::StepComplete => "stepMode",
            Phase::StepFailed => "stepDiscarded",
            other => other.name(),
        }
    }
}

const INSTANTIATED: u16 = Phase::Instantiated.bit();
const INIT: u16 = Phase::InitializationMode.bit();
const STEP_COMPLETE: u16 = Phase::StepComplete.bit();
const STEP_FAILED: u16 = Phase::StepFailed.bit();
const TERMINATED: u16 = Phase::Terminated.bit();
const ERROR: u16 = Phase::Error.bit();
const EVENT: u16 = Phase::EventMode.bit();
const CONTINUOUS: u16 = Phase::ContinuousTimeMode.bit();
/// Initialized, co-simulation or model exchange.
const RUNNING: u16 = STEP_COMPLETE | STEP_FAILED | EVENT | CONTINUOUS;
/// Every state in which the instance is still usable or inspectable.
const ALIVE: u16 = INSTANTIATED | INIT | RUNNING | TERMINATED | ERROR;

/// The functions that take an instance, for the state table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Function {
    SetDebugLogging,
    SetupExperiment,
    EnterInitializationMode,
    ExitInitializationMode,
    Terminate,
    Reset,
    GetReal,
    GetInteger,
    GetBoolean,
    GetString,
    SetReal,
    SetInteger,
    SetBoolean,
    SetString,
    GetFmuState,
    SetFmuState,
    FreeFmuState,
    SerializedFmuStateSize,
    SerializeFmuState,
    DeSerializeFmuState,
    GetDirectionalDerivative,
    SetRealInputDerivatives,
    GetRealOutputDerivatives,
    DoStep,
    CancelStep,
    GetStatus,
    GetRealStatus,
    GetIntegerStatus,
    GetBooleanStatus,
    GetStringStatus,
    EnterEventMode,
    NewDiscreteStates,
    EnterContinuousTimeMode,
    CompletedIntegratorStep,
    SetTime,
    SetContinuousStates,
    GetDerivatives,
    GetEventIndicators,
    GetContinuousStates,
    GetNominalsOfContinuousStates,
    /// FMI 3.0: the number of continuous states or event indicators.
    GetNumberOf,
    /// FMI 3.0: fmi3EnterStepMode (from co-simulation's event mode).
    EnterStepMode,
    /// FMI 3.0: fmi3GetNumberOfVariableDependencies and fmi3GetVariableDependencies.
    GetVariableDependencies,
    /// FMI 3.0: what the FMU does not provide (clocks, configuration mode,
    /// evaluateDiscreteStates, scheduled execution): refused with the reason.
    NotProvided,
}

impl Function {
    /// The C name, for messages.
    pub fn name(self) -> &'static str {
        match self {
            Function::SetDebugLogging => "fmi2SetDebugLogging",
            Function::SetupExperiment => "fmi2SetupExperiment",
            Function::EnterInitializationMode => "fmi2EnterInitializationMode",
            Function::ExitInitializationMode => "fmi2ExitInitializationMode",
            Function::Terminate => "fmi2Terminate",
            Function::Reset => "fmi2Reset",
            Function::GetReal => "fmi2GetReal",
            Function::GetInteger => "fmi2GetInteger",
            Function::GetBoolean => "fmi2GetBoolean",
            Function::GetString => "fmi2GetString",
            Function::SetReal => "fmi2SetReal",
            Function::SetInteger => "fmi2SetInteger",
            Function::SetBoolean => "fmi2SetBoolean",
            Function::SetString => "fmi2SetString",
            Function::GetFmuState => "fmi2GetFMUstate",
            Function::SetFmuState => "fmi2SetFMUstate",
            Function::FreeFmuState => "fmi2FreeFMUstate",
            Function::SerializedFmuStateSize => "fmi2SerializedFMUstateSize",
            Function::SerializeFmuState => "fmi2SerializeFMUstate",
            Function::DeSerializeFmuState => "fmi2DeSerializeFMUstate",
            Function::GetDirectionalDerivative => "fmi2GetDirectionalDerivative",
            Function::SetRealInputDerivatives => "fmi2SetRealInputDerivatives",
            Function::GetRealOutputDerivatives => "fmi2GetRealOutputDerivatives",
            Function::DoStep => "fmi2DoStep",
            Function::CancelStep => "fmi2CancelStep",
            Function::GetStatus => "fmi2GetStatus",
            Function::GetRealStatus => "fmi2GetRealStatus",
            Function::GetIntegerStatus => "fmi2GetIntegerStatus",
            Function::GetBooleanStatus => "fmi2GetBooleanStatus",
            Function::GetStringStatus => "fmi2GetStringStatus",
            Function::EnterEventMode => "fmi2EnterEventMode",
            Function::NewDiscreteStates => "fmi2NewDiscreteStates",
            Function::EnterContinuousTimeMode => "fmi2EnterContinuousTimeMode",
            Function::CompletedIntegratorStep => "fmi2CompletedIntegratorStep",
            Function::SetTime => "fmi2SetTime",
            Function::SetContinuousStates => "fmi2SetContinuousStates",
            Function::GetDerivatives => "fmi2GetDerivatives",
            Function::GetEventIndicators => "fmi2GetEventIndicators",
            Function::GetContinuousStates => "fmi2GetContinuousStates",
            Function::GetNominalsOfContinuousStates => "fmi2GetNominalsOfContinuousStates",
            Function::GetNumberOf => "fmi3GetNumberOf…",
            Function::EnterStepMode => "fmi3EnterStepMode",
            Function::GetVariableDependencies => "fmi3GetVariableDependencies",
            Function::NotProvided => "(not provided)",
        }
    }

    /// The interface the function belongs to, if only one.
    pub fn interface(self) -> Option<Interface> {
        match self {
            Function::DoStep
            | Function::CancelStep
            | Function::GetStatus
            | Function::GetRealStatus
            | Function::GetIntegerStatus
            | Function::GetBooleanStatus
            | Function::GetStringStatus
            | Function::SetRealInputDerivatives
            | Function::GetRealOutputDerivatives
            | Function::EnterStepMode => Some(Interface::CoSimulation),
            Function::NewDiscreteStates
            | Function::EnterContinuousTimeMode
            | Function::CompletedIntegratorStep
            | Function::SetTime
            | Function::SetContinuousStates
            | Function::GetDerivatives
            | Function::GetEventIndicators
            | Function::GetContinuousStates
            | Function::GetNominalsOfContinuousStates
            | Function::GetNumberOf => Some(Interface::ModelExchange),
            _ => None,
        }
    }

    /// The states in which the function may be called (FMI 2.0 §4.2.4 and
    /// §3.2.3). fmi2FreeInstance is not in the table: it is accepted in every
    /// state, `fatal` included, since releasing memory is always safe here
    /// and refusing would only leak it.
    fn allowed(self) -> u16 {
        match self {
            Function::SetDebugLogging | Function::Reset => ALIVE,
            Function::GetFmuState | Function::SetFmuState | Function::FreeFmuState => ALIVE,
            Function::SerializedFmuStateSize | Function::SerializeFmuState | Function::DeSerializeFmuState => ALIVE,
            Function::SetupExperiment | Function::EnterInitializationMode => INSTANTIATED,
            Function::ExitInitializationMode => INIT,
            Function::Terminate => STEP_COMPLETE | STEP_FAILED | EVENT | CONTINUOUS,
            Function::GetReal | Function::GetInteger | Function::GetBoolean | Function::GetString => {
                INIT | RUNNING | TERMINATED | ERROR
            }
            Function::GetDirectionalDerivative => INIT | RUNNING | TERMINATED | ERROR,
            Function::SetReal => INSTANTIATED | INIT | STEP_COMPLETE | EVENT | CONTINUOUS,
            // Only Reals are continuous: the other types change at events (§3.2.3).
            Function::SetInteger | Function::SetBoolean | Function::SetString => {
                INSTANTIATED | INIT | STEP_COMPLETE | EVENT
            }
            Function::SetRealInputDerivatives => INSTANTIATED | INIT | STEP_COMPLETE,
            Function::GetRealOutputDerivatives => STEP_COMPLETE | STEP_FAILED | TERMINATED | ERROR,
            Function::DoStep => STEP_COMPLETE,
            // Only legal in stepInProgress, which a synchronous doStep never leaves behind.
            Function::CancelStep => 0,
            Function::GetStatus
            | Function::GetRealStatus
            | Function::GetIntegerStatus
            | Function::GetBooleanStatus
            | Function::GetStringStatus => STEP_COMPLETE | STEP_FAILED | TERMINATED,
            Function::EnterEventMode => EVENT | CONTINUOUS,
            Function::NewDiscreteStates | Function::EnterContinuousTimeMode => EVENT,
            Function::CompletedIntegratorStep | Function::SetContinuousStates => CONTINUOUS,
            Function::SetTime => EVENT | CONTINUOUS,
            Function::GetEventIndicators | Function::GetContinuousStates => {
                INIT | EVENT | CONTINUOUS | TERMINATED | ERROR
            }
            Function::GetDerivatives => EVENT | CONTINUOUS | TERMINATED | ERROR,
            Function::GetNominalsOfContinuousStates => INSTANTIATED | EVENT | CONTINUOUS | TERMINATED | ERROR,
            Function::GetNumberOf => INSTANTIATED | INIT | EVENT | CONTINUOUS | TERMINATED | ERROR,
            // Co-simulation never enters event mode here (hasEventMode="false").
            Function::EnterStepMode => 0,
            Function::GetVariableDependencies | Function::NotProvided => ALIVE,
        }
    }

    /// Whether the function may be called in `phase`.
    pub fn allowed_in(self, phase: Phase) -> bool {
        self.allowed() & phase.bit() != 0
    }
}

/// The interface an instance was instantiated for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interface {
    /// Model exchange.
    ModelExchange,
    /// Co-simulation.
    CoSimulation,
}

impl Interface {
    /// Whether `phase` is one of this interface's state machine.
    pub fn has(self, phase: Phase) -> bool {
        match phase {
            Phase::StepComplete | Phase::StepFailed => self == Interface::CoSimulation,
            Phase::EventMode | Phase::ContinuousTimeMode => self == Interface::ModelExchange,
            _ => true,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Interface::ModelExchange => "model exchange",
            Interface::CoSimulation => "co-simulation",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn allowed_phases(function: Function) -> Vec<Phase> {
        Phase::ALL.into_iter().filter(|&p| function.allowed_in(p)).collect()
    }

    #[test]
    fn initialization_sequence() {
        assert_eq!(allowed_phases(Function::SetupExperiment), [Phase::Instantiated]);
        assert_eq!(allowed_phases(Function::EnterInitializationMode), [Phase::Instantiated]);
        assert_eq!(allowed_phases(Function::ExitInitializationMode), [Phase::InitializationMode]);
        assert_eq!(allowed_phases(Function::DoStep), [Phase::StepComplete]);
    }

    #[test]
    fn outputs_with_initial_exact_are_settable_only_until_initialized() {
        // fmi2SetReal covers theta/nu start values before initialization and eps afterwards;
        // the slave refuses theta/nu once initialized.
        assert_eq!(
            allowed_phases(Function::SetReal),
            [
                Phase::Instantiated,
                Phase::InitializationMode,
                Phase::StepComplete,
                Phase::EventMode,
                Phase::ContinuousTimeMode
            ]
        );
    }

    #[test]
    fn final_values_stay_readable() {
        for function in [Function::GetReal, Function::GetRealOutputDerivatives, Function::GetFmuState] {
            assert!(function.allowed_in(Phase::Terminated), "{function:?}");
            assert!(function.allowed_in(Phase::Error), "{function:?}");
        }
        assert!(!Function::GetReal.allowed_in(Phase::Instantiated));
    }

    #[test]
    fn codes_round_trip() {
        for phase in Phase::ALL {
            assert_eq!(Phase::from_code(phase.code()), Some(phase));
        }
        assert_eq!(Phase::from_code(9), None);
    }

    #[test]
    fn fatal_allows_nothing_in_the_table() {
        let in_fatal: Vec<Function> =
            [Function::SetDebugLogging, Function::Reset, Function::GetReal, Function::DoStep, Function::GetFmuState]
                .into_iter()
                .filter(|f| f.allowed_in(Phase::Fatal))
                .collect();
        assert_eq!(in_fatal, []);
    }

    #[test]
    fn error_allows_reset_but_not_stepping() {
        assert!(Function::Reset.allowed_in(Phase::Error));
        assert!(!Function::DoStep.allowed_in(Phase::Error));
        assert!(!Function::SetReal.allowed_in(Phase::Error));
        assert!(!Function::Terminate.allowed_in(Phase::Error));
    }

    #[test]
    fn model_exchange_sequence() {
        assert_eq!(allowed_phases(Function::NewDiscreteStates), [Phase::EventMode]);
        assert_eq!(allowed_phases(Function::EnterContinuousTimeMode), [Phase::EventMode]);
        assert_eq!(allowed_phases(Function::SetContinuousStates), [Phase::ContinuousTimeMode]);
        assert_eq!(allowed_phases(Function::CompletedIntegratorStep), [Phase::ContinuousTimeMode]);
        assert_eq!(allowed_phases(Function::SetTime), [Phase::EventMode, Phase::ContinuousTimeMode]);
        assert!(!Function::SetInteger.allowed_in(Phase::ContinuousTimeMode), "only Reals change continuously");
        assert!(
            !Function::DoStep.allowed_in(Phase::EventMode) && !Function::DoStep.allowed_in(Phase::ContinuousTimeMode)
        );
        for function in [Function::SetTime, Function::GetDerivatives, Function::EnterEventMode] {
            assert!(!function.allowed_in(Phase::StepComplete), "{function:?} is model exchange only");
        }
    }

    #[test]
    fn cancel_step_is_never_legal() {
        assert!(allowed_phases(Function::CancelStep).is_empty());
    }
}
