//! One explicit Runge–Kutta–Munthe-Kaas step of (θ, ν) (docs/DYNAMICS.md §6).
//!
//! Each step writes the configuration as θ = θₙ ⊕ Δ, where Δ (nv) is a
//! displacement in the Lie algebra: Δθ for hinges and slides, Δp for the
//! translation of a free joint, and a body-frame rotation vector Θ for ball
//! and free-joint rotations (q = qₙ · exp(Θ)). Δ obeys an ordinary ODE,
//!     Δ̇ = dexp⁻¹₋Θ(θ̇) = θ̇ + ½ Θ×ω + c(|Θ|) Θ×(Θ×ω)   on rotations,
//! so any Runge–Kutta tableau applied to (Δ, ν) keeps its order on every
//! joint type. No crate offers this on a product of vector spaces and unit
//! quaternions (the ODE crates integrate vectors), hence this module.

use nalgebra::DVector;

use super::tableau::{ErrorEstimate, Method};
use crate::dynamics::DynamicsError;
use crate::math::{Quat, Vec3, quat_from_wxyz, quat_to_wxyz};
use crate::model::{LinkJoint, Model};
use crate::workspace::Workspace;

/// The most stages of any method (DOP853).
const MAX_STAGES: usize = 12;

/// θₙ ⊕ Δ: moves `theta` (nq) by the algebra displacement `delta` (nv), in place.
pub fn retract(model: &Model, theta: &mut [f64], delta: &[f64]) {
    for link in &model.links {
        let (q, d) = (&mut theta[link.qpos_adr..], &delta[link.dof_adr..]);
        match link.joint {
            LinkJoint::Hinge | LinkJoint::Slide => q[0] += d[0],
            LinkJoint::Translation => (0..3).for_each(|k| q[k] += d[k]),
            LinkJoint::Ball => {
                let rotated =
                    Quat::from_quaternion(quat_from_wxyz(q)) * Quat::from_scaled_axis(Vec3::new(d[0], d[1], d[2]));
                quat_to_wxyz(&rotated, q);
            }
        }
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
    /// ν̇ at the step's start.
    pub nu_dot: DVector<f64>,
    /// Whether the two hold the rates at the current start of step.
    pub valid: bool,
}

/// Preallocated stage storage for one integrator instance, and the result
/// of the last step attempted.
#[derive(Clone, Debug)]
pub struct Integrator {
    pub(super) method: Method,
    /// Δ-rates of the stages.
    k_delta: Vec<DVector<f64>>,
    /// ν-rates of the stages.
    pub(super) k_nu: Vec<DVector<f64>>,
    /// ν·ν̇ at each stage: the power of all forces, since ν·C = 0.
    stage_power: [f64; MAX_STAGES],
    /// The step's Δ and ν (after `attempt`).
    pub(super) delta: DVector<f64>,
    pub(super) nu_next: DVector<f64>,
    /// The local error estimates of Δ and ν (h-scaled), and for DOP853 those
    /// of its 3rd-order estimator.
    pub(super) error_delta: DVector<f64>,
    pub(super) error_nu: DVector<f64>,
    pub(super) error_delta_low: DVector<f64>,
    pub(super) error_nu_low: DVector<f64>,
    pub(super) first: FirstStage,
    /// θ̇ at the last stage before dexp⁻¹, for "first same as last".
    last_qvel: DVector<f64>,
    pub(super) nu_stage: DVector<f64>,
    pub(super) theta_stage: DVector<f64>,
    pub(super) eps_stage: DVector<f64>,
    pub(super) ctrl_stage: DVector<f64>,
}

impl Integrator {
    /// An integrator with `method`, sized for `model`.
    pub fn new(model: &Model, method: Method) -> Self {
        let nv = model.nv;
        Integrator {
            method,
            k_delta: vec![DVector::zeros(nv); MAX_STAGES],
            k_nu: vec![DVector::zeros(nv); MAX_STAGES],
            stage_power: [0.0; MAX_STAGES],
            delta: DVector::zeros(nv),
            nu_next: DVector::zeros(nv),
            error_delta: DVector::zeros(nv),
            error_nu: DVector::zeros(nv),
            error_delta_low: DVector::zeros(nv),
            error_nu_low: DVector::zeros(nv),
            first: FirstStage { qvel: DVector::zeros(nv), nu_dot: DVector::zeros(nv), valid: false },
            last_qvel: DVector::zeros(nv),
            nu_stage: DVector::zeros(nv),
            theta_stage: DVector::zeros(model.nq),
            eps_stage: DVector::zeros(nv),
            ctrl_stage: DVector::zeros(model.actuators.len()),
        }
    }

    /// The method it integrates with.
    pub fn method(&self) -> Method {
        self.method
    }

    /// Changes the method (the stage storage fits every method).
    pub fn set_method(&mut self, method: Method) {
        self.method = method;
        self.first.valid = false;
    }

    /// One step `(t, h)`, of size `h` from time `t`, without error control:
    /// advances `theta` (nq) and `nu` (nv) in place. `eps_at(t, out)` writes
    /// the applied ε at time t; the actuators' controls stay 0. On error,
    /// `theta` and `nu` are unchanged.
    pub fn step(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        (theta, nu): (&mut [f64], &mut [f64]),
        (t, h): (f64, f64),
        mut eps_at: impl FnMut(f64, &mut [f64]),
    ) -> Result<(), DynamicsError> {
        self.first.valid = false;
        self.attempt(model, ws, (theta, nu), (t, h), &mut |t, eps, _ctrl| eps_at(t, eps))?;
        if let Some(cause) = self.non_finite_result() {
            return Err(cause);
        }
        self.accept(model, theta, nu);
        Ok(())
    }

    /// The first non-finite value of the attempted step, if any.
    pub(super) fn non_finite_result(&self) -> Option<DynamicsError> {
        let update = self.nu_next.iter().chain(self.delta.iter());
        update.enumerate().find(|(_, x)| !x.is_finite()).map(|(index, &value)| DynamicsError::NonFinite {
            what: "integrated state",
            index,
            value,
        })
    }

    /// Evaluates the stages of a step of size `h` from (θ, ν) at time `t`
    /// and forms the step (`delta`, `nu_next`) and its error estimates,
    /// without moving the state. Stage 1 comes from `first` when valid.
    pub(super) fn attempt(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        (theta, nu): (&[f64], &[f64]),
        (t, h): (f64, f64),
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<(), DynamicsError> {
        let tableau = self.method.tableau();
        let last = tableau.b.len() - 1;
        for (i, row) in tableau.a.iter().enumerate() {
            if i == 0 && self.first.valid {
                self.k_delta[0].copy_from(&self.first.qvel);
                self.k_nu[0].copy_from(&self.first.nu_dot);
                self.stage_power[0] = self.first.nu_dot.iter().zip(nu).map(|(a, b)| a * b).sum();
                continue;
            }
            self.delta.fill(0.0);
            self.nu_stage.copy_from_slice(nu);
            for (j, a) in row.iter().enumerate() {
                if *a != 0.0 {
                    self.delta.axpy(h * a, &self.k_delta[j], 1.0);
                    self.nu_stage.axpy(h * a, &self.k_nu[j], 1.0);
                }
            }
            self.theta_stage.copy_from_slice(theta);
            retract(model, self.theta_stage.as_mut_slice(), self.delta.as_slice());
            inputs_at(t + tableau.c[i] * h, self.eps_stage.as_mut_slice(), self.ctrl_stage.as_mut_slice());
            ws.set_configuration(model, self.theta_stage.as_slice())?;
            ws.set_nu(model, self.nu_stage.as_slice())?;
            ws.compute_nu_dot_actuated(model, self.eps_stage.as_slice(), self.ctrl_stage.as_slice())?;
            self.k_nu[i].copy_from(&ws.nu_dot);
            self.k_delta[i].copy_from(&ws.qvel);
            self.stage_power[i] = ws.nu_dot.dot(&self.nu_stage);
            if i == 0 {
                self.first.qvel.copy_from(&ws.qvel);
                self.first.nu_dot.copy_from(&ws.nu_dot);
                self.first.valid = true;
            }
            if i == last && tableau.first_same_as_last {
                self.last_qvel.copy_from(&ws.qvel);
            }
            for link in model.links.iter().filter(|l| l.joint == LinkJoint::Ball) {
                let a = link.dof_adr;
                let rotation = Vec3::new(self.delta[a], self.delta[a + 1], self.delta[a + 2]);
                let omega = Vec3::new(ws.qvel[a], ws.qvel[a + 1], ws.qvel[a + 2]);
                self.k_delta[i].fixed_rows_mut::<3>(a).copy_from(&dexp_inv(&rotation, &omega));
            }
        }
        // The same operations as a stage's, so that a "first same as last"
        // method's last stage is evaluated exactly at the step's result.
        self.delta.fill(0.0);
        self.nu_next.copy_from_slice(nu);
        accumulate(&self.k_delta, &self.k_nu, tableau.b, h, &mut self.delta, &mut self.nu_next);
        let estimators = match tableau.error {
            ErrorEstimate::None => [None, None],
            ErrorEstimate::Embedded(weights) => [Some(weights), None],
            ErrorEstimate::Dop853 { fifth, third } => [Some(fifth), Some(third)],
        };
        let errors = [(&mut self.error_delta, &mut self.error_nu), (&mut self.error_delta_low, &mut self.error_nu_low)];
        for (weights, (delta, nu)) in estimators.into_iter().zip(errors) {
            if let Some(weights) = weights {
                delta.fill(0.0);
                nu.fill(0.0);
                accumulate(&self.k_delta, &self.k_nu, weights, h, delta, nu);
            }
        }
        Ok(())
    }

    /// h·Σ bᵢ(νᵢ·ν̇ᵢ): the step's quadrature of the power, which is the
    /// change of K = ½|ν|² along the exact solution.
    pub(super) fn step_work(&self, h: f64) -> f64 {
        let b = self.method.tableau().b;
        h * b.iter().zip(&self.stage_power).map(|(b, p)| b * p).sum::<f64>()
    }

    /// Moves the state to the attempted step's result; for a "first same as
    /// last" method the last stage becomes the next step's first.
    pub(super) fn accept(&mut self, model: &Model, theta: &mut [f64], nu: &mut [f64]) {
        retract(model, theta, self.delta.as_slice());
        nu.copy_from_slice(self.nu_next.as_slice());
        let tableau = self.method.tableau();
        self.first.valid = tableau.first_same_as_last;
        if tableau.first_same_as_last {
            let last = tableau.b.len() - 1;
            self.first.qvel.copy_from(&self.last_qvel);
            self.first.nu_dot.copy_from(&self.k_nu[last]);
        }
    }
}

/// Adds the (Δ, ν) increments h·Σ wᵢkᵢ of the stages with weights `w`.
fn accumulate(
    k_delta: &[DVector<f64>],
    k_nu: &[DVector<f64>],
    w: &[f64],
    h: f64,
    delta: &mut DVector<f64>,
    nu: &mut DVector<f64>,
) {
    for (i, w) in w.iter().enumerate() {
        if *w != 0.0 {
            delta.axpy(h * w, &k_delta[i], 1.0);
            nu.axpy(h * w, &k_nu[i], 1.0);
        }
    }
}
