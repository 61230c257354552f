//! Adaptive integration over communication intervals: runs meet their
//! tolerance against a tight reference, the carried step makes interval
//! boundaries harmless, and the energy options do what they say.

use crate::common::{Rng, TreeOptions, random_theta, random_vehicle};
use nudyn::integrate::{
    AdvanceError, Carry, Input, MAX_STEPS, Method, MethodSetting, Settings, Simulation, ToleranceRelaxed,
};
use nudyn::model::Model;
use nudyn::vehicle::{JointKind, Vehicle};

/// A smooth, time-varying ε.
fn smooth_eps(t: f64, out: &mut [f64]) {
    out.iter_mut().enumerate().for_each(|(k, e)| *e = 0.3 * (2.0 * t + k as f64).sin());
}

fn no_eps(_: f64, out: &mut [f64]) {
    out.fill(0.0);
}

struct Run {
    /// (θ, ν) at each interval end.
    states: Vec<(Vec<f64>, Vec<f64>)>,
    carry: Carry,
    steps: usize,
    /// Evaluations of the rates.
    evaluations: usize,
    /// The method in effect at the end (what `auto` ran with).
    ended_with: Method,
}

/// `intervals` intervals of `interval` s with `method` and `settings`.
fn run(
    model: &Model,
    start: &(Vec<f64>, Vec<f64>),
    method: impl Into<MethodSetting>,
    settings: Settings,
    (interval, intervals): (f64, usize),
    eps_at: fn(f64, &mut [f64]),
) -> Run {
    let mut sim = Simulation::new(model, method, settings);
    (sim.state.theta, sim.state.nu) = start.clone();
    let mut states = Vec::new();
    let (mut steps, mut evaluations) = (0, 0);
    for n in 1..=intervals {
        let stats = sim.advance_to(model, n as f64 * interval, eps_at).unwrap().stats;
        steps += stats.accepted + stats.rejected;
        evaluations += stats.evaluations;
        states.push((sim.state.theta.clone(), sim.state.nu.clone()));
    }
    Run { states, carry: sim.state.carry, steps, evaluations, ended_with: sim.method() }
}

/// Largest |x − reference| / (1 + |reference|) over all states.
fn scaled_error(run: &Run, reference: &Run) -> f64 {
    let mut worst = 0.0f64;
    for ((theta, nu), (theta_ref, nu_ref)) in run.states.iter().zip(&reference.states) {
        for (x, r) in theta.iter().chain(nu).zip(theta_ref.iter().chain(nu_ref)) {
            worst = worst.max((x - r).abs() / (1.0 + r.abs()));
        }
    }
    worst
}

fn vehicle(seed: u64) -> (Vehicle, Model, (Vec<f64>, Vec<f64>)) {
    let mut rng = Rng::new(seed);
    let mut vehicle = random_vehicle(&mut rng, TreeOptions { bodies: 6, free_base: true, passive: true, chain: false });
    // Ball and free springs pull along the shorter rotation, so their torque
    // jumps where the rotation from rest passes π: no method keeps its
    // accuracy across a discontinuous force.
    for joint in vehicle.bodies.iter_mut().flat_map(|b| b.joints.iter_mut()) {
        if matches!(joint.kind, JointKind::Ball | JointKind::Free) {
            joint.stiffness = 0.0;
        }
    }
    let model = Model::compile(&vehicle).unwrap();
    let theta = random_theta(&mut rng, &vehicle);
    let nu = rng.vec(model.nv, 1.0);
    (vehicle, model, (theta, nu))
}

/// The FMU's defaults apart from the tolerance: no max_step.
fn settings(tolerance: f64) -> Settings {
    Settings { tolerance, max_step: 0.0, energy_projection: false }
}

