//! Exact derivatives (src/dynamics/derivatives.rs) on random trees with
//! every joint type, springs, dampers and gravity, and on vehicles with
//! every actuator kind: against the dense reference of `common` where the
//! derivative is a matrix it gives (∂θ̈/∂T = M⁻¹, ∂ν/∂θ̇ = m*), and against
//! central differences of the f64 passes, taken along MuJoCo's position
//! integration, elsewhere.

use nalgebra::{DMatrix, DVector};
use nudyn::dynamics::constraint::limit_switching_functions;
use nudyn::dynamics::derivatives::{
    DerivativeError, Derivatives, Direction, Input, Jacobians, Output, Point, ThetaDirection,
};
use nudyn::dynamics::mode::ConstraintMode;
use nudyn::dynamics::velocity::Given;
use nudyn::model::{LinkJoint, Model};
use nudyn::vehicle::Vehicle;
use nudyn::workspace::Workspace;

use crate::common::{self, Rng, TreeOptions, integrate_pos, random_theta, random_vehicle};

/// A random tree (free base or not), its model and a random state.
struct Case {
    vehicle: Vehicle,
    model: Model,
    theta: Vec<f64>,
    velocity: Vec<f64>,
    eps: Vec<f64>,
    torque: Vec<f64>,
    ctrl: Vec<f64>,
    /// The activation states (empty without them).
    act: Vec<f64>,
}

fn case(seed: u64, free_base: bool) -> Case {
    flexible_case(seed, free_base, true, false)
}

/// As [`case`], with 1–2 bodies made flexible when `flexible`
/// (docs/flexible.md), child bodies hanging from their nodes when
/// `children_at_nodes`, bodies welded at nodes when `welded`, and without
/// gravity, joint springs and dampers
/// unless `passive` (the modes' stiffness acts still).
fn flexible_case(seed: u64, free_base: bool, passive: bool, flexible: bool) -> Case {
    with_children(seed, free_base, passive, flexible, false, false)
}

fn with_children(
    seed: u64,
    free_base: bool,
    passive: bool,
    flexible: bool,
    children_at_nodes: bool,
    welded: bool,
) -> Case {
    let mut rng = Rng::new(seed);
    let bodies = 2 + rng.below(7);
    let mut vehicle = random_vehicle(&mut rng, TreeOptions { bodies, free_base, passive, chain: false });
    if flexible {
        crate::common::make_flexible(&mut rng, &mut vehicle, true);
    }
    if children_at_nodes {
        crate::common::attach_children_to_nodes(&mut rng, &mut vehicle);
    }
    if welded {
        crate::common::weld_bodies_to_nodes(&mut rng, &mut vehicle);
    }
    let model = Model::compile(&vehicle).unwrap();
    // MuJoCo's ball spring jumps where the rotation from its rest pose
    // passes half a turn (the rotation vector flips): no configuration
    // within the differences' steps of that.
    let far_from_half_turns = |theta: &[f64]| {
        let balls = model.links.iter().filter(|l| l.joint == LinkJoint::Ball);
        balls.map(|l| l.qpos_adr).all(|q| {
            let rest = &model.qpos_spring[q..q + 4];
            theta[q..q + 4].iter().zip(rest).map(|(a, b)| a * b).sum::<f64>().abs() > 0.05
        })
    };
    let theta = std::iter::repeat_with(|| random_theta(&mut rng, &vehicle)).find(|t| far_from_half_turns(t)).unwrap();
    let (velocity, eps, torque) = (rng.vec(model.nv, 1.5), rng.vec(model.nv, 2.0), rng.vec(model.nv, 3.0));
    Case { vehicle, model, theta, velocity, eps, torque, ctrl: Vec::new(), act: Vec::new() }
}

/// A vehicle file at a random state, with each actuator's ctrl inside the
/// middle of its range (or within ±1), away from the clamp.
fn file_case(path: &str, seed: u64) -> Case {
    file_case_at(path, seed, |rng, vehicle, model| {
        // No joint limit within reach of the differences' steps.
        let mut switches = vec![0.0; model.constraints.limit_sides()];
        let mut ws = model.workspace();
        let mut clear_of_limits = |theta: &[f64]| {
            ws.set_configuration(model, theta).unwrap();
            limit_switching_functions(model, theta, ws.tendon_length.as_slice(), &mut switches);
            switches.iter().all(|s| *s > 0.01)
        };
        std::iter::repeat_with(|| random_theta(rng, vehicle)).find(|t| clear_of_limits(t)).unwrap()
    })
}

/// A vehicle file at θ from `theta`, the rest of the state and the inputs random.
fn file_case_at(path: &str, seed: u64, theta: impl FnOnce(&mut Rng, &Vehicle, &Model) -> Vec<f64>) -> Case {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(path);
    let vehicle = nudyn::mjcf::load_mjcf(&path).unwrap().vehicle;
    let model = Model::compile(&vehicle).unwrap();
    let mut rng = Rng::new(seed);
    let theta = theta(&mut rng, &vehicle, &model);
    let (velocity, eps, torque) = (rng.vec(model.nv, 0.5), rng.vec(model.nv, 1.0), rng.vec(model.nv, 1.0));
    let ctrl = model
        .actuators
        .iter()
        .map(|a| match a.ctrl_range {
            Some([low, high]) if low < high => low + (high - low) * rng.uniform(0.2, 0.8),
            _ => rng.uniform(-1.0, 1.0),
        })
        .collect();
    // act inside the middle of its range (or within ±0.5), away from the clamp.
    let act = model
        .actuators
        .iter()
        .filter_map(|a| a.activation)
        .map(|activation| match activation.range {
            Some([low, high]) => low + (high - low) * rng.uniform(0.3, 0.7),
            None => rng.uniform(-0.5, 0.5),
        })
        .collect();
    Case { vehicle, model, theta, velocity, eps, torque, ctrl, act }
}

