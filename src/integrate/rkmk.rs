//! One explicit Runge–Kutta–Munthe-Kaas step of (θ, θ̇) (docs/DYNAMICS.md §6).
//!
//! Each step writes the configuration as θ = θₙ ⊕ Δ, where Δ (nv) is a
//! displacement in the Lie algebra: Δθ for hinges and slides, Δp for the
//! translation of a free joint, and a body-frame rotation vector Θ for ball
//! and free-joint rotations (q = qₙ · exp(Θ)). Δ obeys an ordinary ODE,
//!     Δ̇ = dexp⁻¹₋Θ(θ̇) = θ̇ + ½ Θ×ω + c(|Θ|) Θ×(Θ×ω)   on rotations,
//! so any Runge–Kutta tableau applied to (Δ, θ̇) keeps its order on every
//! joint type. No crate offers this on a product of vector spaces and unit
//! quaternions (the ODE crates integrate vectors), hence this module.

use nalgebra::DVector;

use super::decay::DampedDirections;
use super::reach::Reach;
use super::rosenbrock::{JacobianSource, Linearization};
use super::stiffness::StiffnessTest;
use super::switches::StageWatch;
use super::tableau::{DENSE_ROWS, ErrorEstimate, Method, Scheme};
use crate::dynamics::DynamicsError;
use crate::dynamics::actuation::clamped_ctrl;
use crate::math::{Quat, Vec3, quat_from_wxyz, quat_to_wxyz};
use crate::model::{LinkJoint, Model};
use crate::workspace::Workspace;

/// The most stages of any method with those of its dense output (DOP853's 12 and 4).
const MAX_STAGES: usize = 16;

/// θ̈ and act's rate into `rates` (nv + na), from the workspace's `qacc`
/// and `act_dot`: the rates of the integrated (θ̇, act). act's rate is
/// MuJoCo's even at a bound of act's range: a step that carries act past
/// it is clamped when taken ([`clamp_activations`]), and the force reads
/// act clamped meanwhile, so that the rates stay smooth within a step.
pub(super) fn copy_rates(model: &Model, rates: &mut DVector<f64>, ws: &Workspace) {
    let (qacc, act_rates) = rates.as_mut_slice().split_at_mut(model.nv);
    qacc.copy_from_slice(ws.qacc.as_slice());
    act_rates.copy_from_slice(ws.act_dot.as_slice());
}

/// Clamps each act of `act` (na) to its range, as MuJoCo's step does;
/// whether any moved.
pub(super) fn clamp_activations(model: &Model, act: &mut [f64]) -> bool {
    let mut moved = false;
    for (act, activation) in act.iter_mut().zip(model.actuators.iter().filter_map(|a| a.activation)) {
        let clamped = activation.clamp(*act);
        moved |= clamped != *act;
        *act = clamped;
    }
    moved
}

/// What each limited activation's clamp applies to (act, or actearly's
/// look-ahead: [`crate::model::Actuator::clamped_activation`]) at act
/// `act` (na) and controls `ctrl` (nu), into `out` (na; unlimited ones 0).
pub(super) fn clamped_activations(model: &Model, act: &[f64], ctrl: &[f64], out: &mut [f64]) {
    let clamp_ctrl = model.actuation.clamp_ctrl;
    let timestep = model.constraints.options.timestep;
    let owners = model.actuators.iter().zip(ctrl).filter(|(a, _)| a.activation.is_some());
    for ((slot, &act), (actuator, &ctrl)) in out.iter_mut().zip(act).zip(owners) {
        *slot = actuator.clamped_activation(clamped_ctrl(actuator, clamp_ctrl, ctrl), act, timestep);
    }
}

/// The earliest time, as a share of a step, at which a limited
/// activation's clamped quantity ([`clamped_activations`]) goes from inside
/// its range at the step's start (`start`) to past a bound at its end
/// (`end`), taken as linear over the step; `None` when none does. The
/// force kinks there, which an error control would creep across.
pub(super) fn activation_crossing(model: &Model, start: &[f64], end: &[f64]) -> Option<f64> {
    let activations = model.actuators.iter().filter_map(|a| a.activation);
    let mut earliest: Option<f64> = None;
    for ((&a, &b), activation) in start.iter().zip(end).zip(activations) {
        let Some([low, high]) = activation.range else { continue };
        let bound = if a < high && b > high {
            high
        } else if a > low && b < low {
            low
        } else {
            continue;
        };
        let share = (bound - a) / (b - a);
        earliest = Some(earliest.map_or(share, |e| e.min(share)));
    }
    earliest
}