/// The reference: DOP853 with fixed steps of 1/4096 s (error ~1e-20 by its order).
fn reference(model: &Model, start: &(Vec<f64>, Vec<f64>), intervals: (f64, usize), eps_at: fn(f64, &mut [f64])) -> Run {
    let fixed = Settings { tolerance: 1.0, max_step: 1.0 / 4096.0, energy_projection: false };
    run(model, start, Method::Dop853, fixed, intervals, eps_at)
}

/// The most the error delivered may be, in tolerances: 20, except DOPRI5
/// at its loosest tolerances, where it takes about one step per
/// communication step and its error estimate (of θ̇, mapped to ν by m*,
/// without the change of m* over the step) falls short (measured: up to
/// 41× at 1e-4 and 23× at 1e-5 in a third of the steps the ν-state took
/// for 17×; docs/integration.md), and TSIT5 and BS3 there too, for the
/// same reason (measured: up to 23× and 26×). `auto` is held to 20.
fn highest_ratio(method: MethodSetting, tolerance: f64) -> f64 {
    let loose_pair = matches!(method, MethodSetting::Fixed(Method::Dopri5 | Method::Tsit5 | Method::Bs3));
    if loose_pair && tolerance >= 1e-5 { 50.0 } else { 20.0 }
}

/// The error delivered tracks the tolerance asked. Over 10 s of a 6-body
/// tree with springs, dampers and a time-varying ε, in communication steps
/// of 0.1 s, the largest error at any communication point (scaled by
/// 1 + |value|) lies between 1/50 and `highest_ratio` times the tolerance,
/// for tolerances 1e-4 to 1e-10 (docs/integration.md), or below only where
/// the run takes about one step per communication step, the least it can,
/// so that accuracy beyond the tolerance costs nothing. A tighter
/// tolerance never takes fewer steps (`auto`, whose method changes with
/// the tolerance, never more than 1 % fewer evaluations of the rates: where
/// it starts with `tsit5` and moves up to `dop853` after the second
/// communication step, the detour costs 0.2–0.6 % more than `dop853` from
/// the start at the next tighter tolerance on two of these trees). ROS34PW2, of order 3 and meant for
/// stiff vehicles at moderate tolerances, is held to the band from 1e-4 to
/// 1e-8 (measured: 0.8–10.1 × the tolerance, nearly proportional; at 1e-10
/// it would take 10⁵ steps on these trees). BS3, of order 3 and meant for
/// slow motion at loose tolerances, from 1e-4 to 1e-7 (measured: 4.9–26 ×
/// the tolerance since the order gap is allowed for, 0.3–26 before; below,
/// 10⁴ steps and more). `auto`, at every tolerance,
/// to the band of `dop853`. One test per tree, so that the trees run in
/// parallel.
fn the_error_delivered_tracks_the_tolerance(seed: u64) {
    let intervals = (0.1, 100);
    let all_tolerances = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10];
    let mut outside = Vec::new();
    let (_, model, start) = vehicle(seed);
    let reference = reference(&model, &start, intervals, smooth_eps);
    let methods =
        [Method::Dopri5, Method::Dop853, Method::Ros34pw2, Method::Bs3, Method::Tsit5].map(MethodSetting::from);
    for method in methods.into_iter().chain([MethodSetting::Auto]) {
        let mut previous_cost = 0;
        let tolerances = match method {
            MethodSetting::Fixed(Method::Ros34pw2) => &all_tolerances[..5],
            MethodSetting::Fixed(Method::Bs3) => &all_tolerances[..4],
            _ => &all_tolerances[..],
        };
        for &tolerance in tolerances {
            let result = run(&model, &start, method, settings(tolerance), intervals, smooth_eps);
            let ratio = scaled_error(&result, &reference) / tolerance;
            let case = format!(
                "seed {seed}, {} ({}) at {tolerance:e}: error {ratio:.2} × tolerance in {} steps, {} evaluations",
                method.name(),
                result.ended_with.name(),
                result.steps,
                result.evaluations
            );
            println!("{case}");
            let fewest_steps = result.steps <= intervals.1 + intervals.1 / 10;
            if ratio > highest_ratio(method, tolerance) || (ratio < 0.02 && !fewest_steps) {
                outside.push(case.clone());
            }
            let cost = if method == MethodSetting::Auto { result.evaluations } else { result.steps };
            let slack = if method == MethodSetting::Auto { 1.01 } else { 1.0 };
            if (cost as f64) * slack < previous_cost as f64 {
                outside.push(format!("{case}, cheaper than at the looser tolerance"));
            }
            if result.carry.relaxation != 0.0 {
                println!("  relaxed {:.1}-fold for round-off", result.carry.relaxation);
            }
            previous_cost = cost;
        }
    }
    assert!(outside.is_empty(), "outside the band:\n{}", outside.join("\n"));
}

