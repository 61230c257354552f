//! Random sequences of FMI 3.0 calls on a co-simulation and a model
//! exchange instance of the servicer FMU (with actuators), with arbitrary arguments (value
//! references, value counts, values, times, states, FMU state handles):
//! every call returns a status, and every Float64 read with fmi3OK is finite.
#![no_main]

use arbitrary::Arbitrary;
use fmi_sys::fmi3::*;
use libfuzzer_sys::fuzz_target;
use nudyn_fmu::fmi3::*;
use nudyn_fuzz::servicer;

#[derive(Arbitrary, Debug)]
enum Call {
    EnterInitializationMode {
        tolerance: Option<f64>,
        start: f64,
        stop: Option<f64>,
    },
    ExitInitializationMode,
    SetFloat64 {
        vrs: Vec<u32>,
        values: Vec<f64>,
    },
    /// A buffer of 16 values per value reference, plus `extra` (or short of it, negative).
    GetFloat64 {
        vrs: Vec<u32>,
        extra: i8,
    },
    SetInt64 {
        vr: u32,
        value: i64,
    },
    GetInt64 {
        vr: u32,
    },
    SetBoolean {
        vr: u32,
        value: u8,
    },
    /// At the instance's last successful time plus `offset`.
    DoStep {
        offset: f64,
        step: f64,
    },
    EnterEventMode,
    UpdateDiscreteStates,
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
    Dependencies {
        vr: u32,
        short: u8,
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
    Reserialize {
        from: u8,
        to: u8,
        cut: u8,
    },
    Terminate,
    Reset,
}

#[derive(Arbitrary, Debug)]
struct Scenario {
    calls: Vec<(bool, Call)>,
}

const SLOTS: usize = 4;

fn all_finite(values: &[f64]) -> bool {
    values.iter().all(|v| v.is_finite())
}

fuzz_target!(|scenario: Scenario| {
    let fmu = servicer();
    // SAFETY: valid C strings; no logger.
    let instances = unsafe {
        let token = fmu.guid.as_ptr();
        let path = fmu.path.as_ptr();
        let none = std::ptr::null_mut();
        [
            fmi3InstantiateCoSimulation(
                c"cs".as_ptr(),
                token,
                path,
                false,
                false,
                false,
                false,
                std::ptr::null(),
                0,
                none,
                None,
                None,
            ),
            fmi3InstantiateModelExchange(c"me".as_ptr(), token, path, false, false, none, None),
        ]
    };
    assert!(instances.iter().all(|c| !c.is_null()), "both interfaces instantiate");
    let mut slots: [fmi3FMUState; SLOTS] = [std::ptr::null_mut(); SLOTS];
    // SAFETY: every array passed is at least as long as the count passed with it.
    unsafe {
        for (second, call) in scenario.calls.into_iter().take(64) {
            // A state handle may be used with the other instance: it must be refused, not read.
            let c = instances[usize::from(second)];
            match call {
                Call::EnterInitializationMode { tolerance, start, stop } => {
                    let (t, s) = (tolerance.unwrap_or(0.0), stop.unwrap_or(0.0));
                    fmi3EnterInitializationMode(c, tolerance.is_some(), t, start, stop.is_some(), s);
                }
                Call::ExitInitializationMode => _ = fmi3ExitInitializationMode(c),
                Call::SetFloat64 { vrs, values } => {
                    fmi3SetFloat64(c, vrs.as_ptr(), vrs.len(), values.as_ptr(), values.len());
                }
                Call::GetFloat64 { vrs, extra } => {
                    let n = (vrs.len() * 16).saturating_add_signed(isize::from(extra));
                    let mut values = vec![0.0; n];
                    if fmi3GetFloat64(c, vrs.as_ptr(), vrs.len(), values.as_mut_ptr(), n) == fmi3Status_fmi3OK {
                        assert!(all_finite(&values), "fmi3GetFloat64({vrs:?}) = {values:?}");
                    }
                }
                Call::SetInt64 { vr, value } => _ = fmi3SetInt64(c, &vr, 1, &value, 1),
                Call::GetInt64 { vr } => {
                    let mut value = 0;
                    fmi3GetInt64(c, &vr, 1, &mut value, 1);
                }
                Call::SetBoolean { vr, value } => {
                    // Any byte: the FMU reads C bools as bytes.
                    fmi3SetBoolean(c, &vr, 1, (&value as *const u8).cast(), 1);
                }
                Call::DoStep { offset, step } => {
                    let (mut event, mut terminate, mut early, mut last) = (false, false, false, 0.0);
                    let mut time = [0.0];
                    fmi3GetFloat64(c, &0, 1, time.as_mut_ptr(), 1);
                    fmi3DoStep(c, time[0] + offset, step, true, &mut event, &mut terminate, &mut early, &mut last);
                }
                Call::EnterEventMode => _ = fmi3EnterEventMode(c),
                Call::UpdateDiscreteStates => {
                    let mut flags = [false; 5];
                    let mut next = 0.0;
                    let [a, b, d, e, f] = &mut flags;
                    fmi3UpdateDiscreteStates(c, a, b, d, e, f, &mut next);
                }
                Call::EnterContinuousTimeMode => _ = fmi3EnterContinuousTimeMode(c),
                Call::CompletedIntegratorStep => {
                    let (mut event, mut terminate) = (false, false);
                    fmi3CompletedIntegratorStep(c, true, &mut event, &mut terminate);
                }
                Call::SetTime { time } => _ = fmi3SetTime(c, time),
                Call::SetContinuousStates { x } => _ = fmi3SetContinuousStates(c, x.as_ptr(), x.len()),
                Call::GetContinuousStates { n } => {
                    let mut x = vec![0.0; usize::from(n)];
                    fmi3GetContinuousStates(c, x.as_mut_ptr(), x.len());
                }
                Call::GetDerivatives { n } => {
                    let mut dx = vec![0.0; usize::from(n)];
                    if fmi3GetContinuousStateDerivatives(c, dx.as_mut_ptr(), dx.len()) == fmi3Status_fmi3OK {
                        assert!(all_finite(&dx), "derivatives {dx:?}");
                    }
                }
                Call::Dependencies { vr, short } => {
                    let mut n = 0;
                    if fmi3GetNumberOfVariableDependencies(c, vr, &mut n) == fmi3Status_fmi3OK {
                        let n = n.saturating_sub(usize::from(short % 2));
                        let (mut elements, mut knowns) = (vec![0; n], vec![0; n]);
                        let (mut known_elements, mut kinds) = (vec![0; n], vec![0; n]);
                        let (e, k, ke, d) = (
                            elements.as_mut_ptr(),
                            knowns.as_mut_ptr(),
                            known_elements.as_mut_ptr(),
                            kinds.as_mut_ptr(),
                        );
                        fmi3GetVariableDependencies(c, vr, e, k, ke, d, n);
                    }
                }
                Call::GetState { slot } => _ = fmi3GetFMUState(c, &mut slots[usize::from(slot) % SLOTS]),
                Call::SetState { slot } => _ = fmi3SetFMUState(c, slots[usize::from(slot) % SLOTS]),
                Call::FreeState { slot } => _ = fmi3FreeFMUState(c, &mut slots[usize::from(slot) % SLOTS]),
                Call::Reserialize { from, to, cut } => {
                    let mut size = 0;
                    let from = slots[usize::from(from) % SLOTS];
                    if fmi3SerializedFMUStateSize(c, from, &mut size) == fmi3Status_fmi3OK {
                        let mut blob = vec![0u8; size];
                        fmi3SerializeFMUState(c, from, blob.as_mut_ptr(), size);
                        let kept = size.saturating_sub(usize::from(cut));
                        fmi3DeserializeFMUState(c, blob.as_ptr(), kept, &mut slots[usize::from(to) % SLOTS]);
                    }
                }
                Call::Terminate => _ = fmi3Terminate(c),
                Call::Reset => _ = fmi3Reset(c),
            }
        }
        for c in instances {
            // Unfreed states go with their instance.
            fmi3FreeInstance(c);
        }
    }
});
