//! The error band on the constrained fixtures (docs/integration.md, "Errors
//! the constraint rows damp out"): driven (ε = 0.3 sin k) in 0.05 s
//! communication steps, the largest error at any communication point lies
//! within [1/50, 20] × the tolerance for every adaptive explicit method and
//! `auto`, with the input held (steps may reach past the points) and with
//! the input given as a function of time (every step ends at a point),
//! except below it where one step per point is already more accurate than
//! asked. At 1e-10 (not `bs3`: 10⁵ steps and more) the error is held
//! below the band's top only: its bottom, 2e-12, lies within the
//! reference's own round-off (references at 1e-12, 1e-13 and 1e-14 of the
//! servicer differ by 2–4e-12).

use nudyn::integrate::{Input, Method, MethodSetting, Settings, Simulation, ToleranceRelaxed};
use nudyn::model::Model;

use crate::common::largest_relative_error;
use crate::stiffness::{INTERVAL, eps, fixture};

/// The band's ends, over the tolerance.
const BAND: (f64, f64) = (1.0 / 50.0, 20.0);

/// Runs measured below the band, (fixture, setting, tolerance, held), and
/// the least they must still deliver over the tolerance: `dop853` (and
/// `auto`, which chooses it) on the docked servicer at 1e-8 with every step
/// ending at a point, 1.4e-2 in the welds' first pull (t ≈ 0.15 s) and
/// 1e-4 … 1e-3 after it. The steps (about 5 ms) are held by the damped
/// part of the 5th-order estimate, which at h·σ ≈ 0.5 overstates the
/// error of the 8th-order solution the method goes on with. And `dop853`
/// on empty_rows at 1e-4 and 1e-6 with every step ending at a point,
/// 3.4e-4 and 2.2e-3: its steps end at the points and at the elbow
/// limit's switches (33 and 36 for 20 points; 33 with the input held too,
/// where steps may reach past the points), which is more than asked. And
/// the welded strap (its one row dropped: a pendulum's slow swing) with
/// every step ending at a point: `tsit5` at 1e-8 and `auto` at 1e-4 and
/// 1e-8 take 31–41 steps for 20 points, 4e-3 … 1e-2, near the floor. And
/// tendon_limits' `dop853` (and `auto`) at 1e-4 and 1e-6 with every step
/// ending at a point, 2.0e-3 and 2.4e-3: its steps end at the points and at
/// the switches of its rows (32 and 40 for 20 points).
const BELOW_THE_BAND: [(&str, MethodSetting, f64, bool, f64); 11] = [
    ("docked_servicer", MethodSetting::Fixed(Method::Dop853), 1e-8, false, 1e-3),
    ("docked_servicer", MethodSetting::Auto, 1e-8, false, 1e-3),
    ("empty_rows", MethodSetting::Fixed(Method::Dop853), 1e-4, false, 1e-4),
    ("empty_rows", MethodSetting::Fixed(Method::Dop853), 1e-6, false, 1e-3),
    ("welded_strap", MethodSetting::Fixed(Method::Tsit5), 1e-8, false, 2e-3),
    ("welded_strap", MethodSetting::Auto, 1e-4, false, 2e-3),
    ("welded_strap", MethodSetting::Auto, 1e-8, false, 2e-3),
    ("tendon_limits", MethodSetting::Fixed(Method::Dop853), 1e-4, false, 1e-3),
    ("tendon_limits", MethodSetting::Auto, 1e-4, false, 1e-3),
    ("tendon_limits", MethodSetting::Fixed(Method::Dop853), 1e-6, false, 1e-3),
    ("tendon_limits", MethodSetting::Auto, 1e-6, false, 1e-3),
];

/// The tightest tolerance the band runs at, where round-off in the rates
/// of stiff rows may rule the error estimate: refsafe_off's rows (time
/// constants of 1 ms) hold `dop853`'s estimate above 1e-10 per second
/// (its θ̈ carries 1.5–2.3e-9 of round-off there, measured where the
/// estimate stopped falling as the step was cut), so the run says it holds
/// 1–1.7e-9 per second, a note that the error delivered still meets the
/// tolerance (3.8 and 4.7 times it), not a warning.
const ROUND_OFF_TOLERANCE: f64 = 1e-10;

/// A run's communication points, and what it took.
struct Points {
    /// (θ, ν) at each.
    states: Vec<Vec<f64>>,
    /// Steps taken.
    steps: usize,
    /// Steps past a point taken again, their interpolant refused.
    refused: usize,
}

/// (θ, ν) at each of `points` communication points of `setting` at
/// `tolerance`, with ε held (`held`) or given as a function of time; a
/// relaxation of the tolerance fails the test, except at
/// [`ROUND_OFF_TOLERANCE`] one that still meets what was asked.
fn points(model: &Model, setting: MethodSetting, tolerance: f64, points: usize, held: bool) -> Points {
    let (run, relaxed) = points_relaxing(model, setting, tolerance, points, held);
    let unexcused: Vec<String> = relaxed
        .iter()
        .filter(|relaxation| tolerance > ROUND_OFF_TOLERANCE || !relaxation.meets_asked())
        .map(ToString::to_string)
        .collect();
    assert!(unexcused.is_empty(), "{setting:?} at {tolerance:e}: {unexcused:?}");
    run
}

