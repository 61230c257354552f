//! The FMI 2.0 co-simulation state machine (§4.2.4): the instance's states
//! and, per function, the states it may be called in.
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
}

impl Phase {
    /// Every state, in the order of their codes.
    pub const ALL: [Phase; 7] = [
        Phase::Instantiated,
        Phase::InitializationMode,
        Phase::StepComplete,
        Phase::StepFailed,
        Phase::Terminated,
        Phase::Error,
        Phase::Fatal,
    ];

    const fn bit(self) -> u8 {
        1 << self as u8
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
        }
    }
}

const INSTANTIATED: u8 = Phase::Instantiated.bit();
const INIT: u8 = Phase::InitializationMode.bit();
const STEP_COMPLETE: u8 = Phase::StepComplete.bit();
const STEP_FAILED: u8 = Phase::StepFailed.bit();
const TERMINATED: u8 = Phase::Terminated.bit();
const ERROR: u8 = Phase::Error.bit();
/// Every state in which the instance is still usable or inspectable.
const ALIVE: u8 = INSTANTIATED | INIT | STEP_COMPLETE | STEP_FAILED | TERMINATED | ERROR;

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
        }
    }

    /// The states in which the function may be called (FMI 2.0 §4.2.4).
    /// fmi2FreeInstance is not in the table: it is accepted in every state,
    /// `fatal` included, since releasing memory is always safe here and
    /// refusing would only leak it.
    fn allowed(self) -> u8 {
        match self {
            Function::SetDebugLogging | Function::Reset => ALIVE,
            Function::GetFmuState | Function::SetFmuState | Function::FreeFmuState => ALIVE,
            Function::SerializedFmuStateSize | Function::SerializeFmuState | Function::DeSerializeFmuState => ALIVE,
            Function::SetupExperiment | Function::EnterInitializationMode => INSTANTIATED,
            Function::ExitInitializationMode => INIT,
            Function::Terminate => STEP_COMPLETE | STEP_FAILED,
            Function::GetReal | Function::GetInteger | Function::GetBoolean | Function::GetString => {
                INIT | STEP_COMPLETE | STEP_FAILED | TERMINATED | ERROR
            }
            Function::GetDirectionalDerivative => INIT | STEP_COMPLETE | STEP_FAILED | TERMINATED | ERROR,
            Function::SetReal | Function::SetInteger | Function::SetBoolean | Function::SetString => {
                INSTANTIATED | INIT | STEP_COMPLETE
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
        }
    }

    /// Whether the function may be called in `phase`.
    pub fn allowed_in(self, phase: Phase) -> bool {
        self.allowed() & phase.bit() != 0
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
            [Phase::Instantiated, Phase::InitializationMode, Phase::StepComplete]
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
        assert_eq!(Phase::from_code(7), None);
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
    fn cancel_step_is_never_legal() {
        assert!(allowed_phases(Function::CancelStep).is_empty());
    }
}
