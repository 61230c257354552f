//! Steps past the communication point (docs/integration.md, "Steps past
//! the communication point"): with the inputs held, an adaptive method
//! with a dense output takes steps longer than the communication step on a
//! slow vehicle and delivers the tolerance at every communication point
//! from its interpolant; a change of input at a communication point takes
//! effect exactly there; a restored state continues bit for bit.

use std::path::Path;

use nudyn::dynamics::box_qp::Held;
use nudyn::integrate::{HeldJacobian, Input, Method, Settings, Simulation};
use nudyn::model::Model;

use crate::common::largest_relative_error;

/// Two arms on a 5000 kg base (tests/fixtures/slow_station.xml).
fn station() -> Model {
    let imported = nudyn::mjcf::load_mjcf(Path::new("tests/fixtures/slow_station.xml")).unwrap();
    Model::compile(&imported.vehicle).unwrap()
}

const COMMUNICATION_STEP: f64 = 0.1;
const POINTS: usize = 100;

fn settings(tolerance: f64) -> Settings {
    Settings { tolerance, max_step: 0.0, energy_projection: false }
}

/// The station turning at about 0.01 rad/s, its base drifting at 1 cm/s
/// and every arm joint off its drawn pose and turning at up to 0.05 rad/s.
fn slow_start(model: &Model, method: Method, tolerance: f64) -> Simulation {
    let base_rates = [0.01, -0.004, 0.006, 0.006, -0.004, 0.008];
    started(model, method, tolerance, base_rates, |k| (0.3 * (k as f64).sin(), 0.05 * (1.7 * k as f64).cos()))
}

/// A run of a free-based vehicle whose other joints all have one
/// coordinate per dof: the base at rest in its drawn pose with rates
/// `base_rates`, dof k ≥ 6 at (coordinate, rate) `joint(k)`, ν = m*θ̇.
fn started(
    model: &Model,
    method: Method,
    tolerance: f64,
    base_rates: [f64; 6],
    joint: impl Fn(usize) -> (f64, f64),
) -> Simulation {
    let mut sim = Simulation::new(model, method, settings(tolerance));
    let mut qvel = vec![0.0; model.nv];
    qvel[..6].copy_from_slice(&base_rates);
    // Dof k moves coordinate k + 1 (the free joint has 7 and 6).
    for (k, rate) in qvel.iter_mut().enumerate().skip(6) {
        (sim.state.theta[k + 1], *rate) = joint(k);
    }
    let mut ws = model.workspace();
    ws.set_configuration(model, &sim.state.theta).unwrap();
    ws.set_qvel(model, &qvel).unwrap();
    sim.state.nu.copy_from_slice(ws.nu.as_slice());
    sim.initialize(model).unwrap();
    sim
}

/// The run's end: no step passes it, so the last one ends at the last
/// communication point (an FMU's stop time).
const END: Option<f64> = Some(POINTS as f64 * COMMUNICATION_STEP);

/// ν of the state reported is m*(θ)θ̇ of its θ and θ̇ (interpolated or
/// not), to round-off.
fn assert_nu_is_the_states(sim: &Simulation, model: &Model) {
    let mut ws = model.workspace();
    ws.set_configuration(model, &sim.state.theta).unwrap();
    ws.set_qvel(model, &sim.state.qvel[..model.nv]).unwrap();
    for (formed, reported) in ws.nu.iter().zip(&sim.state.nu) {
        assert!((formed - reported).abs() <= 1e-13 * (1.0 + formed.abs()), "ν {reported}, m*θ̇ {formed}");
    }
}

/// ε on every dof: `before` before `switch_at`, `after` from there on
/// (a communication point; times are compared to within round-off).
struct Schedule {
    before: Vec<f64>,
    after: Vec<f64>,
    switch_at: f64,
}

impl Schedule {
    fn at(&self, t: f64) -> &[f64] {
        if t < self.switch_at - 1e-9 { &self.before } else { &self.after }
    }
}

