//! The Runge–Kutta–Munthe-Kaas step keeps each method's order on every
//! joint type, adaptive runs meet their tolerance against a tight
//! reference, and exact solutions conserve |ν| and momentum (docs/DYNAMICS.md
//! §6, §7 check 5).

use crate::common;

use crate::common::{Rng, TreeOptions, random_theta, random_vehicle};
use nudyn::integrate::{Integrator, Method};
use nudyn::model::Model;
use nudyn::vehicle::{JointKind, Vehicle};

/// A smooth, time-varying ε so that the inputs are exercised too.
fn smooth_eps(t: f64, out: &mut [f64]) {
    out.iter_mut().enumerate().for_each(|(k, e)| *e = 0.3 * (2.0 * t + k as f64).sin());
}

type State = (Vec<f64>, Vec<f64>);

/// `steps` fixed steps of `method`, without error control; None if a step
/// fails (too large a step can reach a non-finite state).
fn simulate(model: &Model, method: Method, theta0: &[f64], nu0: &[f64], h: f64, steps: usize) -> Option<State> {
    let mut ws = model.workspace();
    let mut integrator = Integrator::new(model, method);
    let (mut theta, mut nu) = (theta0.to_vec(), nu0.to_vec());
    for n in 0..steps {
        integrator.step(model, &mut ws, (&mut theta, &mut nu), (n as f64 * h, h), smooth_eps).ok()?;
    }
    Some((theta, nu))
}

fn error(a: &State, b: &State) -> f64 {
    let e = |x: &[f64], y: &[f64]| x.iter().zip(y).fold(0.0f64, |m, (p, q)| m.max((p - q).abs()));
    e(&a.0, &b.0).max(e(&a.1, &b.1))
}

/// Observed order of `method` on `vehicle` over 1 s: the least-squares
/// slope of log(error) against log(h) over 4 to 512 steps, keeping the
/// errors between 1e-11 (above the round-off floor) and 1e-3 (asymptotic).
/// The reference is DOP853 with 4096 steps (error below 1e-20 by its order).
fn observed_order(vehicle: &Vehicle, method: Method, seed: u64) -> f64 {
    let model = Model::compile(vehicle).unwrap();
    let mut rng = Rng::new(seed);
    let theta0 = random_theta(&mut rng, vehicle);
    let nu0 = rng.vec(model.nv, 1.0);
    let run = |method, steps: usize| simulate(&model, method, &theta0, &nu0, 1.0 / steps as f64, steps);
    let reference = run(Method::Dop853, 4096).expect("the reference run succeeds");
    let points: Vec<(f64, f64)> = (2..=9)
        .map(|k| 1usize << k)
        .filter_map(|steps| run(method, steps).map(|x| ((1.0 / steps as f64).ln(), error(&x, &reference))))
        .filter(|&(_, e)| (1e-11..1e-3).contains(&e))
        .map(|(log_h, e)| (log_h, e.ln()))
        .collect();
    assert!(points.len() >= 3, "{method:?}: too few steps with errors in range: {points:?}");
    let n = points.len() as f64;
    let (mean_x, mean_y) = (points.iter().map(|p| p.0).sum::<f64>() / n, points.iter().map(|p| p.1).sum::<f64>() / n);
    let covariance: f64 = points.iter().map(|(x, y)| (x - mean_x) * (y - mean_y)).sum();
    let variance: f64 = points.iter().map(|(x, _)| (x - mean_x).powi(2)).sum();
    covariance / variance
}

/// Every joint type, alone on a fixed base or behind a free base.
const JOINT_CASES: [(JointKind, bool); 5] = [
    (JointKind::Hinge, false),
    (JointKind::Slide, false),
    (JointKind::Ball, false),
    (JointKind::Hinge, true),
    (JointKind::Ball, true),
];

fn vehicle_with(kind: JointKind, free_base: bool, seed: u64) -> Vehicle {
    let mut rng = Rng::new(seed);
    let mut vehicle = random_vehicle(&mut rng, TreeOptions { bodies: 4, free_base, passive: true, chain: true });
    for body in vehicle.bodies.iter_mut().skip(usize::from(free_base)) {
        let mut joint = common::joint(&mut rng, format!("{}_{kind:?}", body.name), kind);
        // A ball spring pulls along the shorter rotation, so its torque jumps
        // where the rotation from rest passes π (as in MuJoCo): no order
        // survives that. Slides get stiff springs, or they would move too
        // gently for DOP853's error to rise above round-off.
        joint.stiffness = match kind {
            JointKind::Ball => 0.0,
            JointKind::Slide => 60.0,
            _ => 2.0,
        };
        joint.damping = 0.3;
        body.joints = vec![joint];
    }
    if free_base {
        vehicle.bodies[0].joints[0].stiffness = 0.0;
    }
    vehicle
}

/// Each method keeps its order on every joint type (a naive quaternion
/// update would show 2; a Rosenbrock–W step with wrong stage weights, 2
/// or less). The embedded pairs are built with small
/// leading error coefficients, so at practical steps they often look
/// better than their order, never worse: the bound is p − 0.3 below,
/// p + 2 above.
#[test]
fn every_method_keeps_its_order_on_every_joint_type() {
    let methods = [
        (Method::Rk4, 4.0),
        (Method::Dopri5, 5.0),
        (Method::Dop853, 8.0),
        (Method::Ros34pw2, 3.0),
        (Method::Bs3, 3.0),
        (Method::Tsit5, 5.0),
    ];
    for (method, expected) in methods {
        for (kind, free_base) in JOINT_CASES {
            let order = observed_order(&vehicle_with(kind, free_base, 11), method, 5);
            eprintln!("{method:?} on {kind:?} (free base: {free_base}): observed order {order:.2}");
            assert!(
                (expected - 0.3..expected + 2.0).contains(&order),
                "{method:?} on {kind:?} (free base: {free_base}): observed order {order:.2}, expected {expected}"
            );
        }
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
        integrator
            .step(&model, &mut ws, (&mut theta, &mut nu), (n as f64 * h, h), |_, e| e.copy_from_slice(&zero))
            .unwrap();
    }
    let (k1, p1) = invariants(&mut ws, &theta, &nu);
    assert!((k1 - k0).abs() / k0 < 1e-9, "energy drift {:.3e}", (k1 - k0).abs() / k0);
    assert!((p1 - p0).norm() / p0.norm().max(1.0) < 1e-9, "momentum drift {:.3e}", (p1 - p0).norm());
}
