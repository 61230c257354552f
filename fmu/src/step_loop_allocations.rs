//! The loops a host runs, at every communication point in co-simulation
//! (set ε, doStep, get θ and ν; for the controller FMU set θ and ν, doStep,
//! get ε) and at every step of its own integrator in model exchange (set
//! time and states, get the derivatives), allocate nothing once the
//! instance has made its first steps: a global allocator counts this
//! thread's allocations.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use fmi_sys::fmi2::*;
use fmi_sys::fmi3::*;
use nudyn_contract::controller::ControllerVariable;
use nudyn_contract::plant::RealVariable;

use crate::fmi2::*;
use crate::fmi3::*;
use crate::layer::Instance;

struct CountingAllocator;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.with(|n| n.set(n.get() + 1));
        }
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

/// The allocations `steps` calls of `step` make, after two uncounted ones
/// (the first step sizes the integrator's start; a host's first reads may
/// size scratch buffers).
fn allocations(steps: usize, mut step: impl FnMut(usize)) -> usize {
    step(0);
    step(1);
    ALLOCATIONS.with(|n| n.set(0));
    COUNTING.with(|c| c.set(true));
    for k in 2..2 + steps {
        step(k);
    }
    COUNTING.with(|c| c.set(false));
    ALLOCATIONS.with(Cell::get)
}

const STEP: f64 = 0.01;
/// The flexible spacecraft's tolerance in the ros34pw2 loop: at 1e-9 its stiff
/// modes took 100 s of steps; at 1e-5 W is still formed within the counted steps.
const TOLERANCE_FLEX: f64 = 1e-5;

/// bus_arm7: 14 positions, 13 dofs.
const NQ: usize = 14;
const NV: usize = 13;

/// An initialized FMI 2.0 instance of `kind` of the resources in `dir`.
fn fmi2_instance(kind: fmi2Type, dir: &std::path::Path, guid: &std::ffi::CStr) -> fmi2Component {
    let c = crate::test_resources::instantiate_fmi2(kind, &crate::test_resources::uri(dir), guid);
    assert!(!c.is_null());
    unsafe {
        assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), fmi2Status_fmi2OK);
        assert_eq!(fmi2EnterInitializationMode(c), fmi2Status_fmi2OK);
        assert_eq!(fmi2ExitInitializationMode(c), fmi2Status_fmi2OK);
    }
    c
}

/// The resource path of bus_arm7 for an FMI 3.0 instance, and its token.
fn fmi3_resources(test: &str) -> (std::ffi::CString, std::ffi::CString) {
    let (dir, guid, _) = crate::test_resources::write("bus_arm7", test);
    (std::ffi::CString::new(format!("{}/", dir.display())).expect("no NUL"), guid)
}

#[test]
fn the_fmi2_step_loop_does_not_allocate() {
    let (dir, guid, layout) = crate::test_resources::write("bus_arm7", "fmi2-loop");
    let c = fmi2_instance(fmi2Type_fmi2CoSimulation, &dir, &guid);
    let vrs = |variable: fn(usize) -> RealVariable, n: usize| -> Vec<u32> {
        (0..n).map(|k| layout.value_reference(variable(k)).expect("declared")).collect()
    };
    let (theta, nu, eps) = (vrs(RealVariable::Theta, NQ), vrs(RealVariable::Nu, NV), vrs(RealVariable::Eps, NV));
    let (mut read, mut input) = (vec![0.0; NQ], vec![0.0; NV]);
    unsafe {
        let count = allocations(20, |k| {
            input.iter_mut().enumerate().for_each(|(i, e)| *e = 0.1 * ((k + i) as f64).sin());
            assert_eq!(fmi2SetReal(c, eps.as_ptr(), eps.len(), input.as_ptr()), fmi2Status_fmi2OK);
            assert_eq!(fmi2DoStep(c, k as f64 * STEP, STEP, 1), fmi2Status_fmi2OK);
            assert_eq!(fmi2GetReal(c, theta.as_ptr(), theta.len(), read.as_mut_ptr()), fmi2Status_fmi2OK);
            assert_eq!(fmi2GetReal(c, nu.as_ptr(), nu.len(), read.as_mut_ptr()), fmi2Status_fmi2OK);
        });
        fmi2FreeInstance(c);
        assert_eq!(count, 0, "allocations in 20 communication steps");
    }
}