fn point(case: &Case, given: Given) -> Point<'_> {
    Point {
        theta: &case.theta,
        velocity: &case.velocity,
        given,
        eps: &case.eps,
        torque: &case.torque,
        ctrl: &case.ctrl,
        act: &case.act,
        time: 0.0,
    }
}

/// One output of the f64 passes at a state: ν̇, θ̈ or the sensors'
/// readings (`output`). With constraint rows, their forces are those of the constraint mode of the
/// state `mode_of` (the limit sides, impedance pieces and solver's working
/// set there, held as the integrators hold them over a step): a smooth
/// function, whose derivative at `mode_of` the dual numbers give.
fn evaluate(model: &Model, point: &Point, mode_of: &Point, output: Output) -> Vec<f64> {
    let mut ws = model.workspace();
    if model.couples_beyond_tree() {
        let mut mode = ConstraintMode::new(model);
        mode.hold_sides(model, &mut ws, mode_of.theta).unwrap();
        evaluate_on(model, &mut ws, mode_of, output);
        let mut start = vec![0.0; mode.len()];
        mode.hold_working_set(&mut ws, &mut start);
    }
    evaluate_on(model, &mut ws, point, output)
}

fn evaluate_on(model: &Model, ws: &mut Workspace, point: &Point, output: Output) -> Vec<f64> {
    ws.set_configuration(model, point.theta).unwrap();
    match point.given {
        Given::Nu => ws.set_nu(model, point.velocity).unwrap(),
        Given::Qvel => ws.set_qvel(model, point.velocity).unwrap(),
    }
    ws.set_act(model, point.act).unwrap();
    let mut applied = vec![0.0; model.nv];
    ws.eps_from_forces(model, point.torque, None, &mut applied).unwrap();
    applied.iter_mut().zip(point.eps).for_each(|(a, e)| *a += e);
    ws.compute_nu_dot_actuated(model, &applied, point.ctrl).unwrap();
    ws.compute_accelerations(model).unwrap();
    match output {
        Output::NuDot => ws.nu_dot.as_slice().to_vec(),
        Output::Qacc => ws.qacc.as_slice().to_vec(),
        Output::Sensordata => {
            ws.compute_sensors(model, &applied, point.ctrl, point.time).unwrap();
            ws.sensordata.as_slice().to_vec()
        }
        Output::ActDot => ws.act_dot.as_slice().to_vec(),
        Output::Momentum => ws.momentum(model).unwrap().as_slice().to_vec(),
        other => unreachable!("{other:?} is given, not evaluated"),
    }
}

/// The Jacobians by central differences of the f64 passes with one
/// Richardson step (error O(h⁴); measured: within 5e-10 of the exact ones
/// on these trees); θ moved by MuJoCo's position integration.
fn differences(case: &Case, given: Given, output: Output) -> Jacobians {
    let (model, nv, nu, na) = (&case.model, case.model.nv, case.model.actuators.len(), case.act.len());
    let h = 1e-3;
    let columns = |which: usize| {
        let count = match which {
            4 => nu,
            5 => na,
            _ => nv,
        };
        let mut jacobian = DMatrix::zeros(output.len(model), count);
        for column in 0..count {
            let at = |step: f64| {
                let moved = |values: &[f64], k: usize| -> Vec<f64> {
                    let mut values = values.to_vec();
                    if k == which {
                        values[column] += step;
                    }
                    values
                };
                let theta = if which == 0 {
                    let mut unit = vec![0.0; nv];
                    unit[column] = 1.0;
                    integrate_pos(&case.vehicle, &case.theta, &unit, step)
                } else {
                    case.theta.clone()
                };
                let (velocity, eps, torque, ctrl, act) = (
                    moved(&case.velocity, 1),
                    moved(&case.eps, 2),
                    moved(&case.torque, 3),
                    moved(&case.ctrl, 4),
                    moved(&case.act, 5),
                );
                let point = Point {
                    theta: &theta,
                    velocity: &velocity,
                    given,
                    eps: &eps,
                    torque: &torque,
                    ctrl: &ctrl,
                    act: &act,
                    time: 0.0,
                };
                DVector::from_vec(evaluate(model, &point, &self::point(case, given), output))
            };
            // ε and T enter linearly: a long step keeps the differences'
            // round-off small where the constraints make M⁻¹'s conditioning
            // poor; not the sensors' (it would cross their cutoffs).
            let h = if (which == 2 || which == 3) && output != Output::Sensordata { 1.0 } else { h };
            let central = |h: f64| (at(h) - at(-h)) / (2.0 * h);
            let richardson = (central(h / 2.0) * 4.0 - central(h)) / 3.0;
            jacobian.set_column(column, &richardson);
        }
        jacobian
    };
    Jacobians {
        theta: columns(0),
        velocity: columns(1),
        eps: columns(2),
        torque: columns(3),
        ctrl: columns(4),
        act: columns(5),
    }
}

