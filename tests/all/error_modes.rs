//! Where the explicit methods' local errors lie on the constrained fixtures,
//! and how much of them reaches the result (docs/integration.md, "Where
//! the local errors go"): the local error estimate of the step a run
//! attempts next, split on the invariant subspaces of the Jacobian of
//! (θ̇, θ̈) in (θ, θ̇) (finite differences of the f64 rates: the exact
//! derivatives do not cover constraint rows); and the global error at the
//! end against the run's errors per communication step propagated by the
//! linearized motion.

use nalgebra::{DMatrix, DVector, Quaternion, UnitQuaternion};
use nudyn::integrate::{Integrator, Method, RunState, Settings, Simulation, retract};
use nudyn::model::{LinkJoint, Model};

use crate::stiffness::{CONSTRAINED, INTERVAL, INTERVALS, eps, fixture};

/// A mode decays "within the horizon" when Re λ < −this (1/s): ten times
/// faster than the one second the tolerance is counted over.
const FAST_DECAY: f64 = 10.0;

/// The Jacobian of (θ̇, θ̈) in (θ, θ̇) at a state (2nv square), by central
/// differences of θ̈, θ moved in its tangent space as a step's Δ moves it;
/// the constraint mode is the state's own at every point, as outside a step.
pub fn rate_jacobian(model: &Model, theta: &[f64], qvel: &[f64], eps: &[f64]) -> DMatrix<f64> {
    let nv = model.nv;
    let mut ws = model.workspace();
    let ctrl = vec![0.0; model.actuators.len()];
    let mut qacc = |theta: &[f64], qvel: &[f64]| {
        ws.set_configuration(model, theta).unwrap();
        ws.set_qvel(model, &qvel[..nv]).unwrap();
        ws.set_act(model, &qvel[nv..]).unwrap();
        ws.compute_qacc_actuated(model, eps, &ctrl).unwrap();
        ws.qacc.clone()
    };
    let mut jacobian = DMatrix::zeros(2 * nv, 2 * nv);
    for j in 0..nv {
        jacobian[(j, nv + j)] = 1.0;
    }
    let step = 1e-6;
    for j in 0..2 * nv {
        let mut sides = [0.0, 0.0].map(|_| DVector::zeros(nv));
        for (side, sign) in sides.iter_mut().zip([1.0, -1.0]) {
            let (mut theta, mut qvel) = (theta.to_vec(), qvel.to_vec());
            if j < nv {
                let mut delta = vec![0.0; nv];
                delta[j] = sign * step;
                retract(model, &mut theta, &delta);
            } else {
                qvel[j - nv] += sign * step;
            }
            *side = qacc(&theta, &qvel);
        }
        let column = (&sides[0] - &sides[1]) / (2.0 * step);
        jacobian.view_mut((nv, j), (nv, 1)).copy_from(&column);
    }
    jacobian
}

/// The spectral projector onto the invariant subspace of `jacobian` whose
/// eigenvalues have Re λ < −`decay`: (I − sign(J + decay·I))/2, the matrix
/// sign function by Newton's iteration with norm scaling (no eigenvectors:
/// the welds' critically damped modes come in nearly defective pairs).
fn fast_projector(jacobian: &DMatrix<f64>, decay: f64) -> DMatrix<f64> {
    let n = jacobian.nrows();
    let identity = DMatrix::<f64>::identity(n, n);
    let mut sign = jacobian + &identity * decay;
    for _ in 0..100 {
        let inverse = sign.clone().try_inverse().expect("an eigenvalue on Re λ = −decay");
        let scale = (inverse.norm() / sign.norm()).sqrt();
        let next = (&sign * scale + inverse / scale) * 0.5;
        let change = (&next - &sign).norm();
        sign = next;
        if change <= 1e-13 * sign.norm() {
            let projector = (identity - sign) * 0.5;
            let idempotence = (&projector * &projector - &projector).norm() / projector.norm().max(1.0);
            assert!(idempotence < 1e-8, "the projector is off by {idempotence:e}");
            return projector;
        }
    }
    panic!("the sign iteration did not converge");
}

/// `a` − `b` in the tangent space at `b` (θ as a step's Δ moves it: a ball
/// joint's body-frame rotation vector), then θ̇'s difference (2nv).
fn difference(model: &Model, a: &RunState, b: &RunState) -> DVector<f64> {
    let nv = model.nv;
    let mut out = DVector::zeros(2 * nv);
    for link in &model.links {
        let (q, d) = (link.qpos_adr, link.dof_adr);
        if link.joint == LinkJoint::Ball {
            let quat = |theta: &[f64]| {
                UnitQuaternion::from_quaternion(Quaternion::new(theta[q], theta[q + 1], theta[q + 2], theta[q + 3]))
            };
            let rotation = (quat(&b.theta).inverse() * quat(&a.theta)).scaled_axis();
            out.rows_mut(d, 3).copy_from(&rotation);
        } else {
            for k in 0..link.ndof {
                out[d + k] = a.theta[q + k] - b.theta[q + k];
            }
        }
    }
    for k in 0..nv {
        out[nv + k] = a.qvel[k] - b.qvel[k];
    }
    out
}