/// With `ros34pw2`: forming W allocates nothing either, in closed form
/// (its default where it covers the vehicle: bus_arm7 without and with ε,
/// the servicer with its actuators) and by forward differences (the
/// flexible spacecraft, whose modes the closed form does not cover). The
/// tolerance is tight enough that W is formed again within the counted
/// steps as it ages (checked on the same runs outside the FMU).
#[test]
fn the_fmi2_step_loop_with_ros34pw2_does_not_allocate() {
    let cases = [
        ("bus_arm7", 0.0, 1e-9, true),
        ("bus_arm7", 0.2, 1e-9, true),
        ("servicer", 0.2, 1e-9, true),
        ("flexible_spacecraft/flexible_spacecraft", 0.2, TOLERANCE_FLEX, false),
    ];
    for (example, eps, tolerance, closed_form) in cases {
        ros34pw2_loop_allocates_nothing(example, eps, tolerance, closed_form);
    }
}

fn ros34pw2_loop_allocates_nothing(example: &str, eps_value: f64, tolerance: f64, closed_form: bool) {
    let label = format!("{example}, ε {eps_value}");
    let nv = crate::test_resources::model(example).nv;
    let (dir, guid, layout) =
        crate::test_resources::write(example, &format!("fmi2-loop-ros34pw2-{example}-{eps_value}"));
    let c =
        crate::test_resources::instantiate_fmi2(fmi2Type_fmi2CoSimulation, &crate::test_resources::uri(&dir), &guid);
    assert!(!c.is_null());
    let method = [nudyn_contract::plant::method_value(nudyn::integrate::Method::Ros34pw2)];
    let tolerance_vr = [layout.value_reference(RealVariable::Tolerance).expect("declared")];
    let vrs = |variable: fn(usize) -> RealVariable| -> Vec<u32> {
        (0..nv).map(|k| layout.value_reference(variable(k)).expect("declared")).collect()
    };
    let (nu_vr, eps_vr) = (vrs(RealVariable::Nu), vrs(RealVariable::Eps));
    let spin: Vec<f64> = (0..nv).map(|k| 0.3 * (k as f64 + 1.0).cos()).collect();
    let eps = vec![eps_value; nv];
    let mut read = vec![0.0; nv];
    unsafe {
        assert_eq!(
            fmi2SetInteger(c, [nudyn_contract::plant::METHOD_VR].as_ptr(), 1, method.as_ptr()),
            fmi2Status_fmi2OK
        );
        assert_eq!(fmi2SetReal(c, tolerance_vr.as_ptr(), 1, [tolerance].as_ptr()), fmi2Status_fmi2OK);
        assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), fmi2Status_fmi2OK);
        assert_eq!(fmi2EnterInitializationMode(c), fmi2Status_fmi2OK);
        assert_eq!(fmi2SetReal(c, nu_vr.as_ptr(), nv, spin.as_ptr()), fmi2Status_fmi2OK);
        assert_eq!(fmi2ExitInitializationMode(c), fmi2Status_fmi2OK);
        assert_eq!(fmi2SetReal(c, eps_vr.as_ptr(), nv, eps.as_ptr()), fmi2Status_fmi2OK);
        let count = allocations(20, |k| {
            assert_eq!(fmi2DoStep(c, k as f64 * STEP, STEP, 1), fmi2Status_fmi2OK);
            assert_eq!(fmi2GetReal(c, nu_vr.as_ptr(), nv, read.as_mut_ptr()), fmi2Status_fmi2OK);
        });
        fmi2FreeInstance(c);
        assert_eq!(count, 0, "{label}: allocations in 20 communication steps");
    }
    let model = crate::test_resources::model(example);
    let settings = nudyn::integrate::Settings { tolerance, max_step: 0.0, energy_projection: false };
    let mut sim = nudyn::integrate::Simulation::new(&model, nudyn::integrate::Method::Ros34pw2, settings);
    sim.state.nu.copy_from_slice(&spin);
    sim.initialize(&model).unwrap();
    let (mut formed, mut exact) = (0, 0);
    for k in 0..22 {
        let stats =
            sim.advance_to(&model, (k + 1) as f64 * STEP, |_: f64, e: &mut [f64]| e.fill(eps_value)).unwrap().stats;
        if k >= 2 {
            (formed, exact) = (formed + stats.jacobians, exact + stats.exact_jacobians);
        }
    }
    let expected_exact = if closed_form { formed } else { 0 };
    assert!(
        formed > 0 && exact == expected_exact,
        "{label}: W formed {formed} times in the counted steps, {exact} exactly"
    );
}