/// The zero direction: `zeros` (nv) in θ, velocity, ε and torque, `no_ctrl` in ctrl, none in act.
fn nowhere<'a>(zeros: &'a [f64], no_ctrl: &'a [f64]) -> Direction<'a> {
    Direction {
        theta: zeros,
        theta_in: ThetaDirection::Tangent,
        velocity: zeros,
        eps: zeros,
        torque: zeros,
        ctrl: no_ctrl,
        act: &[],
    }
}

/// max |a − b| / max(1, max |b|) over a matrix.
fn relative(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    common::rel_err(a.as_slice(), b.as_slice())
}

#[test]
fn the_derivative_of_qacc_in_the_joint_forces_is_the_inverse_mass_matrix() {
    for seed in 0..24 {
        let case = case(seed, seed % 2 == 0);
        let mut derivatives = Derivatives::new(&case.model);
        let jacobians = derivatives.jacobians(&case.model, &point(&case, Given::Qvel), Output::Qacc).unwrap();
        let inverse = common::mass_matrix(&case.vehicle, &case.theta).try_inverse().unwrap();
        let error = relative(&jacobians.torque, &inverse);
        assert!(error < 1e-11, "seed {seed}: ∂qacc/∂T differs from M⁻¹ by {error:e}");
    }
}

#[test]
fn the_derivative_of_nu_in_qvel_is_the_factor_and_of_nu_dot_in_eps_the_identity() {
    for seed in 0..24 {
        let case = case(seed, seed % 2 == 1);
        let mut derivatives = Derivatives::new(&case.model);
        let nu = derivatives.jacobians(&case.model, &point(&case, Given::Qvel), Output::Nu).unwrap();
        let m = common::upper_factor(&common::mass_matrix(&case.vehicle, &case.theta));
        let error = relative(&nu.velocity, &m.transpose());
        assert!(error < 1e-10, "seed {seed}: ∂ν/∂θ̇ differs from m* by {error:e}");
        let nu_dot = derivatives.jacobians(&case.model, &point(&case, Given::Nu), Output::NuDot).unwrap();
        let identity = DMatrix::<f64>::identity(case.model.nv, case.model.nv);
        assert_eq!(nu_dot.eps, identity, "seed {seed}: ∂ν̇/∂ε is not exactly the identity");
    }
}

/// Every Jacobian of θ̈ (θ̇ given) and ν̇ (ν given) within `tolerance` of
/// the differences.
fn assert_agrees_with_differences(case: &Case, label: &str, tolerance: f64) {
    assert_outputs_agree_with_differences(
        case,
        label,
        &[(Given::Qvel, Output::Qacc), (Given::Nu, Output::NuDot)],
        tolerance,
    )
}

/// Every Jacobian of each output (its velocity given) within `tolerance`
/// of the differences.
fn assert_outputs_agree_with_differences(case: &Case, label: &str, outputs: &[(Given, Output)], tolerance: f64) {
    let mut derivatives = Derivatives::new(&case.model);
    for &(given, output) in outputs {
        let exact = derivatives.jacobians(&case.model, &point(case, given), output).unwrap();
        let differenced = differences(case, given, output);
        for (what, a, b) in [
            ("theta", &exact.theta, &differenced.theta),
            ("velocity", &exact.velocity, &differenced.velocity),
            ("eps", &exact.eps, &differenced.eps),
            ("torque", &exact.torque, &differenced.torque),
            ("ctrl", &exact.ctrl, &differenced.ctrl),
            ("act", &exact.act, &differenced.act),
        ] {
            let error = relative(a, b);
            assert!(
                error < tolerance,
                "{label}, {output:?} in {what} ({given:?} given): {error:e} from the differences"
            );
        }
    }
}

#[test]
fn jacobians_agree_with_central_differences_of_the_passes() {
    for seed in 0..16 {
        assert_agrees_with_differences(&case(seed, seed % 2 == 0), &format!("seed {seed}"), 1e-8);
    }
}

/// At the file's pose (qpos0: each hinge at its reference angle, where
/// nalgebra's axis-angle rotation is a constant identity) the derivatives
/// in θ still agree: hinges about an axis off the link origin (the boom's
/// deploy hinge, the servicer's arm joints) carried none there before.
#[test]
fn jacobians_at_the_file_pose_agree_with_central_differences() {
    for path in ["tests/fixtures/damped_stiff_boom.xml", "examples/servicer.xml"] {
        let case = file_case_at(path, 3, |_, _, model| model.qpos0.clone());
        assert_agrees_with_differences(&case, &format!("{path} at qpos0"), 1e-8);
    }
}

/// The modal blocks run in dual numbers as the rigid passes do.
#[test]
fn jacobians_of_flexible_vehicles_agree_with_central_differences_of_the_passes() {
    for seed in 0..8 {
        let case = flexible_case(seed, seed % 2 == 0, seed % 4 < 2, true);
        assert!(!case.model.flexible.is_empty());
        assert_agrees_with_differences(&case, &format!("flexible, seed {seed}"), 1e-8);
    }
}