/// The scale of each (tangent θ, θ̇) component at a state, as the error
/// control's: 1 + |x| for a coordinate or rate, 1 for a rotation.
fn scale(model: &Model, state: &RunState) -> DVector<f64> {
    let nv = model.nv;
    let mut out = DVector::from_element(2 * nv, 1.0);
    for link in model.links.iter().filter(|link| link.joint != LinkJoint::Ball) {
        for k in 0..link.ndof {
            out[link.dof_adr + k] = 1.0 + state.theta[link.qpos_adr + k].abs();
        }
    }
    for k in 0..nv {
        out[nv + k] = 1.0 + state.qvel[k].abs();
    }
    out
}

fn scaled_norm(x: &DVector<f64>, scale: &DVector<f64>) -> f64 {
    x.iter().zip(scale.iter()).map(|(x, s)| (x / s).abs()).fold(0.0, f64::max)
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// One run's measures (module docs).
struct Measured {
    /// Per communication point: the share of the next step's error estimate
    /// (scaled max norm) in the fast subspace, and left in the slow one.
    estimate_fast: Vec<f64>,
    estimate_slow: Vec<f64>,
    /// The same for the error each communication step made (its end against
    /// a 1e-12 run from its start).
    defect_fast: Vec<f64>,
    defect_slow: Vec<f64>,
    /// The fast eigenvalues' least and largest decay rate (1/s) over the
    /// points, and their largest |Im λ| over |Re λ|.
    fast_decay: (f64, f64),
    fast_swing: f64,
    /// At the end (scaled max norms, over the tolerance): the error
    /// delivered, the communication steps' errors propagated by the
    /// linearized motion, and their plain sum.
    global: f64,
    propagated: f64,
    summed: f64,
}

fn measure(model: &Model, method: Method, tolerance: f64, reference_end: &RunState) -> Measured {
    let eps = eps(model);
    let input = |_: f64, out: &mut [f64]| out.copy_from_slice(&eps);
    let settings = |tolerance| Settings { tolerance, max_step: 0.0, energy_projection: false };
    let mut sim = Simulation::new(model, method, settings(tolerance));
    sim.initialize(model).unwrap();
    let mut integrator = Integrator::new(model, method);
    let mut ws = model.workspace();
    let n = 2 * model.nv;
    let (mut propagated, mut summed) = (DVector::zeros(n), DVector::zeros(n));
    let mut measured = Measured {
        estimate_fast: Vec::new(),
        estimate_slow: Vec::new(),
        defect_fast: Vec::new(),
        defect_slow: Vec::new(),
        fast_decay: (f64::INFINITY, 0.0),
        fast_swing: 0.0,
        global: 0.0,
        propagated: 0.0,
        summed: 0.0,
    };
    for k in 1..=INTERVALS {
        let start = sim.state.clone();
        let jacobian = rate_jacobian(model, &start.theta, &start.qvel, &eps);
        let fast = fast_projector(&jacobian, FAST_DECAY);
        let identity = DMatrix::<f64>::identity(n, n);
        for lambda in jacobian.complex_eigenvalues().iter().filter(|l| l.re < -FAST_DECAY) {
            let (least, largest) = measured.fast_decay;
            measured.fast_decay = (least.min(-lambda.re), largest.max(-lambda.re));
            measured.fast_swing = measured.fast_swing.max(lambda.im.abs() / -lambda.re);
        }
        let scale = scale(model, &start);
        let split = |error: &DVector<f64>, fast_share: &mut Vec<f64>, slow_share: &mut Vec<f64>| {
            let whole = scaled_norm(error, &scale);
            fast_share.push(scaled_norm(&(&fast * error), &scale) / whole);
            slow_share.push(scaled_norm(&((&identity - &fast) * error), &scale) / whole);
        };
        let step = start.carry.next_step;
        if step > 0.0 {
            let (mut theta, mut nu) = (start.theta.clone(), start.nu.clone());
            let t = start.time;
            integrator
                .step(model, &mut ws, (&mut theta, &mut nu), (t, step), |_, out| out.copy_from_slice(&eps))
                .unwrap();
            let (delta, qvel) = integrator.error_estimate();
            let estimate = DVector::from_iterator(n, delta.iter().chain(&qvel[..model.nv]).copied());
            split(&estimate, &mut measured.estimate_fast, &mut measured.estimate_slow);
        }
        let end_time = k as f64 * INTERVAL;
        sim.advance_to(model, end_time, input).unwrap();
        // From some starts (near a switch) 1e-12 stalls at round-off: the next tolerance up.
        let exact = [1e-12, 3e-12, 1e-11]
            .into_iter()
            .find_map(|tolerance| {
                let mut exact = Simulation::new(model, Method::Dop853, settings(tolerance));
                exact.state.theta.clone_from(&start.theta);
                exact.state.nu.clone_from(&start.nu);
                exact.state.time = start.time;
                exact.initialize(model).unwrap();
                exact.advance_to(model, end_time, input).is_ok().then_some(exact)
            })
            .expect("no reference for the communication step");
        let defect = difference(model, &sim.state, &exact.state);
        split(&defect, &mut measured.defect_fast, &mut measured.defect_slow);
        propagated = (&jacobian * INTERVAL).exp() * propagated + &defect;
        summed += &defect;
    }
    let scale = scale(model, reference_end);
    measured.global = scaled_norm(&difference(model, &sim.state, reference_end), &scale) / tolerance;
    measured.propagated = scaled_norm(&propagated, &scale) / tolerance;
    measured.summed = scaled_norm(&summed, &scale) / tolerance;
    measured
}

fn reference_end(model: &Model) -> RunState {
    let eps = eps(model);
    let settings = Settings { tolerance: 1e-12, max_step: 0.0, energy_projection: false };
    let mut sim = Simulation::new(model, Method::Dop853, settings);
    sim.initialize(model).unwrap();
    for k in 1..=INTERVALS {
        sim.advance_to(model, k as f64 * INTERVAL, |_: f64, out: &mut [f64]| out.copy_from_slice(&eps)).unwrap();
    }
    sim.state
}

/// The measure of docs/integration.md ("Where the local errors go"), here
/// on the limited arm (the docs add the docked servicer) (ε = 0.3 sin k, 1 s in 0.05 s
/// communication steps, as tests/all/stiffness.rs): the error estimate lies
/// in modes that decay within a tenth of the tolerance's second (its slow
/// part is below 1 % of it), the linearized propagation of the
/// communication steps' errors accounts for the error at the end, and their
/// plain sum, what a tolerance per second counts on, is 10 times more.
#[test]
fn the_local_errors_on_constrained_fixtures_lie_in_modes_that_decay() {
    // One case of the docs' table (docs/integration.md "Where the local
    // errors go" has all eight): each costs a 1e-12 reference run and a
    // Jacobian per communication point, 20–70 s of the suite's time.
    let cases = [(CONSTRAINED[1], Method::Dopri5, 1e-8)];
    let mut references: Vec<(&str, RunState)> = Vec::new();
    for (path, method, tolerance) in cases {
        let model = fixture(path);
        let name = std::path::Path::new(path).file_stem().unwrap().to_string_lossy().into_owned();
        if !references.iter().any(|(p, _)| *p == path) {
            references.push((path, reference_end(&model)));
        }
        let reference = &references.iter().find(|(p, _)| *p == path).unwrap().1;
        let m = measure(&model, method, tolerance, reference);
        let slow = median(m.estimate_slow.clone());
        println!(
            "{name} {} {tolerance:e}: estimate fast/slow share median {:.2}/{slow:.1e} (least fast {:.2}), \
             step errors fast/slow median {:.2}/{:.1e}; fast Re λ −{:.0} … −{:.0} /s, |Im/Re| ≤ {:.2}; \
             end error/tol {:.2e}, propagated {:.2e}, summed {:.2e}",
            method.name(),
            median(m.estimate_fast.clone()),
            m.estimate_fast.iter().copied().fold(f64::INFINITY, f64::min),
            median(m.defect_fast.clone()),
            median(m.defect_slow.clone()),
            m.fast_decay.0,
            m.fast_decay.1,
            m.fast_swing,
            m.global,
            m.propagated,
            m.summed,
        );
        assert!(slow < 0.01, "{name} {method:?} {tolerance:e}: the estimate's slow part {slow}");
        let propagation = m.propagated / m.global;
        assert!((1.0 / 3.0..3.0).contains(&propagation), "{name} {method:?} {tolerance:e}: {propagation}");
        assert!(m.summed > 10.0 * m.global, "{name} {method:?} {tolerance:e}: {} against {}", m.summed, m.global);
    }
}
