//! Bad states and out-of-order calls give typed errors, never NaN.

use crate::common;

use crate::common::{Rng, TreeOptions, random_theta, random_vehicle};
use nudyn::dynamics::DynamicsError;
use nudyn::model::{Model, ModelError};
use nudyn::vehicle::JointKind;
use nudyn::workspace::Stage;

fn free_vehicle() -> (nudyn::vehicle::Vehicle, Model) {
    let mut rng = Rng::new(7);
    let vehicle = random_vehicle(&mut rng, TreeOptions { bodies: 4, free_base: true, passive: false, chain: true });
    let model = Model::compile(&vehicle).unwrap();
    (vehicle, model)
}

#[test]
fn wrong_lengths_and_non_finite_entries_are_rejected() {
    let (_, model) = free_vehicle();
    let mut ws = model.workspace();
    let short = vec![0.0; model.nq - 1];
    assert_eq!(
        ws.set_configuration(&model, &short),
        Err(DynamicsError::Length { what: "theta", expected: model.nq, found: model.nq - 1 })
    );
    let mut theta = model.qpos0.clone();
    theta[2] = f64::NAN;
    assert!(matches!(
        ws.set_configuration(&model, &theta),
        Err(DynamicsError::NonFinite { what: "theta", index: 2, .. })
    ));
    ws.set_configuration(&model, &model.qpos0).unwrap();
    let mut nu = vec![0.0; model.nv];
    nu[1] = f64::INFINITY;
    assert!(matches!(ws.set_nu(&model, &nu), Err(DynamicsError::NonFinite { what: "nu", index: 1, .. })));
}

#[test]
fn zero_quaternion_names_the_joint() {
    let (vehicle, model) = free_vehicle();
    let mut ws = model.workspace();
    let mut theta = model.qpos0.clone();
    theta[3..7].copy_from_slice(&[0.0; 4]);
    let err = ws.set_configuration(&model, &theta).unwrap_err();
    assert_eq!(err, DynamicsError::ZeroQuaternion { joint: vehicle.bodies[0].joints[0].name.clone(), qpos_adr: 3 });
    assert!(err.to_string().contains("theta[4] to theta[7]"), "{err}");
}

#[test]
fn unnormalized_quaternions_are_normalized_like_mujoco() {
    let (vehicle, model) = free_vehicle();
    let mut rng = Rng::new(3);
    let theta = random_theta(&mut rng, &vehicle);
    let mut scaled = theta.clone();
    scaled[3..7].iter_mut().for_each(|q| *q *= 3.0);
    let mut ws = model.workspace();
    ws.set_configuration(&model, &scaled).unwrap();
    let normalized = ws.theta.clone();
    assert!(common::rel_err(normalized.as_slice(), &theta) < 1e-15);
}

#[test]
fn quaternions_at_the_edges_of_floating_point_keep_their_direction() {
    let (vehicle, model) = free_vehicle();
    let mut rng = Rng::new(5);
    let theta = random_theta(&mut rng, &vehicle);
    let nu: Vec<f64> = (0..model.nv).map(|i| 0.1 + 0.05 * i as f64).collect();
    let eps = vec![0.0; model.nv];
    let mut ws = model.workspace();
    nudyn::dynamics::forward(&model, &mut ws, &theta, &nu, &eps).unwrap();
    let (unit_nu_dot, unit_momentum) = (ws.nu_dot.clone(), ws.momentum(&model).unwrap());
    // Powers of two scale exactly, so the direction given is exactly the unit one's.
    for scale in [2f64.powi(-530), 2f64.powi(-1000), 2f64.powi(520), 2f64.powi(1000)] {
        let mut scaled = theta.clone();
        scaled[3..7].iter_mut().for_each(|q| *q *= scale);
        assert!(scaled[3..7].iter().all(|q| q.is_finite() && *q != 0.0));
        nudyn::dynamics::forward(&model, &mut ws, &scaled, &nu, &eps).unwrap();
        let unit = &ws.theta.as_slice()[3..7];
        assert!((unit.iter().map(|q| q * q).sum::<f64>() - 1.0).abs() < 4e-16, "scale {scale:e}: {unit:?}");
        assert!(common::rel_err(ws.theta.as_slice(), &theta) < 1e-15, "scale {scale:e}");
        assert!(common::rel_err(ws.nu_dot.as_slice(), unit_nu_dot.as_slice()) < 1e-13, "scale {scale:e}");
        let momentum = ws.momentum(&model).unwrap();
        assert!((momentum - unit_momentum).norm() <= 1e-14 * unit_momentum.norm(), "scale {scale:e}");
    }
}

