//! The closed-form θ̈ Jacobian (src/dynamics/qacc_jacobian.rs) against the
//! dual numbers of derivatives.rs, an independent route (every pass run in
//! dual numbers, column by column), on random trees with every joint type,
//! gravity, springs, dampers, armature and joint forces, and on the example
//! vehicles; and what it refuses.

use nalgebra::DMatrix;
use nudyn::dynamics::derivatives::{DerivativeError, Derivatives, Output, Point};
use nudyn::dynamics::qacc_jacobian::QaccJacobian;
use nudyn::dynamics::velocity::Given;
use nudyn::model::Model;
use nudyn::vehicle::{JointKind, Vehicle};

use crate::common::{self, Rng, TreeOptions, random_theta, random_vehicle};

/// ∂θ̈/∂Δ and ∂θ̈/∂θ̇ in closed form and in dual numbers, at (θ, θ̇) under
/// an applied ε and joint forces `torque`.
fn both_ways(
    model: &Model,
    (theta, qvel): (&[f64], &[f64]),
    (eps, torque, ctrl): (&[f64], &[f64], &[f64]),
) -> [(DMatrix<f64>, DMatrix<f64>); 2] {
    let nv = model.nv;
    let mut closed = (DMatrix::zeros(nv, nv), DMatrix::zeros(nv, nv));
    QaccJacobian::new(model)
        .unwrap()
        .compute(model, (theta, qvel), (eps, torque, ctrl), (&mut closed.0, &mut closed.1))
        .unwrap();
    let point = Point { theta, velocity: qvel, given: Given::Qvel, eps, torque, ctrl, act: &[], time: 0.0 };
    let duals = Derivatives::new(model).jacobians(model, &point, Output::Qacc).unwrap();
    [closed, (duals.theta, duals.velocity)]
}

fn assert_agree(model: &Model, state: (&[f64], &[f64]), forces: (&[f64], &[f64], &[f64]), label: &str) {
    let [(by_delta, by_qvel), (dual_by_delta, dual_by_qvel)] = both_ways(model, state, forces);
    let errors = [
        common::rel_err(by_delta.as_slice(), dual_by_delta.as_slice()),
        common::rel_err(by_qvel.as_slice(), dual_by_qvel.as_slice()),
    ];
    assert!(errors.iter().all(|e| *e < 1e-10), "{label}: ∂θ̈/∂Δ and ∂θ̈/∂θ̇ differ from the duals' by {errors:?}");
}

/// A vehicle file of the repository (its path from the root), imported and compiled.
fn load(file: &str) -> (Vehicle, Model) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(file);
    let vehicle = nudyn::mjcf::load_mjcf(&path).unwrap().vehicle;
    let model = Model::compile(&vehicle).unwrap();
    (vehicle, model)
}

/// A random tree with gravity, springs and dampers, but none on ball
/// joints (a free joint's rotation is one), whose spring the closed form refuses.
fn random_case(seed: u64) -> (Model, Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
    let mut rng = Rng::new(seed);
    let bodies = 2 + rng.below(7);
    let options =
        TreeOptions { bodies, free_base: seed.is_multiple_of(2), passive: true, chain: seed.is_multiple_of(3) };
    let mut vehicle: Vehicle = random_vehicle(&mut rng, options);
    for joint in vehicle.bodies.iter_mut().flat_map(|b| b.joints.iter_mut()) {
        if matches!(joint.kind, JointKind::Ball | JointKind::Free) {
            joint.stiffness = 0.0;
        }
    }
    let model = Model::compile(&vehicle).unwrap();
    let theta = random_theta(&mut rng, &vehicle);
    let (qvel, eps, torque) = (rng.vec(model.nv, 1.5), rng.vec(model.nv, 2.0), rng.vec(model.nv, 3.0));
    (model, theta, qvel, eps, torque)
}