/// A Jacobian's columns along no θ direction reuse the configuration
/// passes of the column before, and the constraint rows' columns of E: each
/// column equals, bit for bit, a run of a fresh workspace (rigid and
/// flexible trees, tendons, constraint rows with welds, limits and the
/// no-slip pass, the tendons' armature, which changes E in place and so is
/// not reused, sensors, actuators with activation states).
#[test]
fn columns_reusing_the_configuration_equal_fresh_runs() {
    let cases = [
        case(1, true),
        flexible_case(2, false, true, true),
        file_case("tests/fixtures/sensors/every_sensor.xml", 0),
        file_case("tests/fixtures/activation/shortcut_servos.xml", 0),
        constrained_case("tests/fixtures/tendons/tendon_limits.xml", 0, 0.5),
        constrained_case("tests/fixtures/constraints/docked_servicer.xml", 0, 0.05),
        constrained_case("tests/fixtures/constraints/noslip_trees.xml", 0, 0.3),
        constrained_case("tests/fixtures/tendons/tendon_armature.xml", 0, 0.5),
    ];
    let outputs = [Output::NuDot, Output::Qacc, Output::Sensordata, Output::ActDot];
    for (index, case) in cases.iter().enumerate() {
        let model = &case.model;
        let at = point(case, Given::Qvel);
        let jacobians = Derivatives::new(model).jacobians_of(model, &at, outputs, &Input::ALL).unwrap();
        let zeros = Input::ALL.map(|input| vec![0.0; input.len(model)]);
        for (k, &input) in Input::ALL.iter().enumerate() {
            for column in 0..input.len(model) {
                let mut unit = zeros[k].clone();
                unit[column] = 1.0;
                let direction = Direction::along(input, &unit, &zeros);
                let mut fresh = Derivatives::new(model);
                fresh.run(model, &at, &direction, &outputs).unwrap();
                for (o, &output) in outputs.iter().enumerate() {
                    let column_of = jacobians[o][k].column(column);
                    assert!(
                        fresh.derivative(output).zip(column_of.iter()).all(|(a, b)| a.to_bits() == b.to_bits()),
                        "case {index}, {output:?} along {input:?}[{column}]: the reused configuration differs"
                    );
                }
            }
        }
    }
}

/// `run_after` takes the configuration's values from an evaluated f64
/// workspace only where its passes ran at the point's θ (a quaternion off
/// unit length included): the derivatives are then the bits of `run`'s;
/// a workspace corrupted after its passes shows that its values are the
/// ones taken, and at another θ or before any pass it is left alone.
#[test]
fn an_evaluated_workspace_lends_its_configuration_at_the_point_only() {
    let mut cases = [
        case(1, true),
        file_case("tests/fixtures/sensors/every_sensor.xml", 0),
        constrained_case("tests/fixtures/constraints/docked_servicer.xml", 0, 0.05),
    ];
    for (index, case) in cases.iter_mut().enumerate() {
        let model = &case.model;
        for link in model.links.iter().filter(|l| l.joint == LinkJoint::Ball) {
            case.theta[link.qpos_adr..link.qpos_adr + 4].iter_mut().for_each(|c| *c *= 1.3);
        }
        let at = point(case, Given::Nu);
        let along: Vec<f64> = (0..model.nq).map(|k| (0.37 * k as f64 + 0.1).sin()).collect();
        let velocity: Vec<f64> = (0..model.nv).map(|k| (0.7 * k as f64).cos()).collect();
        let (zeros, no_ctrl) = (vec![0.0; model.nv], vec![0.0; model.actuators.len()]);
        let direction = Direction {
            theta: &along,
            theta_in: ThetaDirection::Coordinates,
            velocity: &velocity,
            ..nowhere(&zeros, &no_ctrl)
        };
        let outputs = [Output::NuDot, Output::Sensordata];
        let mut reference = Derivatives::new(model);
        reference.run(model, &at, &direction, &outputs).unwrap();
        let derivatives_after = |evaluated: &Workspace| {
            let mut derivatives = Derivatives::new(model);
            derivatives.run_after(model, evaluated, &at, &direction, &outputs).unwrap();
            outputs.map(|output| derivatives.derivative(output).collect::<Vec<_>>())
        };
        let same = |found: &[Vec<f64>; 2]| {
            outputs.iter().zip(found).all(|(&output, found)| {
                reference.derivative(output).zip(found).all(|(a, b)| a.to_bits() == b.to_bits())
            })
        };
        let mut evaluated = model.workspace();
        assert!(same(&derivatives_after(&evaluated)), "case {index}: a workspace before any pass");
        evaluated.set_configuration(model, &case.theta).unwrap();
        assert!(same(&derivatives_after(&evaluated)), "case {index}: a workspace at the point");
        let elsewhere: Vec<f64> = case.theta.iter().map(|q| q + 1e-3).collect();
        evaluated.set_configuration(model, &elsewhere).unwrap();
        assert!(same(&derivatives_after(&evaluated)), "case {index}: a workspace at another θ");
        evaluated.set_configuration(model, &case.theta).unwrap();
        let last = model.links.len() - 1;
        evaluated.r_inv_joint[last][(0, 0)] *= 1.25;
        assert!(!same(&derivatives_after(&evaluated)), "case {index}: the evaluated values were not taken");
    }
}