#[test]
fn the_fmi3_step_loop_does_not_allocate() {
    let (path, token) = fmi3_resources("fmi3-loop");
    let (mut read, mut input) = (vec![0.0; NQ], vec![0.0; NV]);
    unsafe {
        let instance = fmi3InstantiateCoSimulation(
            c"loop".as_ptr(),
            token.as_ptr(),
            path.as_ptr(),
            false,
            false,
            false,
            false,
            std::ptr::null(),
            0,
            std::ptr::null_mut(),
            None,
            None,
        );
        assert!(!instance.is_null());
        let table = &(*(instance as *const Instance)).fmi3;
        let vr = |name: &str| [table.value_reference(name).expect("declared")];
        let (theta, nu, eps) = (vr("theta"), vr("nu"), vr("eps"));
        assert_eq!(fmi3EnterInitializationMode(instance, false, 0.0, 0.0, false, 0.0), fmi3Status_fmi3OK);
        assert_eq!(fmi3ExitInitializationMode(instance), fmi3Status_fmi3OK);
        let (mut event, mut terminate, mut early, mut reached) = (false, false, false, 0.0);
        let count = allocations(20, |k| {
            input.iter_mut().enumerate().for_each(|(i, e)| *e = 0.1 * ((k + i) as f64).sin());
            assert_eq!(fmi3SetFloat64(instance, eps.as_ptr(), 1, input.as_ptr(), NV), fmi3Status_fmi3OK);
            let status =
                fmi3DoStep(instance, k as f64 * STEP, STEP, true, &mut event, &mut terminate, &mut early, &mut reached);
            assert_eq!(status, fmi3Status_fmi3OK);
            assert_eq!(fmi3GetFloat64(instance, theta.as_ptr(), 1, read.as_mut_ptr(), NQ), fmi3Status_fmi3OK);
            assert_eq!(fmi3GetFloat64(instance, nu.as_ptr(), 1, read.as_mut_ptr(), NV), fmi3Status_fmi3OK);
        });
        fmi3FreeInstance(instance);
        assert_eq!(count, 0, "allocations in 20 communication steps");
    }
}

/// Explicit Euler steps of `STEP` through `set_time`, `get_states`,
/// `get_derivatives`, `set_states` and `completed`, counted as `allocations`
/// counts them.
fn euler_allocations(
    mut set_time: impl FnMut(f64),
    mut get_states: impl FnMut(&mut [f64]),
    mut get_derivatives: impl FnMut(&mut [f64]),
    mut set_states: impl FnMut(&[f64]),
    mut completed: impl FnMut(),
) -> usize {
    let (mut x, mut dx) = (vec![0.0; NQ + NV], vec![0.0; NQ + NV]);
    allocations(20, |k| {
        set_time(k as f64 * STEP);
        get_states(&mut x);
        get_derivatives(&mut dx);
        x.iter_mut().zip(&dx).for_each(|(x, dx)| *x += STEP * dx);
        set_time((k + 1) as f64 * STEP);
        set_states(&x);
        completed();
    })
}

#[test]
fn the_fmi2_model_exchange_loop_does_not_allocate() {
    let (dir, guid, _) = crate::test_resources::write("bus_arm7", "fmi2-me-loop");
    let c = fmi2_instance(fmi2Type_fmi2ModelExchange, &dir, &guid);
    unsafe {
        let mut event_info: fmi2EventInfo = std::mem::zeroed();
        assert_eq!(fmi2NewDiscreteStates(c, &mut event_info), fmi2Status_fmi2OK);
        assert_eq!(fmi2EnterContinuousTimeMode(c), fmi2Status_fmi2OK);
        let (mut enter_event_mode, mut terminate) = (0, 0);
        let count = euler_allocations(
            |t| assert_eq!(fmi2SetTime(c, t), fmi2Status_fmi2OK),
            |x| assert_eq!(fmi2GetContinuousStates(c, x.as_mut_ptr(), x.len()), fmi2Status_fmi2OK),
            |dx| assert_eq!(fmi2GetDerivatives(c, dx.as_mut_ptr(), dx.len()), fmi2Status_fmi2OK),
            |x| assert_eq!(fmi2SetContinuousStates(c, x.as_ptr(), x.len()), fmi2Status_fmi2OK),
            || {
                let status = fmi2CompletedIntegratorStep(c, 1, &mut enter_event_mode, &mut terminate);
                assert_eq!(status, fmi2Status_fmi2OK);
            },
        );
        fmi2FreeInstance(c);
        assert_eq!(count, 0, "allocations in 20 integrator steps");
    }
}

