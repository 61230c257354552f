//! `Simulation`: the one object that advances a vehicle over time for the
//! FMU, `nudyn simulate` and the benchmarks. Intervals compose, the input
//! convention is a hold from the advance's start, a restored state repeats
//! its run exactly, and initialization checks and normalizes θ.

use std::path::Path;

use nudyn::integrate::{HeldJacobian, Input, Method, Settings, Simulation};
use nudyn::model::Model;

fn bus() -> Model {
    let imported = nudyn::mjcf::load_mjcf(Path::new("examples/bus_arm7.xml")).unwrap();
    Model::compile(&imported.vehicle).unwrap()
}

/// A moving start: every dof spinning.
fn moving(model: &Model, method: Method, settings: Settings) -> Simulation {
    let mut sim = Simulation::new(model, method, settings);
    sim.state.nu.iter_mut().enumerate().for_each(|(k, x)| *x = 0.3 * (k as f64 + 1.0).cos());
    sim.initialize(model).unwrap();
    sim
}

const RK4: Settings = Settings { tolerance: 1.0, max_step: 1e-3, energy_projection: false };
const ADAPTIVE: Settings = Settings { tolerance: 1e-9, max_step: 0.05, energy_projection: false };

#[test]
fn one_advance_equals_two_halves_with_fixed_steps() {
    let model = bus();
    let eps = vec![0.2; model.nv];
    let zero = vec![0.0; model.nv];
    let input = Input { eps: &eps, eps_rate: &zero, ctrl: &[], ctrl_rate: &[] };
    let mut whole = moving(&model, Method::Rk4, RK4);
    let mut halves = whole.clone();
    whole.advance_to(&model, 4e-3, input).unwrap();
    halves.advance_to(&model, 2e-3, input).unwrap();
    halves.advance_to(&model, 4e-3, input).unwrap();
    assert_eq!(whole.state.theta, halves.state.theta);
    assert_eq!(whole.state.nu, halves.state.nu);
    assert_eq!(whole.state.time, 4e-3);
}

#[test]
fn the_input_ramp_is_measured_from_the_start_of_each_advance() {
    let model = bus();
    let (eps, rate): (Vec<f64>, Vec<f64>) = (0..model.nv).map(|k| (0.1 * k as f64, 2.0 - 0.3 * k as f64)).unzip();
    let h = 2e-3;
    // ε(t) = eps + rate·t as a function of absolute time, in one advance ...
    let mut absolute = moving(&model, Method::Rk4, RK4);
    let signal = |t: f64, out: &mut [f64]| {
        out.iter_mut().zip(&eps).zip(&rate).for_each(|((o, e), r)| *o = e + r * t);
    };
    absolute.advance_to(&model, 2.0 * h, signal).unwrap();
    // ... and as two holds, the second from ε(h) with the same rate.
    let mut held = moving(&model, Method::Rk4, RK4);
    held.advance_to(&model, h, Input { eps: &eps, eps_rate: &rate, ctrl: &[], ctrl_rate: &[] }).unwrap();
    let eps_at_h: Vec<f64> = eps.iter().zip(&rate).map(|(e, r)| e + r * h).collect();
    held.advance_to(&model, 2.0 * h, Input { eps: &eps_at_h, eps_rate: &rate, ctrl: &[], ctrl_rate: &[] }).unwrap();
    for (a, b) in
        absolute.state.theta.iter().chain(&absolute.state.nu).zip(held.state.theta.iter().chain(&held.state.nu))
    {
        assert!((a - b).abs() <= 1e-14 * (1.0 + a.abs()), "{a} against {b}");
    }
    // A rate that is ignored would leave ν where a constant ε puts it.
    let mut constant = moving(&model, Method::Rk4, RK4);
    let zero = vec![0.0; model.nv];
    constant.advance_to(&model, 2.0 * h, Input { eps: &eps, eps_rate: &zero, ctrl: &[], ctrl_rate: &[] }).unwrap();
    let moved = constant.state.nu.iter().zip(&held.state.nu).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(moved > 1e-7, "the ramp changed ν by only {moved}");
}

#[test]
fn a_restored_state_repeats_its_run_exactly() {
    let model = bus();
    let eps = vec![0.05; model.nv];
    let zero = vec![0.0; model.nv];
    let input = Input { eps: &eps, eps_rate: &zero, ctrl: &[], ctrl_rate: &[] };
    let mut sim = moving(&model, Method::Dop853, ADAPTIVE);
    sim.advance_to(&model, 0.1, input).unwrap();
    let saved = sim.state.clone();
    sim.advance_to(&model, 0.3, input).unwrap();
    let first = sim.state.clone();
    sim.restore(&model, &saved, &HeldJacobian::default());
    sim.advance_to(&model, 0.3, input).unwrap();
    assert_eq!(sim.state, first, "same steps, same carried step size, same result");
    assert!(first.carry.next_step > 0.0);
}

/// ROS34PW2 keeps its W from one advance to the next, and a state restored
/// with the W saved beside it repeats the run bit for bit; restored without
/// it, the run forms W at another step and ends elsewhere.
#[test]
fn a_rosenbrock_run_carries_w_across_advances_and_restores_it() {
    let model = bus();
    let eps = vec![0.05; model.nv];
    let zero = vec![0.0; model.nv];
    let input = Input { eps: &eps, eps_rate: &zero, ctrl: &[], ctrl_rate: &[] };
    let settings = Settings { tolerance: 1e-5, max_step: 0.0, energy_projection: false };
    let mut sim = moving(&model, Method::Ros34pw2, settings);
    let (mut advances, mut formed) = (0, 0);
    for k in 1..=20 {
        formed += sim.advance_to(&model, 0.01 * k as f64, input).unwrap().stats.jacobians;
        advances += 1;
    }
    assert!(formed < advances / 2, "W formed {formed} times in {advances} advances");
    let saved = sim.state.clone();
    let mut w = HeldJacobian::default();
    sim.save_jacobian(&mut w);
    assert_eq!(w.derivatives.len(), 2 * model.nv * model.nv);
    let end = 0.2 + 0.05;
    sim.advance_to(&model, end, input).unwrap();
    let first = sim.state.clone();
    sim.restore(&model, &saved, &w);
    sim.advance_to(&model, end, input).unwrap();
    assert_eq!(sim.state, first, "restored with its W");
    sim.restore(&model, &saved, &HeldJacobian::default());
    sim.advance_to(&model, end, input).unwrap();
    assert_ne!(sim.state.theta, first.theta, "restored without W, which is then formed at the advance's start");
}

#[test]
fn initialization_normalizes_quaternions_and_refuses_non_finite_states() {
    let model = bus();
    let mut sim = Simulation::new(&model, Method::Rk4, RK4);
    // The free joint's quaternion is θ[3..7].
    sim.state.theta[3..7].copy_from_slice(&[2.0, 0.0, 0.0, 0.0]);
    sim.initialize(&model).unwrap();
    assert_eq!(&sim.state.theta[3..7], &[1.0, 0.0, 0.0, 0.0]);
    sim.state.nu[2] = f64::NAN;
    assert!(sim.initialize(&model).is_err());
    sim.state.nu[2] = 0.0;
    sim.state.theta[3..7].fill(0.0);
    assert!(sim.initialize(&model).is_err(), "a zero quaternion is no rotation");
}