/// θₙ ⊕ Δ: moves `theta` (nq) by the algebra displacement `delta` (nv), in place.
pub fn retract(model: &Model, theta: &mut [f64], delta: &[f64]) {
    for link in &model.links {
        // Fixed-size sub-slices: one bounds check per joint, not per coordinate.
        let (q, d) = (&mut theta[link.qpos_adr..], &delta[link.dof_adr..]);
        match link.joint {
            LinkJoint::Hinge | LinkJoint::Slide => q[0] += d[0],
            LinkJoint::Translation => q[..3].iter_mut().zip(&d[..3]).for_each(|(q, d)| *q += d),
            LinkJoint::Ball => {
                let (q, d) = (&mut q[..4], &d[..3]);
                let rotated =
                    Quat::from_quaternion(quat_from_wxyz(q)) * Quat::from_scaled_axis(Vec3::new(d[0], d[1], d[2]));
                quat_to_wxyz(&rotated, q);
            }
        }
    }
    for flexible in &model.flexible {
        let (q, d) = (&mut theta[flexible.qpos_adr..], &delta[flexible.dof_adr..]);
        q[..flexible.mode_count()].iter_mut().zip(d).for_each(|(q, d)| *q += d);
    }
}

/// dexp⁻¹₋Θ(ω): the rate of the body-frame rotation vector Θ of q = qₙ·exp(Θ)
/// when the body-frame angular velocity is ω.
fn dexp_inv(theta: &Vec3, omega: &Vec3) -> Vec3 {
    let angle2 = theta.norm_squared();
    // c = (1 − (a/2)cot(a/2))/a², by its series near 0 where the closed form cancels.
    let c = if angle2 < 1e-6 {
        1.0 / 12.0 + angle2 / 720.0
    } else {
        let a = angle2.sqrt();
        (1.0 - 0.5 * a / (0.5 * a).tan()) / angle2
    };
    let cross = theta.cross(omega);
    omega + 0.5 * cross + c * theta.cross(&cross)
}

/// The rates at the start of a step (stage 1, where Δ = 0 and dexp⁻¹ is the
/// identity), kept so that a rejected step or a "first same as last" method
/// does not evaluate them again.
#[derive(Clone, Debug)]
pub(super) struct FirstStage {
    /// θ̇ (qvel) at the step's start.
    pub qvel: DVector<f64>,
    /// θ̈ then act's rate at the step's start (nv + na, [`copy_rates`]).
    pub qacc: DVector<f64>,
    /// ν = m*θ̇ at the step's start.
    pub nu: DVector<f64>,
    /// ν·ν̇ there.
    pub power: f64,
    /// Whether these hold the rates at the current start of step.
    pub valid: bool,
}

/// Preallocated stage storage for one integrator instance, and the result
/// of the last step attempted.
///
/// The integrated state is (θ, θ̇), not (θ, ν): θ̈ costs the
/// articulated-body algorithm's passes, 0.6–0.7 of ν̇ (which adds the
/// factor's rates), and on the examples RK4's error constant on (θ, θ̇) is
/// smaller (docs/integration.md, "The integrated state"). ν is formed from
/// θ̇ where a caller reads it, and the error control still measures ν.
///
/// The actuators' activation states act (na) ride along after θ̇: every
/// "qvel" vector below holds θ̇ then act (nv + na), and every "qacc" rate
/// θ̈ then act's rate, since both advance by the same linear stage sums.
#[derive(Clone, Debug)]
pub struct Integrator {
    pub(super) method: Method,
    /// Δ-rates of the stages.
    pub(super) k_delta: Vec<DVector<f64>>,
    /// θ̈ of the stages.
    pub(super) k_qvel: Vec<DVector<f64>>,
    /// ν·ν̇ at each stage: the power of all forces, since ν·C = 0.
    pub(super) stage_power: [f64; MAX_STAGES],
    /// The step's Δ and θ̇ (after `attempt`).
    pub(super) delta: DVector<f64>,
    /// Δ of a dense output's extra stage, or of an interpolated point (scratch).
    pub(super) dense_delta: DVector<f64>,
    pub(super) qvel_next: DVector<f64>,
    /// The local error estimates of Δ and θ̇ (h-scaled), and for DOP853 those
    /// of its 3rd-order estimator.
    pub(super) error_delta: DVector<f64>,
    pub(super) error_qvel: DVector<f64>,
    pub(super) error_delta_low: DVector<f64>,
    pub(super) error_qvel_low: DVector<f64>,
    /// θ̈ at the first two points of [`Integrator::rate_round_off`]'s probe (nv).
    round_off_probe: [DVector<f64>; 2],
    /// The largest |ν| at the first and last stages, per dof: the scale of
    /// ν's error.
    pub(super) nu_size: DVector<f64>,
    pub(super) first: FirstStage,
    /// θ̇ at the last stage before dexp⁻¹, and ν and the power there, for
    /// "first same as last".
    last_qvel: DVector<f64>,
    last_nu: DVector<f64>,
    /// The rates at the attempted step's end, when evaluated there
    /// ([`Integrator::evaluate_end`]): the next step's first stage.
    end: FirstStage,
    pub(super) qvel_stage: DVector<f64>,
    pub(super) theta_stage: DVector<f64>,
    pub(super) eps_stage: DVector<f64>,
    pub(super) ctrl_stage: DVector<f64>,
    /// θ̇ for [`Integrator::step`], which takes and gives ν.
    step_qvel: DVector<f64>,
    /// A Rosenbrock method's Jacobian and linear algebra (empty for explicit methods).
    pub(super) linear: Linearization,
    /// The limited activations' clamped quantities at a step's start and
    /// end (na; `activation_crossing`).
    pub(super) clamped_start: Vec<f64>,
    pub(super) clamped_end: Vec<f64>,
    /// Whether its steps are held by stability (explicit methods).
    pub(super) stiffness: StiffnessTest,
    /// Whether a stage of its steps left the constraint mode (switches.rs).
    pub(super) stage_watch: StageWatch,
    /// The directions free constraint rows damp out, for the error norm (decay.rs).
    pub(super) damped: DampedDirections,
    /// How many times it has evaluated the rates, and formed W, ever, and
    /// of those W how many from exact derivatives.
    pub(super) evaluations: usize,
    pub(super) jacobians: usize,
    pub(super) exact_jacobians: usize,
    /// Where a Rosenbrock method's W comes from.
    pub(super) jacobian_source: JacobianSource,
}