/// The vehicle's spatial momentum, an output of the FMU, on rigid trees,
/// flexible bodies, children at their nodes and bodies welded there.
#[test]
fn momentum_jacobians_agree_with_central_differences() {
    let outputs = [(Given::Qvel, Output::Momentum), (Given::Nu, Output::Momentum)];
    for seed in 0..12 {
        let case = match seed % 4 {
            0 => case(seed, seed % 2 == 0),
            1 => flexible_case(seed, seed % 2 == 0, true, true),
            2 => with_children(seed, seed % 2 == 0, true, true, true, false),
            _ => with_children(seed, seed % 2 == 0, true, true, true, true),
        };
        assert_outputs_agree_with_differences(&case, &format!("momentum, seed {seed}"), &outputs, 1e-8);
    }
}

/// With child bodies at nodes (docs/flexible.md, "Child bodies at nodes").
#[test]
fn jacobians_with_children_at_nodes_agree_with_central_differences_of_the_passes() {
    for seed in 0..8 {
        let case = with_children(100 + seed, seed % 2 == 0, seed % 4 < 2, true, true, false);
        assert!(case.model.flexible.iter().any(|f| !f.node_children.is_empty()));
        assert_agrees_with_differences(&case, &format!("children at nodes, seed {seed}"), 1e-8);
    }
}

/// With bodies welded at nodes (docs/flexible.md, "Bodies welded at nodes").
#[test]
fn jacobians_with_bodies_welded_at_nodes_agree_with_central_differences_of_the_passes() {
    for seed in 0..8 {
        let case = with_children(200 + seed, seed % 2 == 0, seed % 4 < 2, true, false, true);
        assert!(case.model.flexible.iter().any(|f| !f.welded.is_empty()));
        assert_agrees_with_differences(&case, &format!("bodies welded at nodes, seed {seed}"), 1e-8);
    }
}

/// Every actuator kind, transmission and clamp (tests/fixtures/actuators/kinds.xml),
/// the servicer's thrusters, wheels and arm servos, ctrl away from its clamps,
/// and actuators on sites at a flexible body's nodes (their modal forces).
#[test]
fn actuated_jacobians_agree_with_central_differences_of_the_passes() {
    let files = [
        ("tests/fixtures/actuators/kinds.xml", 0..4),
        ("examples/servicer.xml", 0..2),
        ("tests/fixtures/flex/bench_thruster.xml", 0..2),
    ];
    for (path, seeds) in files {
        for seed in seeds {
            assert_agrees_with_differences(&file_case(path, seed), &format!("{path}, seed {seed}"), 1e-8);
        }
    }
}

/// Activation states through the dual-number passes (integrator, filter
/// and filterexact, limited, read early; MuJoCo's intvelocity and
/// cylinder): ν̇, θ̈ and act_dot in every input, act among them, against
/// central differences of the f64 passes, act inside its range.
#[test]
fn jacobians_with_activation_states_agree_with_central_differences_of_the_passes() {
    for path in ["tests/fixtures/activation/filtered_arm.xml", "tests/fixtures/activation/shortcut_servos.xml"] {
        for seed in 0..3 {
            let case = file_case(path, seed);
            assert!(!case.act.is_empty());
            let outputs = [(Given::Qvel, Output::Qacc), (Given::Nu, Output::NuDot), (Given::Nu, Output::ActDot)];
            assert_outputs_agree_with_differences(&case, &format!("{path}, seed {seed}"), &outputs, 1e-8);
        }
    }
}

/// Tendons through the dual-number passes: fixed and spatial paths, wraps
/// around spheres and cylinders (with side sites), the tendons' springs and
/// dampers, actuators on tendons and their `actuatorfrcrange` scaling.
#[test]
fn jacobians_with_tendons_agree_with_central_differences_of_the_passes() {
    for path in [
        "tests/fixtures/tendons/tendon_wrap.xml",
        "tests/fixtures/tendons/tendon_sidesite.xml",
        "tests/fixtures/tendons/tendon_wrap_fitted.xml",
        "tests/fixtures/tendons/tendon_force_range.xml",
    ] {
        for seed in 0..3 {
            let case = file_case(path, seed);
            assert!(!case.model.tendons.is_empty());
            assert_agrees_with_differences(&case, &format!("{path}, seed {seed}"), 1e-8);
        }
    }
}

/// tendon_sidesite at a state of `tests/python/test_linearize.py`'s draw
/// where the flexor's side site, straight below the cylinder's axis, lies
/// at x = 0 exactly in the wrap's plane, at angle atan2(−0.08, 0): its
/// derivative was NaN there (num-dual differentiates atan(y/x)), and
/// `nudyn linearize` refused the state.
#[test]
fn a_side_site_on_the_wrap_planes_axis_has_finite_derivatives() {
    let theta = vec![
        -0.02696759246661383,
        -0.22154906384346068,
        0.5829093975826143,
        0.9103407876553549,
        0.057286411113582264,
        -0.4031590199986246,
        0.07389669834642376,
        0.185800239422986,
        1.0987461717255034,
        -0.5587167206748891,
        0.31260625317915913,
    ];
    let case = file_case_at("tests/fixtures/tendons/tendon_sidesite.xml", 7, |_, _, _| theta);
    assert_agrees_with_differences(&case, "tendon_sidesite, side site at x = 0", 1e-8);
}

