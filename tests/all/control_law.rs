//! The noninteracting control law (src/control) against independent dense
//! computations from `common`: ε of a wrench = m⁻¹Jᵀf with J the dense
//! point Jacobian and m the upper factor of the dense mass matrix; joint
//! targets the same with J a selection; and the Lyapunov property, that the
//! configuration term is −∂U/∂θ mapped by ℓ (dU/dt = −ν·g along any motion,
//! by central differences of U along MuJoCo's position integration).

use crate::common;

use crate::common::{Rng, TreeOptions, random_theta, random_vehicle, rel_err};
use nalgebra::{DVector, Rotation3, UnitQuaternion};
use nudyn::control::{BodyFrame, ControlError, ControlLaw, ControlParameters, ControlWorkspace, Objective};
use nudyn::math::{SpatialVec, Vec3, spatial};
use nudyn::model::Model;
use nudyn::vehicle::{Body, JointKind, Vehicle};

fn vehicle(seed: u64) -> Vehicle {
    let mut rng = Rng::new(seed);
    let bodies = 2 + rng.below(6);
    random_vehicle(&mut rng, TreeOptions { bodies, free_base: seed.is_multiple_of(2), passive: false, chain: false })
}

/// m⁻¹ x with m the dense upper factor of M(θ).
fn dense_l(vehicle: &Vehicle, theta: &[f64], x: &DVector<f64>) -> DVector<f64> {
    let m = common::upper_factor(&common::mass_matrix(vehicle, theta));
    m.solve_upper_triangular(x).expect("m is invertible")
}

fn random_parameters(rng: &mut Rng, model: &Model, law: &ControlLaw) -> ControlParameters {
    let mut parameters = law.default_parameters(model).unwrap();
    parameters.c1 = (0..model.nv).map(|_| rng.uniform(0.0, 3.0)).collect();
    parameters.c2 = (0..law.ny()).map(|_| rng.uniform(0.0, 20.0)).collect();
    parameters
}

#[test]
fn eps_of_a_wrench_is_l_jt_f() {
    for seed in 0..40 {
        let vehicle = vehicle(seed);
        let model = Model::compile(&vehicle).unwrap();
        let mut rng = Rng::new(1000 + seed);
        let body = rng.below(vehicle.bodies.len());
        let frame = BodyFrame::find(&vehicle, &model, &vehicle.bodies[body].name).unwrap();
        let law = ControlLaw { objective: Objective::Pose(frame.clone()) };
        let mut cws = ControlWorkspace::new(&model, &law);
        let theta = random_theta(&mut rng, &vehicle);
        let (moment, force) = (rng.vec3(2.0), rng.vec3(5.0));
        cws.ws.set_configuration(&model, &theta).unwrap();
        let mut eps = vec![0.0; model.nv];
        cws.eps_of_wrench(&model, &frame, &spatial(&moment, &force), &mut eps).unwrap();

        let k = common::kinematics(&vehicle, &theta);
        let (jw, jv) = common::point_jacobian(&k, body, &k.body_pos[body], model.nv);
        let torque = jv.transpose() * DVector::from_column_slice(force.as_slice())
            + jw.transpose() * DVector::from_column_slice(moment.as_slice());
        let expected = dense_l(&vehicle, &theta, &torque);
        let err = rel_err(&eps, expected.as_slice());
        assert!(err < 1e-10, "seed {seed}, body {}: error {err:.2e}", vehicle.bodies[body].name);
    }
}