#[test]
fn calls_out_of_order_are_rejected() {
    let (_, model) = free_vehicle();
    let mut ws = model.workspace();
    let zeros = vec![0.0; model.nv];
    assert_eq!(
        ws.set_nu(&model, &zeros),
        Err(DynamicsError::OutOfOrder { call: "set_nu", needed: Stage::Configuration })
    );
    ws.set_configuration(&model, &model.qpos0).unwrap();
    assert_eq!(
        ws.compute_nu_dot(&model, &zeros),
        Err(DynamicsError::OutOfOrder { call: "compute_nu_dot", needed: Stage::Velocity })
    );
    // An input rejected on entry leaves the workspace as it was.
    ws.set_nu(&model, &zeros).unwrap();
    let mut bad = model.qpos0.clone();
    bad[0] = f64::NAN;
    assert!(ws.set_configuration(&model, &bad).is_err());
    assert_eq!(ws.stage, Stage::Velocity);
    // A failure inside the passes invalidates what was computed before it.
    let mut zero_quat = model.qpos0.clone();
    zero_quat[3..7].copy_from_slice(&[0.0; 4]);
    assert!(ws.set_configuration(&model, &zero_quat).is_err());
    assert!(ws.compute_nu_dot(&model, &zeros).is_err());
}

#[test]
fn a_joint_that_moves_nothing_is_rejected_at_compile_time() {
    let (mut vehicle, _) = free_vehicle();
    // A massless tip body on a hinge with no armature: its joint sees zero inertia.
    let tip = vehicle.bodies.len() - 1;
    let mut hinge = common::joint(&mut Rng::new(1), "massless".into(), JointKind::Hinge);
    hinge.armature = 0.0;
    vehicle.bodies[tip].inertia = None;
    vehicle.bodies[tip].joints = vec![hinge];
    let name = "massless".to_string();
    assert_eq!(Model::compile(&vehicle), Err(ModelError::Singular { joint: name }));
}

/// MuJoCo adds a tendon's armature a·JᵢJⱼ only where M stores an entry
/// (ancestor pairs), so over two sibling joints the sum need not stay
/// positive definite; where it leaves M singular or overflows it (an
/// armature of 1e308 here) the error names the tendons that carry armature
/// (here at qpos0, when the model is compiled).
#[test]
fn a_singular_masked_tendon_armature_names_its_tendons() {
    let mjcf = r#"<mujoco><worldbody><body name="root"><joint name="j0" axis="0 0 1"/>
        <geom size="0.1" mass="1"/>
        <body name="left" pos="0.3 0 0"><joint name="j1" axis="0 0 1"/><geom size="0.1" mass="1"/></body>
        <body name="right" pos="-0.3 0 0"><joint name="j2" axis="0 0 1"/><geom size="0.1" mass="1"/></body>
      </body></worldbody>
      <tendon><fixed name="coupler" armature="1e308">
        <joint joint="j0" coef="1"/><joint joint="j1" coef="1"/><joint joint="j2" coef="1"/>
      </fixed></tendon></mujoco>"#;
    let error = Model::compile(&nudyn::mjcf::parse_mjcf(mjcf).unwrap().vehicle).unwrap_err();
    let message =
        "the mass matrix with the armature of tendon 'coupler' is singular (MuJoCo adds it only where M has entries)";
    assert!(error.to_string().ends_with(message), "{error}");
}