#[test]
fn the_fmi3_model_exchange_loop_does_not_allocate() {
    let (path, token) = fmi3_resources("fmi3-me-loop");
    unsafe {
        let instance = fmi3InstantiateModelExchange(
            c"loop".as_ptr(),
            token.as_ptr(),
            path.as_ptr(),
            false,
            false,
            std::ptr::null_mut(),
            None,
        );
        assert!(!instance.is_null());
        assert_eq!(fmi3EnterInitializationMode(instance, false, 0.0, 0.0, false, 0.0), fmi3Status_fmi3OK);
        assert_eq!(fmi3ExitInitializationMode(instance), fmi3Status_fmi3OK);
        let [mut a, mut b, mut c, mut d, mut e] = [false; 5];
        let mut next_event_time = 0.0;
        let status = fmi3UpdateDiscreteStates(instance, &mut a, &mut b, &mut c, &mut d, &mut e, &mut next_event_time);
        assert_eq!(status, fmi3Status_fmi3OK);
        assert_eq!(fmi3EnterContinuousTimeMode(instance), fmi3Status_fmi3OK);
        let (mut enter_event_mode, mut terminate) = (false, false);
        let count = euler_allocations(
            |t| assert_eq!(fmi3SetTime(instance, t), fmi3Status_fmi3OK),
            |x| assert_eq!(fmi3GetContinuousStates(instance, x.as_mut_ptr(), x.len()), fmi3Status_fmi3OK),
            |dx| assert_eq!(fmi3GetContinuousStateDerivatives(instance, dx.as_mut_ptr(), dx.len()), fmi3Status_fmi3OK),
            |x| assert_eq!(fmi3SetContinuousStates(instance, x.as_ptr(), x.len()), fmi3Status_fmi3OK),
            || {
                let status = fmi3CompletedIntegratorStep(instance, true, &mut enter_event_mode, &mut terminate);
                assert_eq!(status, fmi3Status_fmi3OK);
            },
        );
        fmi3FreeInstance(instance);
        assert_eq!(count, 0, "allocations in 20 integrator steps");
    }
}

/// The controller FMU of bus_arm7 with its joints' law and with a pose law
/// of its bus: θ and ν in, ε out.
#[test]
fn the_controller_step_loop_does_not_allocate() {
    for (law, test) in [(None, "controller-joints-loop"), (Some("bus"), "controller-pose-loop")] {
        let (dir, guid, layout) = crate::test_resources::write_controller("bus_arm7", law, test);
        let vrs = |kind: fn(&ControllerVariable) -> bool| -> Vec<u32> {
            layout.variables().filter(|(_, v)| kind(v)).map(|(vr, _)| vr).collect()
        };
        let theta = vrs(|v| matches!(v, ControllerVariable::Theta(_)));
        let nu = vrs(|v| matches!(v, ControllerVariable::Nu(_)));
        let eps = vrs(|v| matches!(v, ControllerVariable::Eps(_)));
        assert_eq!((theta.len(), nu.len(), eps.len()), (NQ, NV, NV));
        let (mut state, mut read) = (vec![0.0; NQ], vec![0.0; NV]);
        let c = fmi2_instance(fmi2Type_fmi2CoSimulation, &dir, &guid);
        unsafe {
            let count = allocations(20, |k| {
                state.iter_mut().enumerate().for_each(|(i, x)| *x = 0.1 * ((k + i) as f64).sin());
                state[3] = 1.0; // the bus's quaternion, w first, near the identity
                assert_eq!(fmi2SetReal(c, theta.as_ptr(), NQ, state.as_ptr()), fmi2Status_fmi2OK);
                assert_eq!(fmi2SetReal(c, nu.as_ptr(), NV, state.as_ptr()), fmi2Status_fmi2OK);
                assert_eq!(fmi2DoStep(c, k as f64 * STEP, STEP, 1), fmi2Status_fmi2OK);
                assert_eq!(fmi2GetReal(c, eps.as_ptr(), NV, read.as_mut_ptr()), fmi2Status_fmi2OK);
            });
            fmi2FreeInstance(c);
            assert_eq!(count, 0, "allocations in 20 communication steps, law {law:?}");
        }
    }
}