#[test]
fn joint_targets_match_the_dense_law() {
    for seed in 0..30 {
        let vehicle = vehicle(seed);
        let model = Model::compile(&vehicle).unwrap();
        let Ok(law) = ControlLaw::joints(&model) else { continue };
        let Objective::Joints(joints) = &law.objective else { unreachable!() };
        let mut rng = Rng::new(2000 + seed);
        let mut parameters = random_parameters(&mut rng, &model, &law);
        parameters.target = (0..law.ny()).map(|_| rng.uniform(-1.0, 1.0)).collect();
        let theta = random_theta(&mut rng, &vehicle);
        let nu = rng.vec(model.nv, 1.0);
        let mut cws = ControlWorkspace::new(&model, &law);
        cws.evaluate(&model, &law, &parameters, &theta, &nu).unwrap();

        let mut torque = DVector::zeros(model.nv);
        let mut potential = 0.0;
        for (k, joint) in joints.iter().enumerate() {
            let error = parameters.target[k] - theta[joint.qpos_adr];
            assert!((cws.error[k] - error).abs() < 1e-15);
            torque[joint.dof_adr] = parameters.c2[k] * error;
            potential += 0.5 * parameters.c2[k] * error * error;
        }
        let c1_nu = DVector::from_iterator(model.nv, parameters.c1.iter().zip(&nu).map(|(c, n)| c * n));
        let expected = dense_l(&vehicle, &theta, &torque) - c1_nu;
        let err = rel_err(cws.eps.as_slice(), expected.as_slice());
        assert!(err < 1e-10, "seed {seed}: error {err:.2e}");
        assert!((cws.potential - potential).abs() <= 1e-12 * potential.max(1.0));
    }
}

#[test]
fn pose_error_is_position_and_rotation_vector_from_dense_kinematics() {
    for seed in 0..20 {
        let vehicle = vehicle(seed);
        let model = Model::compile(&vehicle).unwrap();
        let mut rng = Rng::new(3000 + seed);
        let body = rng.below(vehicle.bodies.len());
        let law = ControlLaw::pose(&vehicle, &model, &vehicle.bodies[body].name).unwrap();
        let mut parameters = random_parameters(&mut rng, &model, &law);
        let target_position = rng.vec3(2.0);
        let target_rotation = rng.unit_quat();
        parameters.target = vec![
            target_position.x,
            target_position.y,
            target_position.z,
            target_rotation.w,
            target_rotation.i,
            target_rotation.j,
            target_rotation.k,
        ];
        let theta = random_theta(&mut rng, &vehicle);
        let mut cws = ControlWorkspace::new(&model, &law);
        cws.evaluate(&model, &law, &parameters, &theta, &vec![0.0; model.nv]).unwrap();

        let k = common::kinematics(&vehicle, &theta);
        let position_error = target_position - k.body_pos[body];
        let relative = target_rotation.to_rotation_matrix().into_inner().transpose() * k.body_rot[body];
        let phi = Rotation3::from_matrix(&relative).scaled_axis();
        let expected: Vec<f64> = position_error.iter().copied().chain(phi.iter().map(|x| -x)).collect();
        let err = rel_err(cws.error.as_slice(), &expected);
        assert!(err < 1e-10, "seed {seed}: error {err:.2e}\n{:?}\n{expected:?}", cws.error.as_slice());
    }
}

/// Central difference (4th order) of f at s = 0 with step h.
fn derivative(f: impl Fn(f64) -> f64, h: f64) -> f64 {
    (8.0 * (f(h) - f(-h)) - (f(2.0 * h) - f(-2.0 * h))) / (12.0 * h)
}

/// dU/dt along θ̇ = u must be −ν·g, ν = m*u, g the configuration term.
fn check_gradient(
    vehicle: &Vehicle,
    model: &Model,
    law: &ControlLaw,
    parameters: &ControlParameters,
    rng: &mut Rng,
) -> Result<(), String> {
    let theta = random_theta(rng, vehicle);
    let qvel = rng.vec(model.nv, 1.0);
    let mut cws = ControlWorkspace::new(model, law);
    let potential_at = |s: f64| {
        let mut cws = ControlWorkspace::new(model, law);
        let moved = common::integrate_pos(vehicle, &theta, &qvel, s);
        cws.evaluate(model, law, parameters, &moved, &vec![0.0; model.nv]).unwrap();
        cws.potential
    };
    cws.ws.set_configuration(model, &theta).unwrap();
    cws.ws.set_qvel(model, &qvel).unwrap();
    let nu = cws.ws.nu.clone();
    cws.evaluate(model, law, parameters, &theta, &vec![0.0; model.nv]).unwrap();
    let power = nu.dot(&cws.eps);
    let rate = derivative(potential_at, 1e-4);
    let scale = power.abs().max(rate.abs()).max(1e-3);
    if (rate + power).abs() > 1e-7 * scale {
        return Err(format!("dU/dt = {rate:.12e} but -nu.g = {:.12e}", -power));
    }
    Ok(())
}