/// A constrained vehicle file near its qpos0 (each dof moved by up to
/// `spread` in the tangent space, velocities up to 0.5), the actuators' ctrl
/// inside their ranges.
fn constrained_case(path: &str, seed: u64, spread: f64) -> Case {
    file_case_at(path, seed, |rng, vehicle, model| {
        integrate_pos(vehicle, &model.qpos0, &rng.vec(model.nv, spread), 1.0)
    })
}

/// Constraint forces at the constraint mode of the point (equality rows,
/// friction loss, joint and tendon limits with sides active), against the
/// differences of the f64 passes with that mode held: the docked
/// servicer (welds, a connect, a joint coupling, friction loss, limits) and
/// the other constrained fixtures, and the tendon fixtures with friction
/// loss, limits and tendon couplings.
#[test]
fn constrained_jacobians_agree_with_central_differences_at_the_mode() {
    let mut rows_seen = 0;
    for (path, spread) in [
        ("tests/fixtures/constraints/docked_servicer.xml", 0.05),
        ("tests/fixtures/constraints/limited_arm.xml", 1.0),
        ("tests/fixtures/constraints/slider_hand.xml", 0.3),
        ("tests/fixtures/constraints/welded_strap.xml", 0.3),
        ("tests/fixtures/constraints/refsafe_off.xml", 0.3),
        ("tests/fixtures/constraints/empty_rows.xml", 0.3),
        ("tests/fixtures/constraints/noslip_trees.xml", 0.3),
        ("tests/fixtures/tendons/tendon_armature.xml", 0.5),
        ("tests/fixtures/tendons/tendon_finger.xml", 0.5),
        ("tests/fixtures/tendons/tendon_limits.xml", 0.5),
    ] {
        for seed in 0..3 {
            let case = constrained_case(path, seed, spread);
            assert_agrees_with_differences(&case, &format!("{path}, seed {seed}"), 1e-8);
            let mut ws = case.model.workspace();
            evaluate_on(&case.model, &mut ws, &point(&case, Given::Qvel), Output::Qacc);
            rows_seen += ws.constraint_rows.count;
        }
    }
    assert!(rows_seen > 50, "only {rows_seen} constraint rows active over the cases");
}

/// Every kind of sensor through the dual numbers: ∂sensordata/∂(δq, θ̇,
/// ε, T, ctrl) and ∂sensordata/∂ν against the differences of the f64
/// sensors (`compute_sensors`), at random states: every_sensor.xml (joint,
/// ball, frame, subtree, gyro, velocimeter, magnetometer, accelerometer and
/// actuator sensors, cutoffs, the clock), the force and torque fixtures
/// (welded bodies), sites at a flexible body's nodes, mocap frames; and at
/// the constraint mode of the point, the docked servicer (force and torque
/// sensors with welds and a connect, joint limit sensors), the joint and
/// tendon limit sensors of limited_arm and tendon_limits, empty_rows'
/// force and torque with a spatial tendon's limit, and tendon_armature's
/// tendon and accelerometer readings with the tendons' armature. A run's
/// readings are the f64 sensors' (the clock's time included) to round-off.
#[test]
fn sensor_jacobians_agree_with_central_differences_of_the_sensors() {
    let outputs = [(Given::Qvel, Output::Sensordata), (Given::Nu, Output::Sensordata)];
    for (path, seeds) in [
        ("tests/fixtures/sensors/every_sensor.xml", 0..3),
        ("tests/fixtures/sensors/force_torque.xml", 0..2),
        ("tests/fixtures/sensors/frames_mocap.xml", 0..1),
        ("tests/fixtures/flex/bench_sensors.xml", 0..2),
    ] {
        for seed in seeds {
            let case = file_case(path, seed);
            assert!(!case.model.sensors.is_empty());
            assert_outputs_agree_with_differences(&case, &format!("{path}, seed {seed}"), &outputs, 1e-7);
            assert_sensor_values_are_the_f64_sensors(&case, &format!("{path}, seed {seed}"));
        }
    }
    for (path, spread) in [
        ("tests/fixtures/constraints/docked_servicer.xml", 0.05),
        ("tests/fixtures/constraints/limited_arm.xml", 1.0),
        ("tests/fixtures/tendons/tendon_limits.xml", 0.5),
        ("tests/fixtures/constraints/empty_rows.xml", 0.3),
        // A spatial tendon's actuator force and an accelerometer with the tendons' armature.
        ("tests/fixtures/tendons/tendon_armature.xml", 0.3),
    ] {
        for seed in 0..2 {
            let case = constrained_case(path, seed, spread);
            assert_outputs_agree_with_differences(&case, &format!("{path}, seed {seed}"), &outputs, 1e-7);
            assert_sensor_values_are_the_f64_sensors(&case, &format!("{path}, seed {seed}"));
        }
    }
}