#[test]
fn the_error_delivered_tracks_the_tolerance_on_tree_3() {
    the_error_delivered_tracks_the_tolerance(3);
}

#[test]
fn the_error_delivered_tracks_the_tolerance_on_tree_4() {
    the_error_delivered_tracks_the_tolerance(4);
}

#[test]
fn the_error_delivered_tracks_the_tolerance_on_tree_5() {
    the_error_delivered_tracks_the_tolerance(5);
}

#[test]
fn the_error_delivered_tracks_the_tolerance_on_tree_6() {
    the_error_delivered_tracks_the_tolerance(6);
}

/// A free tree tumbling with no force for 200 s: K = ½|ν|² is invariant.
/// Without projection it drifts by the integration error; with
/// `energy_projection` it stays at round-off. The projection does nothing
/// for the momentum (measured: its drift grows from 1.1e-5 to 5e-5 here),
/// which stays within the tolerance's budget of 1e-6 per second.
#[test]
fn energy_projection_keeps_kinetic_energy_in_free_tumbling() {
    let mut rng = Rng::new(21);
    let vehicle = random_vehicle(&mut rng, TreeOptions { bodies: 6, free_base: true, passive: false, chain: false });
    let model = Model::compile(&vehicle).unwrap();
    let start = (random_theta(&mut rng, &vehicle), rng.vec(model.nv, 1.0));
    let energy = |nu: &[f64]| 0.5 * nu.iter().map(|x| x * x).sum::<f64>();
    let momentum = |state: &(Vec<f64>, Vec<f64>)| {
        let mut ws = model.workspace();
        ws.set_configuration(&model, &state.0).unwrap();
        ws.set_nu(&model, &state.1).unwrap();
        ws.momentum(&model).unwrap()
    };
    let (k0, p0) = (energy(&start.1), momentum(&start));
    let drift = |energy_projection: bool| {
        let settings = Settings { tolerance: 1e-6, max_step: 1.0, energy_projection };
        let result = run(&model, &start, Method::Dop853, settings, (1.0, 200), no_eps);
        let end = result.states.last().unwrap();
        ((energy(&end.1) - k0).abs() / k0, (momentum(end) - p0).norm() / p0.norm(), result.carry.work)
    };
    let (energy_free, momentum_free, work) = drift(false);
    let (energy_projected, momentum_projected, _) = drift(true);
    eprintln!(
        "relative drift after 200 s: K {energy_free:.1e} -> {energy_projected:.1e}, momentum {momentum_free:.1e} -> {momentum_projected:.1e}"
    );
    assert!(
        energy_free > 1e-10,
        "the unprojected run drifts measurably ({energy_free:.1e}), or this test shows nothing"
    );
    assert!(energy_projected < 1e-13, "projected K drift {energy_projected:.1e}");
    assert!(momentum_free.max(momentum_projected) < 200.0 * 1e-6, "{momentum_free:.1e}, {momentum_projected:.1e}");
    // No force acts, so the quadrature of the power is zero to round-off.
    assert!(work.abs() < 1e-12 * k0, "work {work:e}");
}

