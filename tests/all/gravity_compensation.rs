//! Gravity compensation (docs/DYNAMICS.md §5) against the dense reference
//! in `common`: MuJoCo's qfrc_gravcomp = Σ_b J_b(c_b)ᵀ (−gravcomp_b m_b g),
//! written out with world Jacobians at each body's centre of mass, and the
//! θ̈ it gives through M; then the rules on where the compensation goes
//! (passive or actuator force, or nowhere). Nothing here uses the passes
//! under test to make an expected value.

use crate::common;

use crate::common::{Rng, TreeOptions, V3, kinematics, point_jacobian, random_theta, random_vehicle, rel_err};
use nalgebra::DVector;
use nudyn::model::Model;
use nudyn::vehicle::{Actuator, Transmission, Vehicle};
use proptest::prelude::*;

/// qfrc_gravcomp from the vehicle description: each body's compensating
/// force at its world centre of mass through its point Jacobian.
fn dense_gravcomp(vehicle: &Vehicle, theta: &[f64], nv: usize) -> DVector<f64> {
    let k = kinematics(vehicle, theta);
    let mut qfrc = DVector::zeros(nv);
    for (b, body) in vehicle.bodies.iter().enumerate() {
        let Some(mass) = &body.inertia else { continue };
        let com = k.body_pos[b] + k.body_rot[b] * mass.com;
        let (_, jv) = point_jacobian(&k, b, &com, nv);
        let force: V3 = -body.gravcomp * mass.mass * vehicle.gravity;
        qfrc += jv.transpose() * DVector::from_column_slice(force.as_slice());
    }
    qfrc
}

/// A random tree under gravity with springs and dampers, each body
/// compensated by 0, a negative or a positive fraction (the first body
/// positively, so that MuJoCo applies them all).
fn compensated_vehicle(rng: &mut Rng, bodies: usize, free_base: bool) -> Vehicle {
    let mut vehicle = random_vehicle(rng, TreeOptions { bodies, free_base, passive: true, chain: false });
    for (b, body) in vehicle.bodies.iter_mut().enumerate() {
        body.gravcomp = match (b, rng.below(3)) {
            (0, _) => rng.uniform(0.2, 1.5),
            (_, 0) => 0.0,
            (_, 1) => rng.uniform(-1.0, 0.0),
            _ => rng.uniform(0.0, 2.0),
        };
    }
    vehicle
}