/// (θ, ν) at each communication point, the steps taken, with ε held over
/// each communication step as a host holds it (the FMU's convention).
fn held_run(sim: &mut Simulation, model: &Model, schedule: &Schedule) -> (Vec<Vec<f64>>, usize) {
    let zero = vec![0.0; model.nv];
    let mut points = Vec::new();
    let mut steps = 0;
    for n in 1..=POINTS {
        let eps = schedule.at((n - 1) as f64 * COMMUNICATION_STEP);
        let input = Input { eps, eps_rate: &zero, ctrl: &[], ctrl_rate: &[] };
        let stats = sim.advance_to(model, n as f64 * COMMUNICATION_STEP, input).unwrap().stats;
        steps += stats.accepted;
        assert_nu_is_the_states(sim, model);
        points.push(sim.state.theta.iter().chain(&sim.state.nu).copied().collect());
    }
    (points, steps)
}

/// The reference: DOP853 at 1e-12 ending a step at every half
/// communication point (ε given as a function of time, so no step reaches
/// past one), so that its steps are not those of a run at one step per
/// communication step.
fn reference(model: &Model, schedule: &Schedule) -> Vec<Vec<f64>> {
    let mut sim = slow_start(model, Method::Dop853, 1e-12);
    let half = 0.5 * COMMUNICATION_STEP;
    let mut points = Vec::new();
    for n in 1..=2 * POINTS {
        let eps = schedule.at((n - 1) as f64 * half).to_vec();
        let signal = move |_: f64, out: &mut [f64]| out.copy_from_slice(&eps);
        sim.advance_to(model, n as f64 * half, signal).unwrap();
        if n % 2 == 0 {
            points.push(sim.state.theta.iter().chain(&sim.state.nu).copied().collect());
        }
    }
    points
}

/// The largest |x − x_ref| / (1 + |x_ref|) over the points and (θ, ν).
fn largest_error(points: &[Vec<f64>], reference: &[Vec<f64>]) -> f64 {
    largest_relative_error(points.iter().zip(reference).flat_map(|(p, r)| p.iter().zip(r)))
}

/// At 1e-4 each method with a dense output takes fewer steps than there
/// are communication points (today's floor was one per point), and its
/// interpolant delivers within [1/50, 20] times the tolerance.
#[test]
fn a_slow_vehicle_takes_fewer_steps_than_communication_points() {
    let model = station();
    let eps = vec![0.0; model.nv];
    let schedule = Schedule { before: eps.clone(), after: eps, switch_at: f64::INFINITY };
    let reference = reference(&model, &schedule);
    for method in [Method::Dop853, Method::Dopri5, Method::Tsit5, Method::Bs3] {
        let tolerance = 1e-4;
        let (points, steps) = held_run(&mut slow_start(&model, method, tolerance), &model, &schedule);
        let error = largest_error(&points, &reference) / tolerance;
        println!("{}: {steps} steps for {POINTS} communication points, error {error:.2e} × tolerance", method.name());
        assert!(steps < POINTS, "{}: {steps} steps for {POINTS} communication points", method.name());
        assert!((0.02..=20.0).contains(&error), "{}: error {error:e} × tolerance", method.name());
    }
}

/// ε changed at t = 2.1 s takes effect there: the run that reached past
/// that point restarts from its interpolant and stays within 20 times the
/// tolerance of a reference that ends a step there. Taken from the end of
/// the step that reached past it (about a second later here), the change
/// would put the run far off. (A push much harder than this one sets the
/// arms whirling, where an error grows e-fold every half second or so:
/// no tolerance then bounds the error at the end of 10 s.)
#[test]
fn a_changed_input_takes_effect_at_its_communication_point() {
    let model = station();
    let tolerance = 1e-6;
    let schedule = Schedule { before: vec![0.0; model.nv], after: vec![0.05; model.nv], switch_at: 2.1 };
    let reference = reference(&model, &schedule);
    for method in [Method::Dop853, Method::Tsit5] {
        let mut sim = slow_start(&model, method, tolerance);
        sim.set_horizon(END);
        let (points, steps) = held_run(&mut sim, &model, &schedule);
        let error = largest_error(&points, &reference) / tolerance;
        println!("{}: {steps} steps, error {error:.2e} × tolerance", method.name());
        assert!(error <= 20.0, "{}: error {error:e} × tolerance", method.name());
    }
}