/// With springs, dampers and ε, K changes; the energy residual
/// K − K₀ − ∫ν·ν̇ dt measures only the integration error, so it stays
/// within the tolerance's budget and shrinks with it, and the projection
/// takes it to round-off.
#[test]
fn energy_residual_follows_the_tolerance() {
    let (_, model, start) = vehicle(5);
    let energy = |nu: &[f64]| 0.5 * nu.iter().map(|x| x * x).sum::<f64>();
    let k0 = energy(&start.1);
    let residual = |tolerance: f64, energy_projection: bool| {
        let settings = Settings { tolerance, max_step: 1.0, energy_projection };
        let result = run(&model, &start, Method::Dop853, settings, (0.05, 40), smooth_eps);
        let k = energy(&result.states.last().unwrap().1);
        ((k - k0 - result.carry.work) / k0).abs()
    };
    let (loose, tight, projected) = (residual(1e-5, false), residual(1e-9, false), residual(1e-5, true));
    eprintln!("relative energy residual: {loose:.1e} at 1e-5, {tight:.1e} at 1e-9, {projected:.1e} projected");
    assert!(loose < 2.0 * 1e-5 && tight < 2.0 * 1e-9, "{loose:.1e}, {tight:.1e}");
    assert!(tight < loose / 10.0, "{tight:.1e} vs {loose:.1e}");
    // Round-off only: each rescaling leaves a few ulps of K, summed over the
    // run's steps (6e-13 and 1.4e-12 with two orderings of the same sums).
    assert!(projected < 1e-11, "{projected:.1e}");
}

/// Three rods of inertia diag(1e-9, 1, 1) on a bus: M has three
/// near-null directions (each rod spinning about its own axis), whose pivots
/// come out of sums of order 10 cancelling to 1e-9, so round-off in θ̈ is
/// more than a tolerance of 1e-9 per second allows, at any step size
/// (with ν̇ as the rate, before the integrator advanced θ̇, it was so from
/// 1e-8; DOPRI5 on θ̇ now holds 1e-8). The error control must then say so
/// (the relaxation) and go on, as accurate as double precision lets this
/// vehicle be: fixed-step DOP853 runs at 2e-4 … 2.5e-5 s, whose truncation
/// errors are far below round-off, disagree among themselves by ~1e-5 (the
/// spread); the adaptive runs must be within 3× the larger of the spread
/// and the relaxed tolerance × time of them (measured: 2.5e-6 and 6.6e-6
/// against a spread of 1.3e-5), and keep K (invariant here) to the relaxed
/// tolerance.
#[test]
fn round_off_in_the_rates_relaxes_the_tolerance_and_says_so() {
    let imported = nudyn::mjcf::load_mjcf(std::path::Path::new("tests/fixtures/thin_rods.xml")).unwrap();
    let model = Model::compile(&imported.vehicle).unwrap();
    let mut theta = model.qpos0.clone();
    // Bend the rods so that the near-null directions couple to the rest.
    theta[7..11].copy_from_slice(&[0.9553, 0.0, 0.0, 0.2955]);
    theta[11..15].copy_from_slice(&[0.9801, 0.0, 0.1987, 0.0]);
    // Rates of a few rad/s (a random ν would spin the rods at 1e4 rad/s).
    let mut rng = Rng::new(8);
    let mut ws = model.workspace();
    ws.set_configuration(&model, &theta).unwrap();
    ws.set_qvel(&model, &rng.vec(model.nv, 2.0)).unwrap();
    let start = (theta, ws.nu.as_slice().to_vec());
    let intervals = (0.05, 20);
    let duration = 0.05 * 20.0;
    let fixed = |h| Settings { tolerance: 1.0, max_step: h, energy_projection: false };
    let reference = run(&model, &start, Method::Dop853, fixed(1e-4), intervals, no_eps);
    let spread = [2e-4, 5e-5, 2.5e-5]
        .map(|h| scaled_error(&run(&model, &start, Method::Dop853, fixed(h), intervals, no_eps), &reference))
        .into_iter()
        .fold(0.0, f64::max);
    assert!(spread > 1e-6, "round-off should limit this vehicle: fixed steps agree to {spread:.1e}");
    let energy = |nu: &[f64]| 0.5 * nu.iter().map(|x| x * x).sum::<f64>();
    let tolerance = 1e-9;
    for method in [Method::Dopri5, Method::Dop853] {
        let result = run(&model, &start, method, settings(tolerance), intervals, no_eps);
        let attained = result.carry.attained_tolerance(tolerance);
        assert!(attained > tolerance, "{method:?}: relaxation {}", result.carry.relaxation);
        let error = scaled_error(&result, &reference);
        let floor = spread.max(attained * duration);
        assert!(error <= 3.0 * floor, "{method:?}: error {error:.2e}, fixed-step spread {spread:.2e}");
        let k0 = energy(&start.1);
        let k_drift = (energy(&result.states.last().unwrap().1) - k0).abs() / k0;
        assert!(k_drift <= attained * duration, "{method:?}: K drift {k_drift:.2e}, attained {attained:.2e}");
    }
    // The warning blames round-off here, where the motion stays bounded (K is invariant).
    let mut sim = Simulation::new(&model, Method::Dop853, settings(tolerance));
    (sim.state.theta, sim.state.nu) = start.clone();
    let warnings: Vec<ToleranceRelaxed> =
        (1..=20).filter_map(|n| sim.advance_to(&model, n as f64 * 0.05, no_eps).unwrap().relaxed).collect();
    assert!(!warnings.is_empty());
    for warning in &warnings {
        let message = warning.to_string();
        eprintln!("{message}");
        assert!(!message.contains("diverges"), "{message}");
        assert!(
            message.starts_with("tolerance 1e-9 per second is below what round-off in this vehicle's rates allows")
        );
        assert!(message.contains(&format!("held to {:e} per second, relative to 1 + |x|", warning.attained)));
    }
}