/// [`points`], and the relaxations of the tolerance the run made.
fn points_relaxing(
    model: &Model,
    setting: MethodSetting,
    tolerance: f64,
    points: usize,
    held: bool,
) -> (Points, Vec<ToleranceRelaxed>) {
    let settings = Settings { tolerance, max_step: 0.0, energy_projection: false };
    let mut sim = Simulation::new(model, setting, settings);
    sim.initialize(model).unwrap();
    let eps = eps(model);
    let zero = vec![0.0; model.nv];
    let (mut steps, mut refused, mut relaxed) = (0, 0, Vec::new());
    let states = (1..=points)
        .map(|n| {
            let t = n as f64 * INTERVAL;
            let advanced = if held {
                sim.advance_to(model, t, Input { eps: &eps, eps_rate: &zero, ctrl: &[], ctrl_rate: &[] })
            } else {
                sim.advance_to(model, t, |_: f64, out: &mut [f64]| out.copy_from_slice(&eps))
            };
            let advanced = advanced.unwrap();
            relaxed.extend(advanced.relaxed);
            steps += advanced.stats.accepted;
            refused += advanced.stats.refused_interpolants;
            sim.state.theta.iter().chain(&sim.state.nu).copied().collect()
        })
        .collect();
    (Points { states, steps, refused }, relaxed)
}

/// The largest error relative to 1 + |x| at any point.
fn largest_error(run: &[Vec<f64>], reference: &[Vec<f64>]) -> f64 {
    largest_relative_error(run.iter().zip(reference).flat_map(|(x, r)| x.iter().zip(r)))
}

fn band_on(path: &str, count: usize) {
    let model = fixture(path);
    // At 1e-12 the reference may meet the round-off in the rates and say so
    // (the servicer's: references at 1e-12, 1e-13 and 1e-14 differ by 2–4e-12);
    // held within 20 times that, it lies 10 times below the band at 1e-8.
    let (reference, _) = points_relaxing(&model, MethodSetting::Fixed(Method::Dop853), 1e-12, count, false);
    let mut outside = Vec::new();
    let settings = [Method::Dop853, Method::Dopri5, Method::Tsit5, Method::Bs3]
        .map(MethodSetting::Fixed)
        .into_iter()
        .chain([MethodSetting::Auto]);
    for setting in settings {
        let tightest = if setting == MethodSetting::Fixed(Method::Bs3) { 1e-8 } else { ROUND_OFF_TOLERANCE };
        let tolerances = [1e-4, 1e-6, 1e-8, ROUND_OFF_TOLERANCE].into_iter().filter(|&tolerance| tolerance >= tightest);
        for tolerance in tolerances {
            for held in [true, false] {
                let Points { states, steps, refused } = points(&model, setting, tolerance, count, held);
                let ratio = largest_error(&states, &reference.states) / tolerance;
                let line = format!(
                    "{path} {setting:?} {tolerance:e} held {held}: largest error/tol {ratio:.2e}, {steps} steps"
                );
                println!("{line}");
                // Below the band is allowed only where each step ends at a point (or
                // near one: an interpolant refused takes the step again shorter) and
                // about one step per communication step already delivers more than
                // asked (the floor of one step per point, issue 50; the limited arm's
                // dop853 from 1e-6).
                let at_the_floor = (!held || refused > 0) && 2 * steps <= 3 * count;
                let least = BELOW_THE_BAND
                    .iter()
                    .find(|known| path.contains(known.0) && (known.1, known.2, known.3) == (setting, tolerance, held))
                    .map_or(BAND.0, |known| known.4);
                let bottom_measured = tolerance > ROUND_OFF_TOLERANCE;
                if ratio > BAND.1 || (ratio < least && !at_the_floor && bottom_measured) {
                    outside.push(line);
                }
            }
        }
    }
    assert!(outside.is_empty(), "outside the band:\n{}", outside.join("\n"));
}

#[test]
fn the_docked_servicers_errors_lie_in_the_band() {
    band_on("tests/fixtures/constraints/docked_servicer.xml", 40);
}

#[test]
fn the_slider_hands_errors_lie_in_the_band() {
    band_on("tests/fixtures/constraints/slider_hand.xml", 20);
}

#[test]
fn the_limited_arms_errors_lie_in_the_band() {
    band_on("tests/fixtures/constraints/limited_arm.xml", 20);
}

/// MuJoCo's no-slip pass, its decisions held over each step and their
/// switches located: `dop853` at 1e-4 and 1e-8 was below the band with the
/// input held, its interpolants refused, and its tolerance relaxed at 1e-8
/// (docs/integration.md, "The no-slip pass as part of the mode").
#[test]
fn the_no_slip_trees_errors_lie_in_the_band() {
    band_on("tests/fixtures/constraints/noslip_trees.xml", 20);
}