#[test]
fn the_configuration_term_is_minus_the_gradient_of_the_potential() {
    for seed in 0..40 {
        let vehicle = vehicle(seed);
        let model = Model::compile(&vehicle).unwrap();
        let mut rng = Rng::new(4000 + seed);
        if let Ok(law) = ControlLaw::joints(&model) {
            let mut parameters = random_parameters(&mut rng, &model, &law);
            parameters.target = (0..law.ny()).map(|_| rng.uniform(-1.0, 1.0)).collect();
            check_gradient(&vehicle, &model, &law, &parameters, &mut rng)
                .map_err(|e| format!("seed {seed}, joints: {e}"))
                .unwrap();
        }
        let body = rng.below(vehicle.bodies.len());
        let law = ControlLaw::pose(&vehicle, &model, &vehicle.bodies[body].name).unwrap();
        let mut parameters = random_parameters(&mut rng, &model, &law);
        // Anisotropic orientation gains need the full J_r⁻ᵀ(φ); targets up to 2.5 rad away.
        let axis = rng.unit_vec() * rng.uniform(0.0, 2.5);
        let target = rng.unit_quat() * UnitQuaternion::from_scaled_axis(axis);
        parameters.target = vec![0.3, -0.2, 0.5, target.w, target.i, target.j, target.k];
        check_gradient(&vehicle, &model, &law, &parameters, &mut rng)
            .map_err(|e| format!("seed {seed}, pose: {e}"))
            .unwrap();
    }
}

#[test]
fn rate_feedback_alone_is_minus_c1_nu_and_the_target_term_vanishes_at_the_target() {
    let vehicle = vehicle(4);
    let model = Model::compile(&vehicle).unwrap();
    let mut rng = Rng::new(5);
    for law in
        [ControlLaw::joints(&model).unwrap(), ControlLaw::pose(&vehicle, &model, &vehicle.bodies[1].name).unwrap()]
    {
        let mut parameters = random_parameters(&mut rng, &model, &law);
        let nu = rng.vec(model.nv, 1.0);
        let mut cws = ControlWorkspace::new(&model, &law);
        // The default target is Y(qpos0): at qpos0 only the rate term is left.
        cws.evaluate(&model, &law, &parameters, &model.qpos0, &nu).unwrap();
        let minus_c1_nu: Vec<f64> = parameters.c1.iter().zip(&nu).map(|(c, n)| -c * n).collect();
        assert!(rel_err(cws.eps.as_slice(), &minus_c1_nu) < 1e-12, "{:?}", law.objective);
        assert!(cws.potential < 1e-24);
        // With c2 = 0 it is −c1 ν anywhere.
        parameters.c2.fill(0.0);
        let theta = random_theta(&mut rng, &vehicle);
        cws.evaluate(&model, &law, &parameters, &theta, &nu).unwrap();
        assert_eq!(cws.eps.as_slice(), &minus_c1_nu[..]);
        assert_eq!(cws.potential, 0.0);
    }
}