impl Integrator {
    /// Where within the attempted step of size `h` from time `t` a limited
    /// activation's clamp starts to act ([`activation_crossing`]), from the
    /// step's start `qvel` (θ̇ then act) and its end.
    pub(super) fn activation_crossing(
        &mut self,
        model: &Model,
        qvel: &[f64],
        (t, h): (f64, f64),
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Option<f64> {
        if !model.actuators.iter().any(|a| a.activation.is_some_and(|a| a.range.is_some())) {
            return None;
        }
        let nv = model.nv;
        inputs_at(t, self.eps_stage.as_mut_slice(), self.ctrl_stage.as_mut_slice());
        clamped_activations(model, &qvel[nv..], self.ctrl_stage.as_slice(), &mut self.clamped_start);
        inputs_at(t + h, self.eps_stage.as_mut_slice(), self.ctrl_stage.as_mut_slice());
        let end = &self.qvel_next.as_slice()[nv..];
        clamped_activations(model, end, self.ctrl_stage.as_slice(), &mut self.clamped_end);
        activation_crossing(model, &self.clamped_start, &self.clamped_end)
    }

    /// An integrator with `method`, sized for `model`.
    pub fn new(model: &Model, method: Method) -> Self {
        let nv = model.nv;
        // θ̇ then act.
        let rates = nv + model.activation_count();
        Integrator {
            method,
            k_delta: vec![DVector::zeros(nv); MAX_STAGES],
            k_qvel: vec![DVector::zeros(rates); MAX_STAGES],
            stage_power: [0.0; MAX_STAGES],
            delta: DVector::zeros(nv),
            dense_delta: DVector::zeros(nv),
            qvel_next: DVector::zeros(rates),
            error_delta: DVector::zeros(nv),
            error_qvel: DVector::zeros(rates),
            error_delta_low: DVector::zeros(nv),
            error_qvel_low: DVector::zeros(rates),
            round_off_probe: [DVector::zeros(nv), DVector::zeros(nv)],
            nu_size: DVector::zeros(nv),
            first: FirstStage {
                qvel: DVector::zeros(nv),
                qacc: DVector::zeros(rates),
                nu: DVector::zeros(nv),
                power: 0.0,
                valid: false,
            },
            last_qvel: DVector::zeros(nv),
            last_nu: DVector::zeros(nv),
            end: FirstStage {
                qvel: DVector::zeros(nv),
                qacc: DVector::zeros(rates),
                nu: DVector::zeros(nv),
                power: 0.0,
                valid: false,
            },
            qvel_stage: DVector::zeros(rates),
            theta_stage: DVector::zeros(model.nq),
            eps_stage: DVector::zeros(nv),
            ctrl_stage: DVector::zeros(model.actuators.len()),
            step_qvel: DVector::zeros(rates),
            linear: linearization(model, method),
            clamped_start: vec![0.0; model.activation_count()],
            clamped_end: vec![0.0; model.activation_count()],
            stiffness: StiffnessTest::new(nv, rates),
            stage_watch: StageWatch::default(),
            damped: DampedDirections::new(model),
            evaluations: 0,
            jacobians: 0,
            exact_jacobians: 0,
            jacobian_source: JacobianSource::default(),
        }
    }

    /// Drops a Rosenbrock method's W, so that the next step forms it anew.
    pub(super) fn release_jacobian(&mut self) {
        self.linear.held = false;
        self.linear.fresh = false;
    }

    /// The method it integrates with.
    pub fn method(&self) -> Method {
        self.method
    }

    /// Changes the method (the explicit stage storage fits every method; a
    /// Rosenbrock method's is allocated here).
    pub fn set_method(&mut self, model: &Model, method: Method) {
        self.method = method;
        self.first.valid = false;
        self.stiffness.drop_pending();
        if !matches!(method.scheme(), Scheme::Rosenbrock(r) if self.linear.fits(model, r)) {
            self.linear = linearization(model, method);
        }
        self.release_jacobian();
    }

    /// One step `(t, h)`, of size `h` from time `t`, without error control:
    /// advances `theta` (nq) and `nu` (nv) in place. `eps_at(t, out)` writes
    /// the applied ε at time t; the actuators' controls stay 0, and so do
    /// their activations. On error, `theta` and `nu` are unchanged.
    pub fn step(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        (theta, nu): (&mut [f64], &mut [f64]),
        (t, h): (f64, f64),
        mut eps_at: impl FnMut(f64, &mut [f64]),
    ) -> Result<(), DynamicsError> {
        self.first.valid = false;
        self.release_jacobian();
        qvel_of_nu(model, ws, theta, nu, self.step_qvel.as_mut_slice())?;
        let mut qvel = std::mem::take(&mut self.step_qvel);
        let result = self.step_qvel(model, ws, (theta, qvel.as_mut_slice()), (t, h), &mut eps_at);
        if result.is_ok() {
            nu_of_qvel(model, ws, theta, qvel.as_slice(), nu)?;
        }
        self.step_qvel = qvel;
        result
    }

    /// [`Integrator::step`] on (θ, θ̇).
    fn step_qvel(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        (theta, qvel): (&mut [f64], &mut [f64]),
        (t, h): (f64, f64),
        eps_at: &mut impl FnMut(f64, &mut [f64]),
    ) -> Result<(), DynamicsError> {
        self.attempt(model, ws, (theta, qvel), (t, h), &mut |t, eps, _ctrl| eps_at(t, eps))?;
        if let Some(cause) = self.non_finite_result() {
            return Err(cause);
        }
        self.accept(model, theta, qvel);
        Ok(())
    }

    /// The local error estimate of the step last attempted (h-scaled), on Δ
    /// and on θ̇ then act: DOP853's 5th-order one, which its error norm
    /// damps where its 3rd-order one is much larger.
    pub fn error_estimate(&self) -> (&[f64], &[f64]) {
        (self.error_delta.as_slice(), self.error_qvel.as_slice())
    }

    /// The first non-finite value of the attempted step, if any.
    pub(super) fn non_finite_result(&self) -> Option<DynamicsError> {
        let update = self.qvel_next.iter().chain(self.delta.iter());
        update.enumerate().find(|(_, x)| !x.is_finite()).map(|(index, &value)| DynamicsError::NonFinite {
            what: "integrated state",
            index,
            value,
        })
    }

    /// θ̈ and ν at (`theta_stage`, `qvel_stage`) with the inputs at time `t`,
    /// and the power of the forces there (ν·ν̇ = ν·(ε + ε_passive), as ν·C = 0).
    pub(super) fn evaluate_stage(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        t: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<f64, DynamicsError> {
        self.evaluations += 1;
        inputs_at(t, self.eps_stage.as_mut_slice(), self.ctrl_stage.as_mut_slice());
        ws.set_configuration(model, self.theta_stage.as_slice())?;
        let (qvel, act) = self.qvel_stage.as_slice().split_at(model.nv);
        ws.set_qvel(model, qvel)?;
        ws.set_act(model, act)?;
        ws.compute_qacc_actuated(model, self.eps_stage.as_slice(), self.ctrl_stage.as_slice())?;
        // On slices: nalgebra's iterators step by a runtime stride (2 % of all
        // instructions on bus_arm7 went here).
        let forces = ws.eps_applied.as_slice().iter().zip(ws.eps_passive.as_slice());
        Ok(ws.nu.as_slice().iter().zip(forces).map(|(nu, (applied, passive))| nu * (applied + passive)).sum())
    }

    /// Evaluates the stages of a step of size `h` from (θ, θ̇) at time `t`
    /// and forms the step (`delta`, `qvel_next`) and its error estimates,
    /// without moving the state. Stage 1 comes from `first` when valid.
    pub(super) fn attempt(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        (theta, qvel): (&[f64], &[f64]),
        (t, h): (f64, f64),
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<(), DynamicsError> {
        self.end.valid = false;
        self.stage_watch.start_attempt();
        let tableau = match self.method.scheme() {
            Scheme::Explicit(tableau) => tableau,
            Scheme::Rosenbrock(_) => return self.attempt_rosenbrock(model, ws, (theta, qvel), (t, h), inputs_at),
        };
        let last = tableau.b.len() - 1;
        for (i, row) in tableau.a.iter().enumerate() {
            if i == 1 {
                // The first stage is f where the last step ended; its stage at the end is not yet overwritten.
                self.stiffness.at_first_stage(self.method, &self.k_qvel);
            }
            if i == 0 && self.first.valid {
                self.first_as_stage_one();
                continue;
            }
            self.delta.fill(0.0);
            self.qvel_stage.as_mut_slice().copy_from_slice(qvel);
            accumulate(&self.k_delta, &self.k_qvel, row, h, &mut self.delta, &mut self.qvel_stage);
            self.evaluate_stage_rates(model, ws, theta, i, t + tableau.c[i] * h, inputs_at)?;
            if i == 0 {
                self.keep_as_first(model, ws, self.stage_power[0]);
                set_abs(&mut self.nu_size, &ws.nu);
            }
            if i == last {
                max_abs(&mut self.nu_size, &ws.nu);
                if tableau.first_same_as_last {
                    copy(&mut self.last_qvel, &ws.qvel);
                    copy(&mut self.last_nu, &ws.nu);
                }
            }
            self.stage_watch.check_stage(model, ws, self.theta_stage.as_slice(), tableau.c[i])?;
        }
        // The same operations as a stage's, so that a "first same as last"
        // method's last stage is evaluated exactly at the step's result.
        self.delta.fill(0.0);
        self.qvel_next.as_mut_slice().copy_from_slice(qvel);
        accumulate(&self.k_delta, &self.k_qvel, tableau.b, h, &mut self.delta, &mut self.qvel_next);
        let estimators = match tableau.error {
            ErrorEstimate::None => [None, None],
            ErrorEstimate::Embedded(weights) => [Some(weights), None],
            ErrorEstimate::Dop853 { fifth, third } => [Some(fifth), Some(third)],
        };
        let errors =
            [(&mut self.error_delta, &mut self.error_qvel), (&mut self.error_delta_low, &mut self.error_qvel_low)];
        for (weights, (delta, qvel)) in estimators.into_iter().zip(errors) {
            if let Some(weights) = weights {
                delta.fill(0.0);
                qvel.fill(0.0);
                accumulate(&self.k_delta, &self.k_qvel, weights, h, delta, qvel);
            }
        }
        Ok(())
    }

    /// Evaluates stage `i` at θ ⊕ `delta` and θ̇ = `qvel_stage` (both formed
    /// by the caller), at time `t`: its θ̈ into `k_qvel[i]`, its Δ-rates into
    /// `k_delta[i]` and its power into `stage_power[i]`; the workspace keeps
    /// the stage's passes.
    pub(super) fn evaluate_stage_rates(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        theta: &[f64],
        i: usize,
        t: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<(), DynamicsError> {
        self.theta_stage.as_mut_slice().copy_from_slice(theta);
        retract(model, self.theta_stage.as_mut_slice(), self.delta.as_slice());
        self.stage_power[i] = self.evaluate_stage(model, ws, t, inputs_at)?;
        copy_rates(model, &mut self.k_qvel[i], ws);
        // Δ̇ = θ̇, but dexp⁻¹₋Δ(ω) on ball joints.
        copy(&mut self.k_delta[i], &ws.qvel);
        for link in model.links.iter().filter(|l| l.joint == LinkJoint::Ball) {
            let a = link.dof_adr;
            let (delta, qvel) = (&self.delta.as_slice()[a..a + 3], &ws.qvel.as_slice()[a..a + 3]);
            let rate = dexp_inv(&Vec3::new(delta[0], delta[1], delta[2]), &Vec3::new(qvel[0], qvel[1], qvel[2]));
            self.k_delta[i].as_mut_slice()[a..a + 3].copy_from_slice(rate.as_slice());
        }
        Ok(())
    }

    /// Stage 1 from the rates cached at the step's start; ν's error scale
    /// starts from their ν.
    pub(super) fn first_as_stage_one(&mut self) {
        copy(&mut self.k_delta[0], &self.first.qvel);
        copy(&mut self.k_qvel[0], &self.first.qacc);
        self.stage_power[0] = self.first.power;
        set_abs(&mut self.nu_size, &self.first.nu);
    }

    /// Caches the rates the workspace holds, with their `power`, as the
    /// step's first stage.
    fn keep_as_first(&mut self, model: &Model, ws: &Workspace, power: f64) {
        copy(&mut self.first.qvel, &ws.qvel);
        copy_rates(model, &mut self.first.qacc, ws);
        copy(&mut self.first.nu, &ws.nu);
        self.first.power = power;
        self.first.valid = true;
    }

    /// The round-off in θ̈ at (θ, θ̇, act) and time `t`, relative to 1 + |θ̇|
    /// per dof: the largest second difference of θ̈ along a move of θ and
    /// θ̇ by a few ulps, where the rates' own curvature is nil and only the
    /// rounding of the evaluation differs (stiff constraints carry the
    /// rounding of positions into θ̈). Overwrites the workspace's passes and
    /// the stage buffers (three evaluations).
    pub(super) fn rate_round_off(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        (theta, qvel): (&[f64], &[f64]),
        t: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<f64, DynamicsError> {
        for j in 0..3 {
            let moved = j as f64 * ROUND_OFF_PROBE_ULPS * f64::EPSILON;
            probe_point(self.theta_stage.as_mut_slice(), theta, moved);
            probe_point(self.qvel_stage.as_mut_slice(), qvel, moved);
            self.evaluate_stage(model, ws, t, inputs_at)?;
            if j < 2 {
                copy(&mut self.round_off_probe[j], &ws.qacc);
            }
        }
        let [f0, f1] = &self.round_off_probe;
        let f2 = ws.qacc.as_slice();
        Ok((0..model.nv).map(|d| (f2[d] - 2.0 * f1[d] + f0[d]).abs() / (1.0 + qvel[d].abs())).fold(0.0, f64::max))
    }

    /// Σ|eᵢ| of the error estimator's weights: how much of the stages'
    /// round-off an estimate of one step of size h carries, times h.
    pub(super) fn estimator_weight(&self) -> f64 {
        match self.method.scheme() {
            Scheme::Explicit(tableau) => match tableau.error {
                ErrorEstimate::None => 0.0,
                ErrorEstimate::Embedded(weights) | ErrorEstimate::Dop853 { fifth: weights, .. } => {
                    weights.iter().map(|w| w.abs()).sum()
                }
            },
            Scheme::Rosenbrock(_) => 0.0,
        }
    }

    /// Whether the attempted step's last stage is evaluated at its result
    /// ("first same as last"), so that the workspace holds the rates there.
    pub(super) fn last_stage_is_end(&self) -> bool {
        matches!(self.method.scheme(), Scheme::Explicit(t) if t.first_same_as_last)
    }

    /// Evaluates the rates at the attempted step's result (θ ⊕ Δ from
    /// `theta`, at `t_end`); taken, the step hands them to the next as its
    /// first stage.
    pub(super) fn evaluate_end(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        theta: &[f64],
        t_end: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<(), DynamicsError> {
        self.theta_stage.as_mut_slice().copy_from_slice(theta);
        retract(model, self.theta_stage.as_mut_slice(), self.delta.as_slice());
        self.qvel_stage.copy_from(&self.qvel_next);
        let power = self.evaluate_stage(model, ws, t_end, inputs_at)?;
        copy(&mut self.end.qvel, &ws.qvel);
        copy_rates(model, &mut self.end.qacc, ws);
        copy(&mut self.end.nu, &ws.nu);
        self.end.power = power;
        self.end.valid = true;
        Ok(())
    }

    /// The attempted step's interpolant, into `reach` (its start, size,
    /// origin and rows): the attempt is from (θ, θ̇) = (`theta`, `qvel`) at
    /// time `t` with size `h`, after work `work` done. A method whose dense
    /// output needs more stages evaluates them here; DOP853's first, f(y₁),
    /// is then the next step's first stage.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn form_interpolant(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        (theta, qvel): (&[f64], &[f64]),
        (t, h): (f64, f64),
        work: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
        reach: &mut Reach,
    ) -> Result<(), DynamicsError> {
        let Some(dense) = self.method.dense() else { return Ok(()) };
        let Scheme::Explicit(tableau) = self.method.scheme() else { return Ok(()) };
        let stages = tableau.b.len();
        // The extra stages' Δ in `delta`, where the stages read it; the step's own is kept aside.
        std::mem::swap(&mut self.delta, &mut self.dense_delta);
        let mut evaluated = Ok(());
        for (k, &(c, row)) in dense.extra.iter().enumerate() {
            let i = stages + k;
            self.delta.fill(0.0);
            self.qvel_stage.as_mut_slice().copy_from_slice(qvel);
            accumulate(&self.k_delta, &self.k_qvel, row, h, &mut self.delta, &mut self.qvel_stage);
            evaluated = self.evaluate_stage_rates(model, ws, theta, i, t + c * h, inputs_at);
            if evaluated.is_err() {
                break;
            }
            if i == dense.end_stage {
                copy(&mut self.end.qvel, &ws.qvel);
                copy(&mut self.end.qacc, &self.k_qvel[i]);
                copy(&mut self.end.nu, &ws.nu);
                self.end.power = self.stage_power[i];
                self.end.valid = true;
            }
        }
        std::mem::swap(&mut self.delta, &mut self.dense_delta);
        evaluated?;
        let (nv, width) = (model.nv, reach.origin.len() + model.nv);
        reach.rows.fill(0.0);
        for (j, row) in reach.rows.chunks_exact_mut(width).enumerate().take(dense.rows().min(DENSE_ROWS)) {
            let (delta, rest) = row.split_at_mut(nv);
            let (rates, work_row) = rest.split_at_mut(rest.len() - 1);
            for i in 0..stages + dense.extra.len() {
                let weight = h * dense.weight(tableau.b, j, i);
                if weight != 0.0 {
                    add_scaled(delta, weight, self.k_delta[i].as_slice());
                    add_scaled(rates, weight, self.k_qvel[i].as_slice());
                    work_row[0] += weight * self.stage_power[i];
                }
            }
        }
        reach.start = t;
        reach.step = h;
        reach.theta_start.copy_from_slice(theta);
        let (rates, work_origin) = reach.origin.split_at_mut(qvel.len());
        rates.copy_from_slice(qvel);
        work_origin[0] = work;
        Ok(())
    }

    /// How far the interpolant in `reach` (just formed) strays from the
    /// motion, an estimate to set against the tolerance: its defect, θ̇'s
    /// slope against θ̈ evaluated on it, at the middle of the step, where an
    /// interpolant tied to both ends strays most, times a quarter of the
    /// step (the defect carried over the half step, weighted s(1 − s));
    /// largest over the dofs relative to 1 + |θ̇|. Along the directions of
    /// constraint rows whose forces are free the defect is carried over
    /// 1/σ where that is shorter (decay.rs): there it reads an offset the
    /// row pulls back at σ, and the quarter step would overstate it σh/4
    /// times. One evaluation, which leaves the stages, `first` and `end` as
    /// they were.
    pub(super) fn interpolant_strays(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        reach: &Reach,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<f64, DynamicsError> {
        let t = reach.start + 0.5 * reach.step;
        let span = 0.25 * reach.step;
        self.evaluate_on_interpolant(model, ws, reach, t, inputs_at)?;
        let nv = model.nv;
        let qvel = &self.qvel_stage.as_slice()[..nv];
        let damped = ws.constraint_rows.count > 0 && self.damped.form(model, &ws.constraint_rows);
        if !damped {
            let defect = (ws.qacc.iter().zip(qvel).enumerate())
                .map(|(dof, (qacc, rate))| (reach.qacc(t, dof) - qacc).abs() / (1.0 + rate.abs()))
                .fold(0.0, f64::max);
            return Ok(span * defect);
        }
        // The defect in ν (m* at the middle), carried, and mapped back to θ̇'s units.
        let defect = &mut self.damped.error_nu;
        for (dof, entry) in defect.iter_mut().enumerate() {
            *entry = reach.qacc(t, dof) - ws.qacc[dof];
        }
        ws.set_qvel(model, defect)?;
        defect.copy_from_slice(ws.nu.as_slice());
        self.damped.carry_defect(nv, span);
        ws.set_nu(model, &self.damped.error_nu)?;
        Ok((ws.qvel.iter().zip(qvel)).map(|(carried, rate)| carried.abs() / (1.0 + rate.abs())).fold(0.0, f64::max))
    }

    /// Reads the constraint margins at `share` of the step whose
    /// interpolant `reach` holds, as at a stage (switches.rs): the state
    /// there from the interpolant, its rates evaluated in the step's mode.
    /// A point whose rates cannot be evaluated counts as one that left it.
    pub(super) fn probe_margins(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        reach: &Reach,
        share: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) {
        let t = reach.start + share * reach.step;
        let read = self
            .evaluate_on_interpolant(model, ws, reach, t, inputs_at)
            .and_then(|_| self.stage_watch.check_stage(model, ws, self.theta_stage.as_slice(), share));
        if read.is_err() {
            self.stage_watch.left_at(share);
        }
    }

    /// Evaluates the rates at time `t` on the interpolant `reach` holds (the
    /// state there in `theta_stage` and `qvel_stage`); the stages, `first`
    /// and `end` stay as they were.
    pub(super) fn evaluate_on_interpolant(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        reach: &Reach,
        t: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<f64, DynamicsError> {
        let (theta, qvel) = (self.theta_stage.as_mut_slice(), self.qvel_stage.as_mut_slice());
        reach.interpolate(model, t, theta, qvel, self.dense_delta.as_mut_slice());
        self.evaluate_stage(model, ws, t, inputs_at)
    }

    /// Evaluates the rates at the step's start (θ, θ̇, t) into `first`.
    pub(super) fn evaluate_start(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        (theta, qvel): (&[f64], &[f64]),
        t: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<(), DynamicsError> {
        self.theta_stage.as_mut_slice().copy_from_slice(theta);
        self.qvel_stage.as_mut_slice().copy_from_slice(qvel);
        let power = self.evaluate_stage(model, ws, t, inputs_at)?;
        self.keep_as_first(model, ws, power);
        // Any W held was formed at another start.
        self.linear.fresh = false;
        Ok(())
    }

    /// h·Σ bᵢ(νᵢ·ν̇ᵢ): the step's quadrature of the power, which is the
    /// change of K = ½|ν|² along the exact solution.
    pub(super) fn step_work(&self, h: f64) -> f64 {
        let weights = match self.method.scheme() {
            Scheme::Explicit(tableau) => tableau.b,
            Scheme::Rosenbrock(method) => method.power_weights,
        };
        h * weights.iter().zip(&self.stage_power).map(|(w, p)| w * p).sum::<f64>()
    }

    /// Moves the state to the attempted step's result, act clamped to its
    /// range; for a "first same as last" method the last stage becomes the
    /// next step's first (unless the clamp moved act). A held W has served
    /// one more step.
    pub(super) fn accept(&mut self, model: &Model, theta: &mut [f64], qvel: &mut [f64]) {
        retract(model, theta, self.delta.as_slice());
        qvel.copy_from_slice(self.qvel_next.as_slice());
        let clamped = clamp_activations(model, &mut qvel[model.nv..]);
        if clamped {
            self.stiffness.drop_pending();
        }
        let first_same_as_last = self.last_stage_is_end() && !clamped;
        self.first.valid = first_same_as_last || (self.end.valid && !clamped);
        self.linear.age = self.linear.age.saturating_add(1);
        if first_same_as_last {
            let last = self.method.stages() - 1;
            copy(&mut self.first.qvel, &self.last_qvel);
            copy(&mut self.first.qacc, &self.k_qvel[last]);
            copy(&mut self.first.nu, &self.last_nu);
            self.first.power = self.stage_power[last];
        } else if self.end.valid {
            copy(&mut self.first.qvel, &self.end.qvel);
            copy(&mut self.first.qacc, &self.end.qacc);
            copy(&mut self.first.nu, &self.end.nu);
            self.first.power = self.end.power;
        }
    }
}

/// How far θ and θ̇ are moved between the points of the round-off probe,
/// in units of their last place: enough that the evaluation's rounding differs
/// at each, too little for the rates' curvature to show.
const ROUND_OFF_PROBE_ULPS: f64 = 4.0;

/// `base` moved by `moved` relative to 1 + |x| per entry, in alternating
/// directions, into `point`: one point of the round-off probe.
fn probe_point(point: &mut [f64], base: &[f64], moved: f64) {
    for (d, (entry, x)) in point.iter_mut().zip(base).enumerate() {
        let sign = if d.is_multiple_of(2) { 1.0 } else { -1.0 };
        *entry = x + sign * moved * (1.0 + x.abs());
    }
}

/// A Rosenbrock method's storage, or none for an explicit method.
fn linearization(model: &Model, method: Method) -> Linearization {
    match method.scheme() {
        Scheme::Rosenbrock(r) => Linearization::new(model, r),
        Scheme::Explicit(_) => Linearization::default(),
    }
}

/// θ̇ = ℓ*(θ) ν into `qvel`'s first nv entries (act, after them, is left alone).
pub(super) fn qvel_of_nu(
    model: &Model,
    ws: &mut Workspace,
    theta: &[f64],
    nu: &[f64],
    qvel: &mut [f64],
) -> Result<(), DynamicsError> {
    ws.set_configuration(model, theta)?;
    ws.set_nu(model, nu)?;
    qvel[..model.nv].copy_from_slice(ws.qvel.as_slice());
    Ok(())
}

/// ν = m*(θ) θ̇ into `nu`, θ̇ the first nv entries of `qvel`.
pub(super) fn nu_of_qvel(
    model: &Model,
    ws: &mut Workspace,
    theta: &[f64],
    qvel: &[f64],
    nu: &mut [f64],
) -> Result<(), DynamicsError> {
    ws.set_configuration(model, theta)?;
    ws.set_qvel(model, &qvel[..model.nv])?;
    nu.copy_from_slice(ws.nu.as_slice());
    Ok(())
}

/// `to = from` as one memcpy (nalgebra's `copy_from` copies entry by entry).
fn copy(to: &mut DVector<f64>, from: &DVector<f64>) {
    to.as_mut_slice().copy_from_slice(from.as_slice());
}

/// size = |ν|, on slices (nalgebra's `zip_apply` steps by a runtime stride).
fn set_abs(size: &mut DVector<f64>, nu: &DVector<f64>) {
    size.as_mut_slice().iter_mut().zip(nu.as_slice()).for_each(|(size, nu)| *size = nu.abs());
}

/// size = max(size, |ν|), on slices.
pub(super) fn max_abs(size: &mut DVector<f64>, nu: &DVector<f64>) {
    size.as_mut_slice().iter_mut().zip(nu.as_slice()).for_each(|(size, nu)| *size = size.max(nu.abs()));
}

/// Adds the (Δ, θ̇) increments h·Σ wᵢkᵢ of the stages with weights `w`.
fn accumulate(
    k_delta: &[DVector<f64>],
    k_qvel: &[DVector<f64>],
    w: &[f64],
    h: f64,
    delta: &mut DVector<f64>,
    qvel: &mut DVector<f64>,
) {
    for (i, w) in w.iter().enumerate() {
        if *w != 0.0 {
            add_scaled(delta.as_mut_slice(), h * w, k_delta[i].as_slice());
            add_scaled(qvel.as_mut_slice(), h * w, k_qvel[i].as_slice());
        }
    }
}

/// y += a·x on slices, which the compiler vectorizes (nalgebra's axpy steps
/// by a runtime stride); a·x + y is exactly what axpy(a, x, 1) forms.
fn add_scaled(y: &mut [f64], a: f64, x: &[f64]) {
    for (y, x) in y.iter_mut().zip(x) {
        *y += a * x;
    }
}