#[test]
fn the_closed_form_agrees_with_the_dual_numbers_on_random_trees() {
    for seed in 0..60 {
        let (model, theta, qvel, eps, torque) = random_case(seed);
        let zeros = vec![0.0; model.nv];
        // Without ε, and with ε (its joint forces m(θ)ε turn with θ).
        assert_agree(&model, (&theta, &qvel), (&zeros, &torque, &[]), &format!("seed {seed}, no ε"));
        assert_agree(&model, (&theta, &qvel), (&eps, &torque, &[]), &format!("seed {seed}, with ε"));
    }
}

#[test]
fn the_closed_form_agrees_with_the_dual_numbers_on_the_examples() {
    for name in ["bus_arm7", "chain60", "fixed_rig", "flexible_boom"] {
        let (vehicle, model) = load(&format!("examples/{name}.xml"));
        let mut rng = Rng::new(7);
        for repeat in 0..3 {
            let theta = random_theta(&mut rng, &vehicle);
            let (qvel, eps, torque) = (rng.vec(model.nv, 1.0), rng.vec(model.nv, 1.0), rng.vec(model.nv, 1.0));
            assert_agree(&model, (&theta, &qvel), (&eps, &torque, &[]), &format!("{name}, state {repeat}"));
        }
    }
}

/// Joint actuators of every gain and bias, at controls inside their ranges
/// and past them, and with forces inside and past their force ranges
/// (the clamps hold their pieces, derivative 0, as the passes' own do);
/// and the servicer's thrusters (motors on sites) with its wheel motors
/// and arm servos.
#[test]
fn the_closed_form_agrees_with_the_dual_numbers_with_actuators() {
    for (file, ctrl_scale) in [("tests/fixtures/actuators/joint_servos.xml", 2.5), ("examples/servicer.xml", 25.0)] {
        agrees_with_actuators(file, ctrl_scale);
    }
}

/// [`the_closed_form_agrees_with_the_dual_numbers_with_actuators`] on one
/// file, ctrl within ±`ctrl_scale` (past the ranges at times).
fn agrees_with_actuators(file: &str, ctrl_scale: f64) {
    let (vehicle, model) = load(file);
    let mut rng = Rng::new(11);
    let mut clamped = [0usize; 2];
    for repeat in 0..40 {
        let theta = random_theta(&mut rng, &vehicle);
        let (qvel, eps, torque) = (rng.vec(model.nv, 1.5), rng.vec(model.nv, 1.0), rng.vec(model.nv, 1.0));
        let ctrl = rng.vec(model.actuators.len(), ctrl_scale);
        for (actuator, c) in model.actuators.iter().zip(&ctrl) {
            if actuator.ctrl_range.is_some_and(|[low, high]| *c < low || *c > high) {
                clamped[0] += 1;
            }
        }
        let mut ws = model.workspace();
        ws.set_configuration(&model, &theta).unwrap();
        ws.set_qvel(&model, &qvel).unwrap();
        ws.compute_qacc_actuated(&model, &eps, &ctrl).unwrap();
        for (k, actuator) in model.actuators.iter().enumerate() {
            if actuator.force_range.is_some_and(|[low, high]| {
                let force = ws.actuator_force[k];
                force <= low || force >= high
            }) {
                clamped[1] += 1;
            }
        }
        assert_agree(&model, (&theta, &qvel), (&eps, &torque, &ctrl), &format!("{file}, state {repeat}"));
    }
    let has_force_ranges = model.actuators.iter().any(|a| a.force_range.is_some());
    assert!(
        clamped[0] > 5 && (clamped[1] > 5 || !has_force_ranges),
        "{file}: ctrl clamped {} times, forces {} times: too few",
        clamped[0],
        clamped[1]
    );
}