/// A sampled loop around the vehicle whose gain is too high for its
/// communication step: ε = −c₁ν sampled and held over h = 0.01 s with
/// c₁h = 3, so |ν| is multiplied by about |1 − c₁h| = 2 each step and the
/// arm's rates grow faster still (Coriolis terms grow as |ν|²). The error
/// estimate then stops falling as the step is cut (the motion outruns every
/// step), which the round-off test takes for round-off; the warning used to
/// say "below what round-off in this vehicle's rates allows". It must say
/// that the motion diverges, by how much the rates grew, and what error
/// is held relative to the state's size.
#[test]
fn a_diverging_loop_is_not_blamed_on_round_off() {
    let imported = nudyn::mjcf::load_mjcf(std::path::Path::new("examples/bus_arm7.xml")).unwrap();
    let model = Model::compile(&imported.vehicle).unwrap();
    let mut sim = Simulation::new(&model, Method::Dop853, settings(1e-8));
    sim.state.nu = vec![0.1; model.nv];
    sim.initialize(&model).unwrap();
    let speed = |nu: &[f64]| nu.iter().map(|x| x * x).sum::<f64>().sqrt();
    let start_speed = speed(&sim.state.nu);
    let (h, c1) = (0.01, 300.0);
    let (no_rate, no_ctrl) = (vec![0.0; model.nv], vec![0.0; model.actuators.len()]);
    let mut eps = vec![0.0; model.nv];
    for k in 1..=40 {
        eps.iter_mut().zip(&sim.state.nu).for_each(|(e, nu)| *e = -c1 * nu);
        let input = Input { eps: &eps, eps_rate: &no_rate, ctrl: &no_ctrl, ctrl_rate: &no_ctrl };
        let advanced = sim.advance_to(&model, k as f64 * h, input).unwrap_or_else(|e| panic!("step {k}: {e}"));
        if let Some(warning) = advanced.relaxed {
            let grown = speed(&sim.state.nu) / start_speed;
            let message = warning.to_string();
            eprintln!("{message}");
            assert!(grown > 1e4, "|ν| grew only {grown:.1e}-fold by the warning: {message}");
            let factor = message
                .strip_prefix("the motion diverges: the rates grew ")
                .and_then(|rest| rest.split_once("-fold since the start"))
                .and_then(|(factor, _)| factor.parse::<f64>().ok());
            assert!(factor.is_some_and(|factor| factor > grown), "{message}");
            assert!(message.contains("an unstable loop around the FMU") && !message.contains("round-off"), "{message}");
            assert!(message.contains(&format!("held to {:e} per second, relative to 1 + |x|", warning.attained)));
            return;
        }
    }
    panic!("no warning in 40 steps: |ν| = {:.1e}", speed(&sim.state.nu));
}