/// A state saved while the last step reaches past the communication point
/// (its interpolant and its end are part of the state) continues bit for
/// bit as the run that saved it, with the input unchanged or changed, to
/// the run's end.
#[test]
fn a_state_saved_inside_a_step_continues_bit_for_bit() {
    let model = station();
    let zero = vec![0.0; model.nv];
    let push = vec![0.2; model.nv];
    for method in [Method::Dop853, Method::Dopri5, Method::Tsit5, Method::Bs3] {
        let mut sim = slow_start(&model, method, 1e-4);
        sim.set_horizon(END);
        let hold = |sim: &mut Simulation, from: usize, to: usize, eps: &[f64]| {
            for n in from..=to {
                let input = Input { eps, eps_rate: &zero, ctrl: &[], ctrl_rate: &[] };
                sim.advance_to(&model, n as f64 * COMMUNICATION_STEP, input).unwrap();
            }
        };
        hold(&mut sim, 1, 30, &zero);
        assert!(sim.state.reach.held, "{}: the last step reaches past t = 3 s", method.name());
        assert!(sim.state.reach.end > 3.0 + COMMUNICATION_STEP, "{}: a step beyond the next point", method.name());
        let saved = sim.state.clone();
        let mut other = Simulation::new(&model, method, settings(1e-4));
        other.set_horizon(END);
        for eps in [&zero, &push] {
            hold(&mut sim, 31, 100, eps);
            let continued = sim.state.clone();
            for restored in [&mut sim, &mut other] {
                restored.restore(&model, &saved, &HeldJacobian::default());
                hold(restored, 31, 100, eps);
                assert_eq!(restored.state, continued, "{}", method.name());
            }
            sim.restore(&model, &saved, &HeldJacobian::default());
        }
    }
}

/// examples/servicer.xml: a free bus with thrusters, three reaction
/// wheels and a four-joint arm on position servos (kp 150, critically
/// damped): fast damped modes, |λ| up to about 39 /s.
fn servicer() -> Model {
    let imported = nudyn::mjcf::load_mjcf(Path::new("examples/servicer.xml")).unwrap();
    Model::compile(&imported.vehicle).unwrap()
}

/// The servicer off its servo targets (ctrl 0) and tumbling slowly: (θ, ν)
/// at each of `points` communication points, ctrl held at 0, with steps
/// reaching past the points, or (`reach` false) ending at each (ε given
/// as a function of time); and the interpolants refused.
fn servicer_run(model: &Model, tolerance: f64, points: usize, reach: bool) -> (Vec<Vec<f64>>, usize) {
    // The wheels and the arm joints moved; the arm's off its servo targets.
    let joint = |k: usize| (0.4 * (1.3 * k as f64).sin(), 0.2 * (0.7 * k as f64).cos());
    let mut sim = started(model, Method::Dop853, tolerance, [0.02, -0.01, 0.01, 0.05, -0.03, 0.04], joint);
    let (zero_eps, zero_ctrl) = (vec![0.0; model.nv], vec![0.0; model.actuators.len()]);
    let (mut points_out, mut refused) = (Vec::new(), 0);
    for n in 1..=points {
        let t = n as f64 * COMMUNICATION_STEP;
        let advanced = if reach {
            let input = Input { eps: &zero_eps, eps_rate: &zero_eps, ctrl: &zero_ctrl, ctrl_rate: &zero_ctrl };
            sim.advance_to(model, t, input).unwrap()
        } else {
            let signal = |_: f64, out: &mut [f64]| out.fill(0.0);
            sim.advance_to(model, t, signal).unwrap()
        };
        refused += advanced.stats.refused_interpolants;
        points_out.push(sim.state.theta.iter().chain(&sim.state.nu).copied().collect());
    }
    (points_out, refused)
}

