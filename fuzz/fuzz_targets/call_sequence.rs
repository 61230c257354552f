//! Random sequences of FMI 2.0 calls on three instances of the servicer FMU (with actuators), two
//! for co-simulation and one for model exchange, with arbitrary arguments
//! (value references, values, times, step sizes, continuous states, FMU
//! state handles): every call returns a status, and every Real value or
//! derivative read with fmi2OK is finite.
#![no_main]

use arbitrary::Arbitrary;
use fmi_sys::fmi2::*;
use libfuzzer_sys::fuzz_target;
use nudyn_fmu::fmi2::*;
use nudyn_fuzz::{check_reals, instantiate, instantiate_as, servicer};

#[derive(Arbitrary, Debug)]
enum Call {
    SetupExperiment {
        tolerance: Option<f64>,
        start: f64,
        stop: Option<f64>,
    },
    EnterInitializationMode,
    ExitInitializationMode,
    SetReal {
        vrs: Vec<u32>,
        values: Vec<f64>,
    },
    GetReal {
        vrs: Vec<u32>,
    },
    SetInteger {
        vr: u32,
        value: i32,
    },
    GetInteger {
        vr: u32,
    },
    SetInputDerivative {
        vr: u32,
        order: i32,
        value: f64,
    },
    GetOutputDerivative {
        vr: u32,
        order: i32,
    },
    /// At the instance's last successful time plus `offset`.
    DoStep {
        offset: f64,
        step: f64,
    },
    CancelStep,
    GetStatus {
        kind: u32,
    },
    GetState {
        slot: u8,
    },
    SetState {
        slot: u8,
    },
    FreeState {
        slot: u8,
    },
    /// Serializes a slot's state, truncated by `cut` bytes, into another slot.
    Reserialize {
        from: u8,
        to: u8,
        cut: u8,
    },
    SetDebugLogging {
        on: bool,
        category: u8,
    },
    Terminate,
    Reset,
    EnterEventMode,
    NewDiscreteStates,
    EnterContinuousTimeMode,
    CompletedIntegratorStep,
    SetTime {
        time: f64,
    },
    SetContinuousStates {
        x: Vec<f64>,
    },
    GetContinuousStates {
        n: u8,
    },
    GetDerivatives {
        n: u8,
    },
    GetNominals {
        n: u8,
    },
    GetEventIndicators {
        n: u8,
    },
}

#[derive(Arbitrary, Debug)]
struct Scenario {
    /// The instance: 0 and 1 co-simulation, 2 model exchange (the rest wrap).
    calls: Vec<(u8, Call)>,
}

const SLOTS: usize = 4;