/// At the file's pose the modal coordinates are 0, where nalgebra's
/// exponential of a rotation vector is a constant identity: the readings of
/// sites at nodes, and of a body hanging from a node, still have their
/// derivatives in η there.
#[test]
fn sensor_jacobians_at_rest_of_the_modes_agree_with_central_differences() {
    let outputs = [(Given::Qvel, Output::Sensordata), (Given::Nu, Output::Sensordata)];
    for path in ["tests/fixtures/flex/bench_sensors.xml", "tests/fixtures/flex/bench_child.xml"] {
        let case = file_case_at(path, 1, |_, _, model| model.qpos0.clone());
        assert!(case.model.flexible.iter().all(|f| f.eta(&case.theta).iter().all(|e| *e == 0.0)));
        assert_outputs_agree_with_differences(&case, &format!("{path} at qpos0"), &outputs, 1e-7);
    }
}

fn assert_sensor_values_are_the_f64_sensors(case: &Case, label: &str) {
    let model = &case.model;
    let (zeros, no_ctrl) = (vec![0.0; model.nv], vec![0.0; model.actuators.len()]);
    let at = Point { time: 0.25, ..point(case, Given::Qvel) };
    let mut derivatives = Derivatives::new(model);
    derivatives.run(model, &at, &nowhere(&zeros, &no_ctrl), &[Output::Sensordata]).unwrap();
    let values: Vec<f64> = derivatives.value(Output::Sensordata).collect();
    let error = common::rel_err(&values, &evaluate(model, &at, &at, Output::Sensordata));
    assert!(error < 1e-12, "{label}: the readings differ from the f64 sensors' by {error:e}");
}

/// A reading clamped at its `cutoff` has derivative 0; one exactly at
/// it is on a switch of the clamp, refused with the sensor named.
#[test]
fn a_reading_at_its_cutoff_is_a_switch_and_past_it_is_held() {
    let mut case = file_case("tests/fixtures/sensors/every_sensor.xml", 0);
    let model = &case.model;
    let (index, sensor) = model.sensors.iter().enumerate().find(|(_, s)| s.cutoff > 0.0).unwrap();
    let nudyn::model::SensorSource::Joint { qpos, .. } = sensor.source else {
        panic!("the first cutoff is a jointpos's")
    };
    let (adr, cutoff) = (sensor.adr, sensor.cutoff);
    let mut derivatives = Derivatives::new(model);
    let (nv, nu) = (model.nv, model.actuators.len());
    case.theta[qpos] = 2.0 * cutoff;
    let jacobians = derivatives.jacobians(model, &point(&case, Given::Qvel), Output::Sensordata).unwrap();
    assert!(jacobians.theta.row(adr).iter().all(|d| *d == 0.0), "{}", jacobians.theta.row(adr));
    case.theta[qpos] = cutoff;
    let (zeros, no_ctrl) = (vec![0.0; nv], vec![0.0; nu]);
    let refused = derivatives
        .run(&case.model, &point(&case, Given::Qvel), &nowhere(&zeros, &no_ctrl), &[Output::Sensordata])
        .unwrap_err();
    let named = format!("{}'s reading (sensordata[{}]) at its cutoff", case.model.sensors[index].label(index), adr + 1);
    assert_eq!(refused, DerivativeError::OnSwitch(named));
}

/// On a switch (the elbow's upper side exactly at its margin) a run is
/// refused; with the mode an f64 workspace holds there (as an FMU holds
/// one between events) it gives that mode's derivatives, which agree with
/// the differences of the f64 passes with the mode held.
#[test]
fn a_held_mode_gives_its_derivatives_on_a_switch() {
    let mut case = constrained_case("tests/fixtures/constraints/limited_arm.xml", 5, 0.3);
    let model = &case.model;
    let elbow = model.joints.iter().position(|j| j.name == "elbow").unwrap();
    let limit = model.constraints.limits.iter().find(|l| l.joint == elbow).unwrap();
    case.theta[limit.qpos] = limit.range[1] - limit.margin;
    let mut derivatives = Derivatives::new(model);
    let (nv, nu) = (model.nv, model.actuators.len());
    let (zeros, no_ctrl) = (vec![0.0; nv], vec![0.0; nu]);
    let along = nowhere(&zeros, &no_ctrl);
    let at = point(&case, Given::Qvel);
    let refused = derivatives.run(model, &at, &along, &[Output::Qacc]).unwrap_err();
    assert!(
        matches!(&refused, DerivativeError::OnSwitch(s) if s.contains("upper limit of joint 'elbow'")),
        "{refused}"
    );

    let mut ws = model.workspace();
    let mut mode = ConstraintMode::new(model);
    mode.hold_sides(model, &mut ws, at.theta).unwrap();
    evaluate_on(model, &mut ws, &at, Output::Qacc);
    let mut start = vec![0.0; mode.len()];
    mode.hold_working_set(&mut ws, &mut start);
    derivatives.hold_constraint_mode_of(&ws.constraint_rows);
    let exact = derivatives.jacobians(model, &at, Output::Qacc).unwrap();
    let differenced = differences(&case, Given::Qvel, Output::Qacc);
    for (what, a, b) in
        [("theta", &exact.theta, &differenced.theta), ("velocity", &exact.velocity, &differenced.velocity)]
    {
        let error = relative(a, b);
        assert!(error < 1e-8, "{what}: {error:e} from the held mode's differences");
    }
}