/// The servicer's steps are held by stability near 0.1–0.16 s, so with
/// the input held they reach past the points; their interpolant followed
/// the servos' damped modes far less closely than their ends (dop853 was
/// 23–200 times the tolerance off at the points over 10 s). Refused where
/// it strays, the run stays within 20 times the tolerance of a reference
/// that ends its steps at the points.
#[test]
fn an_interpolant_that_strays_from_a_fast_damped_mode_is_refused() {
    let model = servicer();
    let points = 30;
    let (reference, _) = servicer_run(&model, 1e-12, points, false);
    for tolerance in [1e-4, 1e-8] {
        let (run, refused) = servicer_run(&model, tolerance, points, true);
        let error = largest_error(&run, &reference) / tolerance;
        println!("servicer, dop853 at {tolerance:e}: {refused} interpolants refused, error {error:.2e} × tolerance");
        assert!(refused > 0, "at {tolerance:e}: no interpolant refused");
        assert!(error <= 20.0, "at {tolerance:e}: error {error:e} × tolerance");
    }
}

/// A step cut to end just past a constraint switch that reaches past the
/// communication point is held like any other: the run goes on from its
/// end in the mode past the switch instead of locating the switch again
/// from the point. The solver's working set there is part of the state,
/// so a state saved then continues bit for bit, into the instance that ran
/// on (whose solver was left elsewhere) and into a fresh one.
#[test]
fn a_step_held_past_a_switch_continues_bit_for_bit() {
    let cases = [
        ("docked_servicer", 1e-6, [Method::Dop853, Method::Dopri5]),
        ("noslip_trees", 1e-6, [Method::Dop853, Method::Tsit5]),
        ("empty_rows", 1e-8, [Method::Dop853, Method::Tsit5]),
    ];
    for (name, tolerance, methods) in cases {
        let model = crate::stiffness::fixture(&format!("tests/fixtures/constraints/{name}.xml"));
        let eps = crate::stiffness::eps(&model);
        let zero = vec![0.0; model.nv];
        let hold = |sim: &mut Simulation, points: std::ops::RangeInclusive<usize>| {
            for n in points {
                let input = Input { eps: &eps, eps_rate: &zero, ctrl: &[], ctrl_rate: &[] };
                sim.advance_to(&model, n as f64 * crate::stiffness::INTERVAL, input).unwrap();
            }
        };
        for method in methods {
            let mut sim = Simulation::new(&model, method, settings(tolerance));
            sim.initialize(&model).unwrap();
            let past_switch = (1..=60).find(|&n| {
                hold(&mut sim, n..=n);
                let reach = &sim.state.reach;
                reach.held && !reach.working_set.is_empty()
            });
            let Some(saved_at) = past_switch else {
                panic!("{name}, {}: no step held past a switch in 60 points", method.name());
            };
            let saved = sim.state.clone();
            let rest = saved_at + 1..=saved_at + 20;
            hold(&mut sim, rest.clone());
            let continued = sim.state.clone();
            let mut fresh = Simulation::new(&model, method, settings(tolerance));
            for restored in [&mut sim, &mut fresh] {
                restored.restore(&model, &saved, &HeldJacobian::default());
                hold(restored, rest.clone());
                assert_eq!(restored.state, continued, "{name}, {}", method.name());
            }
            // A working set longer than this vehicle's rows (not one its solver
            // gave) is not started from: the run goes on from the state alone.
            let mut foreign = saved.clone();
            foreign.reach.working_set.resize(model.constraints.max_rows() + 1, Held::Lower);
            sim.restore(&model, &foreign, &HeldJacobian::default());
            hold(&mut sim, rest.clone());
        }
    }
}