#[test]
fn bad_input_is_a_clear_error() {
    let vehicle = vehicle(2);
    let model = Model::compile(&vehicle).unwrap();
    let unknown = ControlLaw::pose(&vehicle, &model, "no_such_body").unwrap_err();
    assert!(matches!(&unknown, ControlError::UnknownBody { name, .. } if name == "no_such_body"), "{unknown}");
    assert!(unknown.to_string().contains("b0"), "the message lists the bodies: {unknown}");

    let mut welded = vehicle.clone();
    welded.bodies.push(Body { name: "antenna".into(), parent: None, joints: Vec::new(), ..welded.bodies[0].clone() });
    let welded_model = Model::compile(&welded).unwrap();
    assert_eq!(ControlLaw::pose(&welded, &welded_model, "antenna"), Err(ControlError::WeldedToWorld("antenna".into())));

    let mut ball_only = vehicle.clone();
    ball_only.bodies.truncate(1);
    ball_only.bodies[0].joints.truncate(1);
    ball_only.bodies[0].joints[0].kind = JointKind::Ball;
    ball_only.bodies[0].joints[0].pos = Vec3::zeros();
    let ball_model = Model::compile(&ball_only).unwrap();
    assert_eq!(ControlLaw::joints(&ball_model), Err(ControlError::NoJointTargets));

    let law = ControlLaw::pose(&vehicle, &model, "b1").unwrap();
    let good = law.default_parameters(&model).unwrap();
    assert_eq!(good.check(&model, &law), Ok(()));
    let mut bad = good.clone();
    bad.c1[2] = -1.0;
    assert_eq!(bad.check(&model, &law), Err(ControlError::NegativeGain { what: "c1", index: 2, value: -1.0 }));
    assert_eq!(
        ControlError::NegativeGain { what: "c1", index: 2, value: -1.0 }.to_string(),
        "c1[3] = -1 is negative: gains must be non-negative"
    );
    let mut bad = good.clone();
    bad.c2.push(1.0);
    assert_eq!(bad.check(&model, &law), Err(ControlError::Length { what: "c2", expected: 6, found: 7 }));
    let mut bad = good.clone();
    bad.target[1] = f64::NAN;
    assert!(matches!(bad.check(&model, &law), Err(ControlError::NonFinite { what: "target", index: 1, .. })));
    let mut bad = good.clone();
    bad.target[3..7].fill(0.0);
    assert_eq!(bad.check(&model, &law), Err(ControlError::ZeroTargetQuaternion));

    let mut cws = ControlWorkspace::new(&model, &law);
    let mut nu = vec![0.0; model.nv];
    nu[0] = f64::INFINITY;
    let err = cws.evaluate(&model, &law, &good, &model.qpos0, &nu).unwrap_err();
    assert!(err.to_string().contains("nu[1] is not finite"), "{err}");
    let err = cws.evaluate(&model, &law, &good, &model.qpos0[1..], &vec![0.0; model.nv]).unwrap_err();
    assert!(err.to_string().contains("theta has"), "{err}");
}

#[test]
fn a_welded_end_effector_is_carried_by_its_link() {
    // A tool welded to a moving body: its frame is offset from the link's,
    // and the wrench there must still be ℓJᵀf of the tool's own point.
    let mut vehicle = vehicle(6);
    let mut rng = Rng::new(6);
    let parent = vehicle.bodies.len() - 1;
    vehicle.bodies.push(Body {
        name: "tool".into(),
        parent: Some(parent),
        pos: rng.vec3(0.4),
        quat: rng.unit_quat(),
        inertia: Some(common::random_mass(&mut rng)),
        inertial_pos: Default::default(),
        inertial_quat: None,
        mass_unknown: false,
        joints: Vec::new(),
        gravcomp: 0.0,
        line: 0,
    });
    let model = Model::compile(&vehicle).unwrap();
    let tool = vehicle.bodies.len() - 1;
    let frame = BodyFrame::find(&vehicle, &model, "tool").unwrap();
    let law = ControlLaw { objective: Objective::Pose(frame.clone()) };
    let mut cws = ControlWorkspace::new(&model, &law);
    let theta = random_theta(&mut rng, &vehicle);
    cws.ws.set_configuration(&model, &theta).unwrap();
    let wrench: SpatialVec = spatial(&rng.vec3(1.0), &rng.vec3(3.0));
    let mut eps = vec![0.0; model.nv];
    cws.eps_of_wrench(&model, &frame, &wrench, &mut eps).unwrap();
    let k = common::kinematics(&vehicle, &theta);
    let (jw, jv) = common::point_jacobian(&k, tool, &k.body_pos[tool], model.nv);
    let torque = jw.transpose() * DVector::from_column_slice(&wrench.as_slice()[..3])
        + jv.transpose() * DVector::from_column_slice(&wrench.as_slice()[3..]);
    let err = rel_err(&eps, dense_l(&vehicle, &theta, &torque).as_slice());
    assert!(err < 1e-10, "error {err:.2e}");
}