#[test]
fn the_closed_form_refuses_what_it_leaves_out() {
    let (model, theta, qvel, mut eps, torque) = random_case(1);
    let nv = model.nv;
    eps[nv - 1] = f64::NAN;
    let mut out = (DMatrix::zeros(nv, nv), DMatrix::zeros(nv, nv));
    let mut closed_form = QaccJacobian::new(&model).unwrap();
    let refused = closed_form.compute(&model, (&theta, &qvel), (&eps, &torque, &[]), (&mut out.0, &mut out.1));
    assert_eq!(refused.unwrap_err().to_string(), format!("eps[{nv}] is not finite (NaN)"));
    let refused = closed_form.compute(&model, (&theta, &qvel), (&torque[1..], &torque, &[]), (&mut out.0, &mut out.1));
    assert_eq!(refused.unwrap_err().to_string(), format!("eps has {} entries, expected {nv}", nv - 1));

    let (_, filtered) = load("tests/fixtures/activation/filtered_arm.xml");
    let refused = QaccJacobian::new(&filtered).unwrap_err().to_string();
    assert!(refused.contains("activation states"), "{refused}");

    let mut rng = Rng::new(3);
    let options = TreeOptions { bodies: 3, free_base: true, passive: true, chain: true };
    let mut vehicle = random_vehicle(&mut rng, options);
    vehicle.bodies[0].joints[0].stiffness = 2.0;
    let sprung = Model::compile(&vehicle).unwrap();
    assert_eq!(QaccJacobian::new(&sprung).unwrap_err(), DerivativeError::Unsupported("springs on ball joints"));
}

/// `nudyn linearize` takes the closed form when only θ and its rates are
/// asked for; asked for ν too, it runs the dual numbers. The two give the
/// same A and B, for the joint forces and for ε (∂θ̈/∂ε = ℓ*, the
/// transpose of ℓ's columns), at points with ε and T held.
#[test]
fn linearize_gives_the_same_matrices_by_either_route() {
    use nudyn::linearize::{Inputs, LinearOutput, OperatingPoint, linearize};
    for seed in 0..12 {
        let (model, theta, qvel, eps, torque) = random_case(seed);
        let point = OperatingPoint { qpos: theta, qvel, act: Vec::new(), eps, torque, ctrl: Vec::new() };
        for inputs in [Inputs::Torque, Inputs::Eps] {
            let closed = linearize(&model, &point, inputs, &[LinearOutput::Qacc], None).unwrap();
            let duals = linearize(&model, &point, inputs, &[LinearOutput::Qacc, LinearOutput::Nu], None).unwrap();
            let errors = [
                common::rel_err(closed.a.as_slice(), duals.a.as_slice()),
                common::rel_err(closed.b.as_slice(), duals.b.as_slice()),
            ];
            assert!(errors.iter().all(|e| *e < 1e-10), "seed {seed}, {inputs:?}: A and B differ by {errors:?}");
        }
    }
    // Joint and site actuators: ctrl as the input, some past their ranges.
    for (file, ctrl_scale) in [("tests/fixtures/actuators/joint_servos.xml", 2.0), ("examples/servicer.xml", 25.0)] {
        linearize_with_ctrl_by_either_route(file, ctrl_scale);
    }
}

/// [`linearize_gives_the_same_matrices_by_either_route`] with ctrl as the
/// input, ctrl within ±`ctrl_scale`.
fn linearize_with_ctrl_by_either_route(file: &str, ctrl_scale: f64) {
    use nudyn::linearize::{Inputs, LinearOutput, OperatingPoint, linearize};
    let (vehicle, model) = load(file);
    let mut rng = Rng::new(13);
    for repeat in 0..8 {
        let point = OperatingPoint {
            qpos: random_theta(&mut rng, &vehicle),
            qvel: rng.vec(model.nv, 1.0),
            act: Vec::new(),
            eps: rng.vec(model.nv, 1.0),
            torque: rng.vec(model.nv, 1.0),
            ctrl: rng.vec(model.actuators.len(), ctrl_scale),
        };
        let closed = linearize(&model, &point, Inputs::Ctrl, &[LinearOutput::Qacc], None).unwrap();
        let duals = linearize(&model, &point, Inputs::Ctrl, &[LinearOutput::Qacc, LinearOutput::Nu], None).unwrap();
        let errors = [
            common::rel_err(closed.a.as_slice(), duals.a.as_slice()),
            common::rel_err(closed.b.as_slice(), duals.b.as_slice()),
        ];
        assert!(errors.iter().all(|e| *e < 1e-10), "{file}, state {repeat}: A and B differ by {errors:?}");
    }
}