fuzz_target!(|scenario: Scenario| {
    let fmu = servicer();
    let instances = [
        instantiate(&fmu.uri, &fmu.guid),
        instantiate(&fmu.uri, &fmu.guid),
        instantiate_as(fmi2Type_fmi2ModelExchange, &fmu.uri, &fmu.guid),
    ];
    let mut slots: [fmi2FMUstate; SLOTS] = [std::ptr::null_mut(); SLOTS];
    // SAFETY: the arrays passed are as long as the counts; instances live until the end.
    unsafe {
        for (which, call) in scenario.calls.into_iter().take(64) {
            // A state handle may be used with another instance: it must be refused, not read.
            let c = instances[usize::from(which) % instances.len()];
            match call {
                Call::SetupExperiment { tolerance, start, stop } => {
                    fmi2SetupExperiment(
                        c,
                        tolerance.is_some().into(),
                        tolerance.unwrap_or(0.0),
                        start,
                        stop.is_some().into(),
                        stop.unwrap_or(0.0),
                    );
                }
                Call::EnterInitializationMode => _ = fmi2EnterInitializationMode(c),
                Call::ExitInitializationMode => _ = fmi2ExitInitializationMode(c),
                Call::SetReal { vrs, values } => {
                    let n = vrs.len().min(values.len());
                    fmi2SetReal(c, vrs.as_ptr(), n, values.as_ptr());
                }
                Call::GetReal { vrs } => {
                    let mut values = vec![0.0; vrs.len()];
                    if fmi2GetReal(c, vrs.as_ptr(), vrs.len(), values.as_mut_ptr()) == fmi2Status_fmi2OK {
                        assert!(values.iter().all(|v| v.is_finite()), "fmi2GetReal({vrs:?}) = {values:?}");
                    }
                }
                Call::SetInteger { vr, value } => _ = fmi2SetInteger(c, &vr, 1, &value),
                Call::GetInteger { vr } => {
                    let mut value = 0;
                    fmi2GetInteger(c, &vr, 1, &mut value);
                }
                Call::SetInputDerivative { vr, order, value } => {
                    _ = fmi2SetRealInputDerivatives(c, &vr, 1, &order, &value)
                }
                Call::GetOutputDerivative { vr, order } => {
                    let mut value = 0.0;
                    if fmi2GetRealOutputDerivatives(c, &vr, 1, &order, &mut value) == fmi2Status_fmi2OK {
                        assert!(value.is_finite(), "derivative of {vr} = {value}");
                    }
                }
                Call::DoStep { offset, step } => {
                    let mut time = 0.0;
                    fmi2GetRealStatus(c, fmi2StatusKind_fmi2LastSuccessfulTime, &mut time);
                    fmi2DoStep(c, time + offset, step, 1);
                }
                Call::CancelStep => _ = fmi2CancelStep(c),
                Call::GetStatus { kind } => {
                    let (mut status, mut real, mut boolean) = (0, 0.0, 0);
                    fmi2GetStatus(c, kind, &mut status);
                    fmi2GetRealStatus(c, kind, &mut real);
                    fmi2GetBooleanStatus(c, kind, &mut boolean);
                }
                Call::GetState { slot } => _ = fmi2GetFMUstate(c, &mut slots[usize::from(slot) % SLOTS]),
                Call::SetState { slot } => _ = fmi2SetFMUstate(c, slots[usize::from(slot) % SLOTS]),
                Call::FreeState { slot } => _ = fmi2FreeFMUstate(c, &mut slots[usize::from(slot) % SLOTS]),
                Call::Reserialize { from, to, cut } => {
                    let mut size = 0;
                    let from = slots[usize::from(from) % SLOTS];
                    if fmi2SerializedFMUstateSize(c, from, &mut size) == fmi2Status_fmi2OK {
                        let mut blob = vec![0u8; size];
                        fmi2SerializeFMUstate(c, from, blob.as_mut_ptr() as *mut fmi2Byte, size);
                        let kept = size.saturating_sub(usize::from(cut));
                        fmi2DeSerializeFMUstate(
                            c,
                            blob.as_ptr() as *const fmi2Byte,
                            kept,
                            &mut slots[usize::from(to) % SLOTS],
                        );
                    }
                }
                Call::SetDebugLogging { on, category } => {
                    let names = [c"logCalls".as_ptr(), c"logStatusError".as_ptr(), c"nonsense".as_ptr()];
                    let n = usize::from(category) % (names.len() + 1);
                    fmi2SetDebugLogging(c, on.into(), n, names.as_ptr());
                }
                Call::Terminate => _ = fmi2Terminate(c),
                Call::Reset => _ = fmi2Reset(c),
                Call::EnterEventMode => _ = fmi2EnterEventMode(c),
                Call::NewDiscreteStates => {
                    let mut info = std::mem::zeroed::<fmi2EventInfo>();
                    fmi2NewDiscreteStates(c, &mut info);
                }
                Call::EnterContinuousTimeMode => _ = fmi2EnterContinuousTimeMode(c),
                Call::CompletedIntegratorStep => {
                    let (mut event, mut terminate) = (0, 0);
                    fmi2CompletedIntegratorStep(c, 1, &mut event, &mut terminate);
                }
                Call::SetTime { time } => _ = fmi2SetTime(c, time),
                Call::SetContinuousStates { x } => _ = fmi2SetContinuousStates(c, x.as_ptr(), x.len()),
                Call::GetContinuousStates { n } => {
                    let mut x = vec![0.0; usize::from(n)];
                    fmi2GetContinuousStates(c, x.as_mut_ptr(), x.len());
                }
                Call::GetDerivatives { n } => {
                    let mut dx = vec![0.0; usize::from(n)];
                    if fmi2GetDerivatives(c, dx.as_mut_ptr(), dx.len()) == fmi2Status_fmi2OK {
                        assert!(dx.iter().all(|d| d.is_finite()), "derivatives {dx:?}");
                    }
                }
                Call::GetNominals { n } => {
                    let mut nominals = vec![0.0; usize::from(n)];
                    fmi2GetNominalsOfContinuousStates(c, nominals.as_mut_ptr(), nominals.len());
                }
                Call::GetEventIndicators { n } => {
                    let mut indicators = vec![0.0; usize::from(n)];
                    fmi2GetEventIndicators(c, indicators.as_mut_ptr(), indicators.len());
                }
            }
        }
        for c in instances {
            check_reals(c, fmu.reals);
            // Unfreed states go with their instance.
            fmi2FreeInstance(c);
        }
    }
});