#[test]
fn the_empty_rows_errors_lie_in_the_band() {
    band_on("tests/fixtures/constraints/empty_rows.xml", 20);
}

#[test]
fn refsafe_offs_errors_lie_in_the_band() {
    band_on("tests/fixtures/constraints/refsafe_off.xml", 20);
}

/// Tendon limits, friction loss and tendon equalities: `dop853` at 1e-4
/// with the input held was below the band (0.0078 of the tolerance) while
/// a refused interpolant halved the steps after it ([`interpolant_shrink`]
/// in adaptive.rs, docs/integration.md "The cap after a refusal").
#[test]
fn tendon_limits_errors_lie_in_the_band() {
    band_on("tests/fixtures/tendons/tendon_limits.xml", 20);
}

/// Its one row is dropped, so nothing damps its error: `bs3` delivered the
/// tolerance to the power 1.5 (0.0069 of it at 1e-6, 0.00069 at 1e-8)
/// before the order gap was allowed for (docs/integration.md, "The order
/// gap").
#[test]
fn the_welded_straps_errors_lie_in_the_band() {
    band_on("tests/fixtures/constraints/welded_strap.xml", 20);
}

/// The docked servicer left at rest (ε = 0), 0.01 s communication steps,
/// `tsit5` at 1e-4 with the input held: the pod's weld leaves its impedance
/// piece at 0.1141 s and comes back at 0.1196 s, inside an 11 ms step whose
/// stages at 0.327 and 0.9 of it fall on either side. Read at the middle
/// of that gap, the excursion is located; missed, the state at 0.12 s was
/// 47 times the tolerance off.
#[test]
fn an_excursion_between_two_stages_is_caught_by_the_gap_probe() {
    let model = fixture("tests/fixtures/constraints/docked_servicer.xml");
    let reference = at_rest(&model, Method::Dop853, 1e-12, (0.01, 30));
    let ratio = largest_error(&at_rest(&model, Method::Tsit5, 1e-4, (0.01, 30)), &reference) / 1e-4;
    assert!(ratio <= BAND.1, "largest error/tol {ratio:.3}");
}

/// (θ, ν) at `count` communication points `interval` apart of `model` left
/// to itself (ε = 0 held, so that steps may reach past the points, and no
/// stop time) with `method` at `tolerance`.
fn at_rest(model: &Model, method: Method, tolerance: f64, (interval, count): (f64, usize)) -> Vec<Vec<f64>> {
    let settings = Settings { tolerance, max_step: 0.0, energy_projection: false };
    let mut sim = Simulation::new(model, method, settings);
    sim.initialize(model).unwrap();
    let zero = vec![0.0; model.nv];
    (1..=count)
        .map(|n| {
            let input = Input { eps: &zero, eps_rate: &zero, ctrl: &[], ctrl_rate: &[] };
            sim.advance_to(model, n as f64 * interval, input).unwrap();
            sim.state.theta.iter().chain(&sim.state.nu).copied().collect()
        })
        .collect()
}

/// With MuJoCo's no-slip pass a friction row that sticks has its
/// acceleration taken to its reference −b·v, with no regularizer, so its
/// velocity decays at b; one that slips is clamped and decays at no rate.
/// `dopri5` and `dop853` at 1e-8 on noslip_trees, driven with the input
/// held, land inside the band with those rates (taken as not decaying, the
/// steps were held short by them: `dop853` reached past no point and
/// delivered 4e-4 times the tolerance), and the tolerance is not relaxed.
#[test]
fn friction_rows_the_no_slip_pass_holds_decay_at_their_references_damping() {
    let model = fixture("tests/fixtures/constraints/noslip_trees.xml");
    let fixed = |method| MethodSetting::Fixed(method);
    let (reference, _) = points_relaxing(&model, fixed(Method::Dop853), 1e-12, 20, false);
    for method in [Method::Dopri5, Method::Dop853] {
        let (run, relaxed) = points_relaxing(&model, fixed(method), 1e-8, 20, true);
        assert!(relaxed.is_empty(), "{method:?}: {relaxed:?}");
        let ratio = largest_error(&run.states, &reference.states) / 1e-8;
        assert!((BAND.0..=BAND.1).contains(&ratio), "{method:?}: largest error/tol {ratio:.3}");
    }
}

/// The arm of empty_rows swinging under gravity (ε = 0), 0.05 s
/// communication steps, `dop853` at 1e-3 with the input held: its elbow's
/// limit comes on and off again between the stages at 1/3 and 0.6 of a
/// step, which the probe at 0.467 reads (978 times the tolerance at 0.9 s
/// without it).
#[test]
fn a_limit_touched_between_dop853s_stages_is_caught_by_the_gap_probe() {
    let model = fixture("tests/fixtures/constraints/empty_rows.xml");
    let run = |tolerance| at_rest(&model, Method::Dop853, tolerance, (INTERVAL, 40));
    let ratio = largest_error(&run(1e-3), &run(1e-12)) / 1e-3;
    assert!(ratio <= BAND.1, "largest error/tol {ratio:.3}");
}