/// A run's values are those of the f64 passes to round-off (not bit for
/// bit: num-dual divides by multiplying with the reciprocal).
#[test]
fn a_run_gives_the_f64_values() {
    for seed in 0..8 {
        let case = case(seed, true);
        let mut derivatives = Derivatives::new(&case.model);
        let nv = case.model.nv;
        let zeros = vec![0.0; nv];
        let direction = nowhere(&zeros, &[]);
        for (given, output) in [(Given::Qvel, Output::Qacc), (Given::Nu, Output::NuDot)] {
            derivatives.run(&case.model, &point(&case, given), &direction, &[output]).unwrap();
            let values: Vec<f64> = derivatives.value(output).collect();
            let at = point(&case, given);
            let passes = evaluate(&case.model, &at, &at, output);
            let error = common::rel_err(&values, &passes);
            assert!(error < 1e-13, "seed {seed}, {output:?}: {error:e}");
            assert!(derivatives.derivative(output).all(|d| d == 0.0), "seed {seed}: a zero direction moved {output:?}");
        }
    }
}

/// A direction in θ's coordinates that is a tangent direction written out
/// (a quaternion's q ⊗ (0, δ/2)) gives the tangent direction's derivative.
#[test]
fn coordinate_and_tangent_directions_agree() {
    for seed in 0..8 {
        let case = case(seed, true);
        let mut derivatives = Derivatives::new(&case.model);
        let (nq, nv) = (case.model.nq, case.model.nv);
        let mut rng = Rng::new(100 + seed);
        let tangent = rng.vec(nv, 1.0);
        // θ's rate along the tangent direction, by differences of the
        // position integration (exact to O(h²) for a quaternion's product).
        let h = 1e-6;
        let plus = integrate_pos(&case.vehicle, &case.theta, &tangent, h);
        let minus = integrate_pos(&case.vehicle, &case.theta, &tangent, -h);
        let coordinates: Vec<f64> = plus.iter().zip(&minus).map(|(p, m)| (p - m) / (2.0 * h)).collect();
        assert_eq!(coordinates.len(), nq);
        let zeros = vec![0.0; nv];
        let mut along = |theta: &[f64], theta_in| {
            let direction =
                Direction { theta, theta_in, velocity: &zeros, eps: &zeros, torque: &zeros, ctrl: &[], act: &[] };
            derivatives.run(&case.model, &point(&case, Given::Qvel), &direction, &[Output::Qacc]).unwrap();
            derivatives.derivative(Output::Qacc).collect::<Vec<f64>>()
        };
        let from_tangent = along(&tangent, ThetaDirection::Tangent);
        let from_coordinates = along(&coordinates, ThetaDirection::Coordinates);
        let error = common::rel_err(&from_coordinates, &from_tangent);
        assert!(error < 1e-8, "seed {seed}: {error:e}");
    }
}

#[test]
fn points_on_a_switch_and_bad_points_are_refused() {
    // The shoulder exactly where its upper side becomes a row: a switch.
    let mut at_a_limit = file_case("tests/fixtures/actuators/kinds.xml", 0);
    let shoulder = at_a_limit.model.joints.iter().position(|j| j.name == "shoulder").unwrap();
    let limit = at_a_limit.model.constraints.limits.iter().find(|l| l.joint == shoulder).unwrap();
    at_a_limit.theta[limit.qpos] = limit.range[1] - limit.margin;
    let mut derivatives = Derivatives::new(&at_a_limit.model);
    let (nv, nu) = (at_a_limit.model.nv, at_a_limit.model.actuators.len());
    let (zeros, no_ctrl) = (vec![0.0; nv], vec![0.0; nu]);
    let along = nowhere(&zeros, &no_ctrl);
    let error =
        derivatives.run(&at_a_limit.model, &point(&at_a_limit, Given::Qvel), &along, &[Output::Qacc]).unwrap_err();
    assert_eq!(error, DerivativeError::OnSwitch("the upper limit of joint 'shoulder' at its margin".into()), "{error}");

    let case = case(3, true);
    let mut derivatives = Derivatives::new(&case.model);
    let nv = case.model.nv;
    let zeros = vec![0.0; nv];
    let short = vec![0.0; nv - 1];
    let direction = Direction {
        theta: &short,
        theta_in: ThetaDirection::Tangent,
        velocity: &zeros,
        eps: &zeros,
        torque: &zeros,
        ctrl: &[],
        act: &[],
    };
    let error = derivatives.run(&case.model, &point(&case, Given::Qvel), &direction, &[Output::Qacc]).unwrap_err();
    assert_eq!(error, DerivativeError::DirectionLength { what: "theta", expected: nv, found: nv - 1 });
    let mut eps = case.eps.clone();
    eps[1] = f64::NAN;
    let bad = Point { eps: &eps, ..point(&case, Given::Qvel) };
    let direction = nowhere(&zeros, &[]);
    let error = derivatives.run(&case.model, &bad, &direction, &[Output::Qacc]).unwrap_err();
    assert!(error.to_string().contains("eps[2] is not finite"), "{error}");
}
