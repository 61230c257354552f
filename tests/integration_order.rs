//! The Runge–Kutta–Munthe-Kaas step keeps RK4's order on every joint type,
//! and exact solutions conserve |ν| and momentum (DYNAMICS.md §6, §7 check 5).

mod common;

use common::{Rng, TreeOptions, random_theta, random_vehicle};
use nudyn::integrate::{Integrator, Method};
use nudyn::model::Model;
use nudyn::vehicle::{JointKind, Vehicle};

fn simulate(model: &Model, theta0: &[f64], nu0: &[f64], h: f64, steps: usize) -> (Vec<f64>, Vec<f64>) {
    let mut ws = model.workspace();
    let mut integrator = Integrator::new(model, Method::Rk4);
    let (mut theta, mut nu) = (theta0.to_vec(), nu0.to_vec());
    // A smooth, time-varying ε so that the inputs are exercised too.
    let eps_at = |t: f64, out: &mut [f64]| out.iter_mut().enumerate().for_each(|(k, e)| *e = 0.3 * (2.0 * t + k as f64).sin());
    for n in 0..steps {
        integrator.step(model, &mut ws, &mut theta, &mut nu, n as f64 * h, h, eps_at).unwrap();
    }
    (theta, nu)
}

fn error(a: &(Vec<f64>, Vec<f64>), b: &(Vec<f64>, Vec<f64>)) -> f64 {
    let e = |x: &[f64], y: &[f64]| x.iter().zip(y).fold(0.0f64, |m, (p, q)| m.max((p - q).abs()));
    e(&a.0, &b.0).max(e(&a.1, &b.1))
}

/// Observed order of RK4 on a vehicle whose only joints are of `kind`
/// (plus a free base where `free_base`).
fn observed_order(vehicle: &Vehicle, seed: u64) -> f64 {
    let model = Model::compile(vehicle).unwrap();
    let mut rng = Rng::new(seed);
    let theta0 = random_theta(&mut rng, vehicle);
    let nu0 = rng.vec(model.nv, 1.0);
    let t_end = 1.0;
    let reference = simulate(&model, &theta0, &nu0, t_end / 2048.0, 2048);
    let coarse = simulate(&model, &theta0, &nu0, t_end / 64.0, 64);
    let fine = simulate(&model, &theta0, &nu0, t_end / 128.0, 128);
    (error(&coarse, &reference) / error(&fine, &reference)).log2()
}

fn vehicle_with(kind: JointKind, free_base: bool, seed: u64) -> Vehicle {
    let mut rng = Rng::new(seed);
    let mut vehicle = random_vehicle(&mut rng, TreeOptions { bodies: 4, free_base, passive: true, chain: true });
    for body in vehicle.bodies.iter_mut().skip(usize::from(free_base)) {
        let mut joint = common::joint(&mut rng, format!("{}_{kind:?}", body.name), kind);
        // A ball spring pulls along the shorter rotation, so its torque jumps
        // where the rotation from rest passes π (as in MuJoCo): no order survives that.
        joint.stiffness = if kind == JointKind::Ball { 0.0 } else { 2.0 };
        joint.damping = 0.3;
        body.joints = vec![joint];
    }
    if free_base {
        vehicle.bodies[0].joints[0].stiffness = 0.0;
    }
    vehicle
}

#[test]
fn rk4_is_fourth_order_on_every_joint_type() {
    for (kind, free_base) in [
        (JointKind::Hinge, false),
        (JointKind::Slide, false),
        (JointKind::Ball, false),
        (JointKind::Hinge, true),
        (JointKind::Ball, true),
    ] {
        let order = observed_order(&vehicle_with(kind, free_base, 11), 5);
        assert!((3.7..4.5).contains(&order), "{kind:?} (free base: {free_base}): observed order {order:.2}");
    }
}

#[test]
fn free_tumbling_conserves_norm_of_nu_and_momentum() {
    let mut rng = Rng::new(21);
    let vehicle = random_vehicle(&mut rng, TreeOptions { bodies: 6, free_base: true, passive: false, chain: false });
    let model = Model::compile(&vehicle).unwrap();
    let mut ws = model.workspace();
    let mut integrator = Integrator::new(&model, Method::Rk4);
    let mut theta = random_theta(&mut rng, &vehicle);
    let mut nu = rng.vec(model.nv, 1.0);
    let zero = vec![0.0; model.nv];
    let invariants = |ws: &mut nudyn::workspace::Workspace, theta: &[f64], nu: &[f64]| {
        ws.set_configuration(&model, theta).unwrap();
        ws.set_nu(&model, nu).unwrap();
        (ws.kinetic_energy(), ws.momentum(&model).unwrap())
    };
    let (k0, p0) = invariants(&mut ws, &theta, &nu);
    let h = 1e-3;
    for n in 0..2000 {
        integrator.step(&model, &mut ws, &mut theta, &mut nu, n as f64 * h, h, |_, e| e.copy_from_slice(&zero)).unwrap();
    }
    let (k1, p1) = invariants(&mut ws, &theta, &nu);
    assert!((k1 - k0).abs() / k0 < 1e-9, "energy drift {:.3e}", (k1 - k0).abs() / k0);
    assert!((p1 - p0).norm() / p0.norm().max(1.0) < 1e-9, "momentum drift {:.3e}", (p1 - p0).norm());
}