/// A motor on the vehicle's first joint, with no ctrl range.
fn motor_on_first_joint(vehicle: &Vehicle) -> Actuator {
    let joint = vehicle.bodies[0].joints[0].name.clone();
    common::motor(Transmission::Joint { joint, in_parent: false }, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
}

/// θ̈ with the actuators at ctrl = 0 and no applied ε, at rest.
fn qacc_at_rest(vehicle: &Vehicle, theta: &[f64]) -> Vec<f64> {
    let model = Model::compile(vehicle).unwrap();
    let mut ws = model.workspace();
    ws.set_configuration(&model, theta).unwrap();
    ws.set_qvel(&model, &vec![0.0; model.nv]).unwrap();
    ws.compute_qacc_actuated(&model, &vec![0.0; model.nv], &vec![0.0; model.actuators.len()]).unwrap();
    ws.qacc.as_slice().to_vec()
}

fn check(vehicle: &Vehicle, rng: &mut Rng) -> Result<(), String> {
    let model = Model::compile(vehicle).map_err(|e| e.to_string())?;
    let mut ws = model.workspace();
    let theta = random_theta(rng, vehicle);
    let expected = dense_gravcomp(vehicle, &theta, model.nv);
    ws.set_configuration(&model, &theta).unwrap();
    let error = rel_err(ws.qfrc_gravcomp.as_slice(), expected.as_slice());
    if error > 1e-12 {
        return Err(format!("qfrc_gravcomp: error {error:.3e}"));
    }
    // At rest the dense bias has no velocity terms (its differences along
    // a motion that does not move are exactly zero): θ̈ = M⁻¹(τ_passive − g + qfrc_gravcomp).
    let rest = vec![0.0; model.nv];
    let qacc_dense = common::forward_dynamics(vehicle, &theta, &rest, expected.as_slice());
    ws.set_qvel(&model, &rest).unwrap();
    ws.compute_qacc(&model, &rest).unwrap();
    let error = rel_err(ws.qacc.as_slice(), qacc_dense.as_slice());
    if error > 1e-9 {
        return Err(format!("qacc: error {error:.3e}"));
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn compensation_is_the_dense_sum_of_the_bodies_forces(seed in any::<u64>(), bodies in 1usize..9, free_base in any::<bool>()) {
        let mut rng = Rng::new(seed);
        let vehicle = compensated_vehicle(&mut rng, bodies, free_base);
        if let Err(e) = check(&vehicle, &mut rng) {
            prop_assert!(false, "{e}\n{vehicle:#?}");
        }
    }
}

#[test]
fn full_compensation_cancels_gravity_and_half_halves_it() {
    let mut rng = Rng::new(33);
    for free_base in [false, true] {
        let mut vehicle = random_vehicle(&mut rng, TreeOptions { bodies: 8, free_base, passive: true, chain: false });
        let theta = random_theta(&mut rng, &vehicle);
        let gravity = vehicle.gravity;
        for fraction in [1.0, 0.5] {
            vehicle.bodies.iter_mut().for_each(|b| b.gravcomp = fraction);
            vehicle.gravity = gravity;
            let compensated = qacc_at_rest(&vehicle, &theta);
            vehicle.bodies.iter_mut().for_each(|b| b.gravcomp = 0.0);
            vehicle.gravity = (1.0 - fraction) * gravity;
            let reduced = qacc_at_rest(&vehicle, &theta);
            let error = rel_err(&compensated, &reduced);
            assert!(error < 1e-12, "gravcomp {fraction}, free base {free_base}: {error:e}");
        }
    }
}

#[test]
fn nothing_is_compensated_without_gravity_or_a_positive_gravcomp() {
    let mut rng = Rng::new(7);
    let mut vehicle = compensated_vehicle(&mut rng, 6, true);
    assert!(!Model::compile(&vehicle).unwrap().gravity_compensation.is_empty());
    let mut weightless = vehicle.clone();
    weightless.gravity = V3::zeros();
    assert!(Model::compile(&weightless).unwrap().gravity_compensation.is_empty());
    // MuJoCo's flg_gravcomp counts bodies with gravcomp > 0 only.
    vehicle.bodies.iter_mut().for_each(|b| b.gravcomp = -b.gravcomp.abs());
    let theta = random_theta(&mut rng, &vehicle);
    let negative = qacc_at_rest(&vehicle, &theta);
    assert!(Model::compile(&vehicle).unwrap().gravity_compensation.is_empty());
    vehicle.bodies.iter_mut().for_each(|b| b.gravcomp = 0.0);
    assert_eq!(negative, qacc_at_rest(&vehicle, &theta));
}

#[test]
fn compensation_through_the_actuators_needs_an_actuator() {
    let mut rng = Rng::new(12);
    let mut vehicle = compensated_vehicle(&mut rng, 7, true);
    let theta = random_theta(&mut rng, &vehicle);
    let passive = qacc_at_rest(&vehicle, &theta);
    let without = {
        let mut v = vehicle.clone();
        v.bodies.iter_mut().for_each(|b| b.gravcomp = 0.0);
        qacc_at_rest(&v, &theta)
    };
    vehicle.bodies.iter_mut().flat_map(|b| &mut b.joints).for_each(|j| j.actuator_gravcomp = true);
    // Without actuators MuJoCo's qfrc_actuator is zero: the share routed there is lost.
    assert_eq!(qacc_at_rest(&vehicle, &theta), without);
    // With one (at zero force), all of it arrives as an actuator force.
    vehicle.actuators.push(motor_on_first_joint(&vehicle));
    let routed = qacc_at_rest(&vehicle, &theta);
    assert!(rel_err(&routed, &passive) < 1e-12, "{routed:?}\n{passive:?}");
    assert!(rel_err(&routed, &without) > 1e-3);
    vehicle.actuation.enabled = false;
    assert_eq!(qacc_at_rest(&vehicle, &theta), without);
}