/// A long interval of slow motion is work asked for, not a failure: from
/// rest (springs only), 1310 s with max_step 0.01 s takes 131 000 steps.
/// With no bound (max_step 0, the default) the error control alone decides
/// (about 41 000 here, the springs oscillating); with max_step 0.01 s those
/// 131 000 are more than one advance may take, refused before any step.
#[test]
fn a_long_interval_takes_the_steps_its_bound_allows() {
    let (_, model, (theta, _)) = vehicle(1);
    let at_rest = |max_step| {
        let mut sim = Simulation::new(&model, Method::Dopri5, Settings { max_step, ..settings(1e-8) });
        (sim.state.theta, sim.state.nu) = (theta.clone(), vec![0.0; model.nv]);
        sim.initialize(&model).unwrap();
        sim
    };
    let mut unbounded = at_rest(0.0);
    let stats = unbounded.advance_to(&model, 1310.0, no_eps).unwrap().stats;
    assert!(stats.accepted + stats.rejected < 131_000 / 2, "{stats:?}");
    assert_eq!(unbounded.state.time, 1310.0);

    let mut bounded = at_rest(0.01);
    let before = bounded.state.clone();
    let error = bounded.advance_to(&model, 1310.0, no_eps).unwrap_err();
    let message = error.to_string();
    assert!(matches!(error, AdvanceError::TooLong { .. }), "{message}");
    assert!(message.contains("1.31e5 internal steps") && message.contains("a larger max_step"), "{message}");
    assert_eq!(bounded.state, before, "nothing is integrated");
    assert!(bounded.advance_to(&model, 600.0, no_eps).unwrap().stats.accepted >= 60_000);
}

/// Steps held short by the error control stop at the limit, with a message
/// that says so and what lets the run through.
#[test]
fn an_error_control_that_holds_the_step_short_stops_at_the_limit() {
    let (_, model, (theta, nu)) = vehicle(2);
    let fast: Vec<f64> = nu.iter().map(|v| 300.0 * v).collect();
    let mut sim = Simulation::new(&model, Method::Dopri5, Settings { max_step: f64::INFINITY, ..settings(1e-10) });
    (sim.state.theta, sim.state.nu) = (theta, fast);
    sim.initialize(&model).unwrap();
    let error = sim.advance_to(&model, 1e3, no_eps).unwrap_err();
    let message = error.to_string();
    assert!(matches!(error, AdvanceError::TooManySteps { .. }), "{message}");
    assert!(message.starts_with(&format!("{MAX_STEPS} internal steps")), "{message}");
    assert!(
        message.contains("too fast or stiff for tolerance 1e-10") && message.contains("looser tolerance"),
        "{message}"
    );
    assert!(error.reached() > 0.0 && error.reached() < 1e3 && sim.state.time == error.reached(), "{message}");
    assert!(sim.state.nu.iter().all(|v| v.is_finite()));
}
