//! One step of a Rosenbrock–W method (tableau.rs, [`Rosenbrock`]) on
//! (Δ, θ̇), for vehicles whose stiffest mode limits explicit steps
//! (docs/integration.md, "Stiff vehicles").
//!
//! The ODE is rkmk.rs's: y = (Δ, θ̇) from (0, θ̇ₙ), with
//! f = (dexp⁻¹₋Δ(θ̇), θ̈(θₙ ⊕ Δ, θ̇, t)). Its matrix W is
//!     W = [ 0  I ]   A = ∂θ̈/∂Δ, B = ∂θ̈/∂θ̇,
//!         [ A  B ]
//! the Jacobian but for the small, non-stiff block of dexp⁻¹ on ball
//! joints (−½[ω]×), which a W-method does not need. By default ([`JacobianSource`])
//! A and B are θ̈'s derivatives in closed form (dynamics/qacc_jacobian.rs,
//! along the tangent directions Δ of `retract`) where they cover the
//! vehicle: exact, for 2.4 ν̇ on the damped stiff
//! boom where the differences cost 17; else forward differences (2·nv
//! evaluations of θ̈). `JacobianSource::Exact` adds the dual numbers
//! (derivatives.rs, 2·nv runs of the passes, in the constraint mode the
//! step holds), which cost 2–4 times the differences. Every kind gave the
//! same steps where measured (docs/integration.md, "What W is made from").
//! W is formed at the
//! first step and kept over the steps that follow, across advances (it is
//! part of an FMU state: [`HeldJacobian`]), until a step with an older W is
//! rejected or [`W_MAX_AGE`] steps were accepted with it; then it is formed
//! again at that step's start.
//! Each stage's system (cI − W)u = r, c = 1/(hγ), is reduced to nv
//! unknowns by eliminating the Δ rows:
//!     (cI − B − A/c) u_θ̇ = r_θ̇ + A r_Δ / c,   u_Δ = (r_Δ + u_θ̇)/c,
//! so a step size costs one LU of an nv × nv matrix. The LU is written here
//! because nalgebra's allocates, and the hot path must not.
//! The actuators' activations act (na) ride along after θ̇ (rkmk.rs): B
//! and A then have nv + na rows (θ̈ then act's rate) and B nv + na columns,
//! probed like θ̇'s, and the matrix is (nv + na) × (nv + na) (exact
//! derivatives do not cover activation states yet: such a model's W is
//! always by differences).

use nalgebra::{DMatrix, DVector};

use super::adaptive::positions;
use super::rkmk::{Integrator, copy_rates, max_abs, retract};
use super::tableau::{ROSENBROCK_STAGES, Rosenbrock, RosenbrockStages};
use crate::dynamics::DynamicsError;
use crate::dynamics::derivatives::{DerivativeError, Derivatives, Direction, Input, Output, Point};
use crate::dynamics::qacc_jacobian::QaccJacobian;
use crate::dynamics::velocity::Given;
use crate::model::Model;
use crate::workspace::Workspace;

/// The most steps accepted with one W. Any W keeps a W-method's order, but
/// one formed far back in the motion can hold the step far below what a
/// fresh one allows, without a rejection to show it: on the damped stiff
/// boom at 1e-6, a W kept for 10⁵ steps held them 25 times shorter. Limits
/// of 25 and 50 steps cost 4–20 % more evaluations there (W formed more
/// often); from 100 to 400 the count levels off. (CVODE reuses its
/// Jacobian for at most 51 steps, but also re-forms it when its Newton
/// iteration converges slowly, a sign a W-method does not have.)
pub const W_MAX_AGE: u32 = 100;

/// The W a Rosenbrock method holds, as saved with a state so that a run
/// restored from it forms W again exactly when the saved run would have.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HeldJacobian {
    /// ∂(θ̈, act's rate)/∂Δ ((nv + na) × nv) then ∂(θ̈, act's rate)/∂(θ̇, act)
    /// ((nv + na) × (nv + na)), column-major; empty when none is held.
    pub derivatives: Vec<f64>,
    /// Steps accepted with it since it was formed.
    pub age: u32,
}

/// Where a Rosenbrock method's W comes from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum JacobianSource {
    /// θ̈'s derivatives in closed form (dynamics/qacc_jacobian.rs) where
    /// they cover the model: exact, and several times cheaper than the
    /// differences (docs/integration.md); forward differences elsewhere.
    #[default]
    ClosedForm,
    /// Exact derivatives: the closed form where it applies, else the dual
    /// numbers where they cover the model and the point, else forward
    /// differences. The dual numbers' W costs 2–4 times the differences'
    /// and gave the same steps where measured (docs/integration.md, "What
    /// W is made from").
    Exact,
    /// Forward differences only.
    Differences,
}

/// Power iterations that estimate W's largest |λ| (`Linearization::largest_rate`).
const POWER_ITERATIONS: usize = 60;

/// The relative size of a forward-difference probe: √ε balances truncation
/// against round-off in the difference.
const PROBE: f64 = 1.4901161193847656e-8;

/// W, its factored iteration matrix, and the stage storage of a Rosenbrock
/// step. Empty (no storage) unless the method is a Rosenbrock method.
#[derive(Clone, Debug, Default)]
pub(super) struct Linearization {
    /// The method's coefficients in stage form.
    stages: RosenbrockStages,
    /// ∂θ̈/∂Δ, with act's rate's rows ((nv + na) × nv).
    qacc_by_delta: DMatrix<f64>,
    /// ∂θ̈/∂θ̇, with act's rate's rows and act's columns ((nv + na) × (nv + na)).
    qacc_by_qvel: DMatrix<f64>,
    /// Whether W holds derivatives (formed at some earlier step's start).
    pub(super) held: bool,
    /// Whether they were formed at the current step's start.
    pub(super) fresh: bool,
    /// Steps accepted since they were formed.
    pub(super) age: u32,
    /// cI − B − A/c, LU-factored in place (unit L below the diagonal), and
    /// the row interchanged with each row in turn.
    lu: DMatrix<f64>,
    pivots: Vec<usize>,
    /// The stages' u: their Δ and (θ̇, act) parts.
    u_delta: Vec<DVector<f64>>,
    u_qvel: Vec<DVector<f64>>,
    /// A stage's right-hand side, solved in place into its u.
    rhs_delta: DVector<f64>,
    rhs_qvel: DVector<f64>,
    /// The rates at a probe of W's derivatives (nv + na).
    probed: DVector<f64>,
    /// The passes in dual numbers that give W's derivatives exactly, when
    /// they cover the model.
    exact: Option<Box<ExactJacobian>>,
    /// θ̈'s derivatives in closed form, when they cover the model, and
    /// the joint forces they take (none: nv zeros).
    closed_form: Option<Box<QaccJacobian>>,
    no_torque: Vec<f64>,
}

/// The derivatives' passes and the directions of W's columns, allocated
/// with the integrator so that forming W allocates nothing.
#[derive(Clone, Debug)]
struct ExactJacobian {
    derivatives: Derivatives,
    /// A unit direction (nv), one entry 1 at a time.
    unit: Vec<f64>,
    /// Zeros along each input (the directions not moved, and the joint forces).
    zeros: [Vec<f64>; 6],
}

impl ExactJacobian {
    /// The buffers for `model`, or None when it has activation states (W's
    /// act rows and columns are not formed here).
    fn new(model: &Model) -> Option<Box<Self>> {
        if model.activation_count() > 0 {
            return None;
        }
        let derivatives = Derivatives::new(model);
        Some(Box::new(ExactJacobian {
            derivatives,
            unit: vec![0.0; model.nv],
            zeros: Input::ALL.map(|input| vec![0.0; input.len(model)]),
        }))
    }

    /// ∂θ̈/∂Δ and ∂θ̈/∂θ̇ at (θ, θ̇) with the inputs (ε, ctrl) at `t`
    /// into `by_delta` and `by_qvel`, column by column, in the constraint
    /// mode `ws` holds (the one its evaluations of the step's stages hold).
    #[allow(clippy::too_many_arguments)]
    fn form(
        &mut self,
        model: &Model,
        ws: &Workspace,
        (theta, qvel): (&[f64], &[f64]),
        (eps, ctrl): (&[f64], &[f64]),
        t: f64,
        (by_delta, by_qvel): (&mut DMatrix<f64>, &mut DMatrix<f64>),
    ) -> Result<(), DerivativeError> {
        self.derivatives.hold_constraint_mode_of(&ws.constraint_rows);
        let torque = &self.zeros[Input::Torque as usize];
        let point = Point { theta, velocity: qvel, given: Given::Qvel, eps, torque, ctrl, act: &[], time: t };
        for (input, jacobian) in [(Input::Theta, by_delta), (Input::Velocity, by_qvel)] {
            for column in 0..model.nv {
                self.unit[column] = 1.0;
                let direction = Direction::along(input, &self.unit, &self.zeros);
                let run = self.derivatives.run_after(model, ws, &point, &direction, &[Output::Qacc]);
                self.unit[column] = 0.0;
                run?;
                for (entry, derivative) in
                    jacobian.column_mut(column).iter_mut().zip(self.derivatives.derivative(Output::Qacc))
                {
                    *entry = derivative;
                }
            }
        }
        Ok(())
    }
}

impl Linearization {
    /// Storage for `method` on `model`.
    pub(super) fn new(model: &Model, method: &Rosenbrock) -> Self {
        let nv = model.nv;
        let rates = nv + model.activation_count();
        Linearization {
            stages: method.stages(),
            qacc_by_delta: DMatrix::zeros(rates, nv),
            qacc_by_qvel: DMatrix::zeros(rates, rates),
            held: false,
            fresh: false,
            age: 0,
            lu: DMatrix::zeros(rates, rates),
            pivots: vec![0; rates],
            u_delta: vec![DVector::zeros(nv); ROSENBROCK_STAGES],
            u_qvel: vec![DVector::zeros(rates); ROSENBROCK_STAGES],
            rhs_delta: DVector::zeros(nv),
            rhs_qvel: DVector::zeros(rates),
            probed: DVector::zeros(rates),
            exact: ExactJacobian::new(model),
            closed_form: QaccJacobian::new(model).ok().map(Box::new),
            no_torque: vec![0.0; nv],
        }
    }

    /// Whether it is the storage for `method` on `model`.
    pub(super) fn fits(&self, model: &Model, method: &Rosenbrock) -> bool {
        self.pivots.len() == model.nv + model.activation_count() && self.stages == method.stages()
    }

    /// W as held, into `out` (its buffer reused).
    fn save(&self, out: &mut HeldJacobian) {
        out.derivatives.clear();
        if self.held {
            out.derivatives.extend(self.qacc_by_delta.iter().chain(self.qacc_by_qvel.iter()));
        }
        out.age = if self.held { self.age } else { 0 };
    }

    /// Holds what `save` wrote, if it is the pair of blocks for this
    /// storage; otherwise holds none.
    fn hold(&mut self, saved: &HeldJacobian) {
        let block = self.qacc_by_delta.len();
        self.held = !saved.derivatives.is_empty() && saved.derivatives.len() == block + self.qacc_by_qvel.len();
        self.fresh = false;
        self.age = saved.age;
        if self.held {
            let (by_delta, by_qvel) = saved.derivatives.split_at(block);
            self.qacc_by_delta.as_mut_slice().copy_from_slice(by_delta);
            self.qacc_by_qvel.as_mut_slice().copy_from_slice(by_qvel);
        }
    }

    /// The largest |λ| of the Jacobian W stands for, [[0, I], [∂θ̈/∂Δ,
    /// ∂θ̈/∂θ̇]] (act with θ̇), by power iteration: the iterate's growth
    /// over the last [`POWER_ITERATIONS`]/2 iterations, which is |λ| for a
    /// complex pair too (it turns the iterate, and grows it by |λ|). None
    /// when no W is held. The stage storage serves as scratch.
    fn largest_rate(&mut self) -> Option<f64> {
        if !self.held || self.u_delta.is_empty() {
            return None;
        }
        let nv = self.qacc_by_delta.ncols();
        let (x_delta, x_qvel) = (&mut self.u_delta[0], &mut self.u_qvel[0]);
        x_delta.fill(1.0);
        x_qvel.fill(1.0);
        let mut log_growth = 0.0;
        for k in 0..POWER_ITERATIONS {
            self.rhs_delta.copy_from(&x_qvel.rows(0, nv));
            self.rhs_qvel.gemv(1.0, &self.qacc_by_delta, x_delta, 0.0);
            self.rhs_qvel.gemv(1.0, &self.qacc_by_qvel, x_qvel, 1.0);
            let size = (self.rhs_delta.norm_squared() + self.rhs_qvel.norm_squared()).sqrt();
            if !(size > 0.0 && size.is_finite()) {
                return (size == 0.0).then_some(0.0);
            }
            x_delta.copy_from(&self.rhs_delta);
            x_qvel.copy_from(&self.rhs_qvel);
            *x_delta /= size;
            *x_qvel /= size;
            if k >= POWER_ITERATIONS / 2 {
                log_growth += size.ln();
            }
        }
        Some((log_growth / (POWER_ITERATIONS - POWER_ITERATIONS / 2) as f64).exp())
    }

    /// Factors cI − B − A/c (A on θ̇'s columns: Δ's rate is θ̇).
    fn factor(&mut self, c: f64) -> Result<(), SingularMatrix> {
        let nv = self.qacc_by_delta.ncols();
        self.lu.zip_apply(&self.qacc_by_qvel, |m, by_qvel| *m = -by_qvel);
        self.lu.columns_mut(0, nv).zip_apply(&self.qacc_by_delta, |m, by_delta| *m -= by_delta / c);
        for j in 0..self.lu.nrows() {
            self.lu[(j, j)] += c;
        }
        lu_factor(&mut self.lu, &mut self.pivots)
    }

    /// Solves the stage system for the right-hand side in (`rhs_delta`,
    /// `rhs_qvel`), leaving u there.
    fn solve(&mut self, c: f64) {
        self.rhs_qvel.gemv(1.0 / c, &self.qacc_by_delta, &self.rhs_delta, 1.0);
        lu_solve(&self.lu, &self.pivots, &mut self.rhs_qvel);
        let nv = self.rhs_delta.len();
        self.rhs_delta += &self.rhs_qvel.rows(0, nv);
        self.rhs_delta /= c;
    }
}

/// A zero or non-finite pivot.
struct SingularMatrix;

/// LU factorization with partial pivoting, in place.
fn lu_factor(m: &mut DMatrix<f64>, pivots: &mut [usize]) -> Result<(), SingularMatrix> {
    let n = m.nrows();
    for k in 0..n {
        let pivot = (k..n).max_by(|&i, &j| m[(i, k)].abs().total_cmp(&m[(j, k)].abs())).unwrap_or(k);
        pivots[k] = pivot;
        if pivot != k {
            m.swap_rows(k, pivot);
        }
        let diagonal = m[(k, k)];
        if diagonal == 0.0 || !diagonal.is_finite() {
            return Err(SingularMatrix);
        }
        for i in k + 1..n {
            m[(i, k)] /= diagonal;
        }
        for j in k + 1..n {
            let factor = m[(k, j)];
            if factor != 0.0 {
                for i in k + 1..n {
                    m[(i, j)] -= m[(i, k)] * factor;
                }
            }
        }
    }
    Ok(())
}

/// Solves LU x = b with the factors of [`lu_factor`], in place.
fn lu_solve(lu: &DMatrix<f64>, pivots: &[usize], b: &mut DVector<f64>) {
    let n = lu.nrows();
    for (k, &pivot) in pivots.iter().enumerate() {
        b.swap_rows(k, pivot);
    }
    for j in 0..n {
        let x = b[j];
        if x != 0.0 {
            for i in j + 1..n {
                b[i] -= lu[(i, j)] * x;
            }
        }
    }
    for j in (0..n).rev() {
        b[j] /= lu[(j, j)];
        let x = b[j];
        for i in 0..j {
            b[i] -= lu[(i, j)] * x;
        }
    }
}

impl Integrator {
    /// The W a Rosenbrock method holds for its next step, into `out`.
    pub(super) fn save_jacobian(&self, out: &mut HeldJacobian) {
        self.linear.save(out);
    }

    /// Holds a W that [`Integrator::save_jacobian`] wrote.
    pub(super) fn hold_jacobian(&mut self, saved: &HeldJacobian) {
        self.linear.hold(saved);
    }

    /// The largest |λ| of the Jacobian the held W stands for (None when a
    /// Rosenbrock method holds none).
    pub(super) fn held_largest_rate(&mut self) -> Option<f64> {
        self.linear.largest_rate()
    }

    /// The Rosenbrock counterpart of `attempt`: forms the step (`delta`,
    /// `qvel_next`) of size `h` from (θ, θ̇) at `t` and its error estimate,
    /// without moving the state.
    pub(super) fn attempt_rosenbrock(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        (theta, qvel): (&[f64], &[f64]),
        (t, h): (f64, f64),
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<(), DynamicsError> {
        if !self.first.valid {
            self.evaluate_start(model, ws, (theta, qvel), t, inputs_at)?;
        } else if !self.linear.fresh {
            // Another attempt from this start: the last was rejected, or
            // nothing was tried from here yet. An older W may be why.
            self.linear.held = false;
        }
        if self.linear.age >= W_MAX_AGE {
            self.linear.held = false;
        }
        let mut linear = std::mem::take(&mut self.linear);
        let result = self.rosenbrock_stages(model, ws, &mut linear, (theta, qvel), (t, h), inputs_at);
        self.linear = linear;
        result
    }

    fn rosenbrock_stages(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        linear: &mut Linearization,
        (theta, qvel): (&[f64], &[f64]),
        (t, h): (f64, f64),
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<(), DynamicsError> {
        if !linear.held {
            self.linearize(model, ws, linear, (theta, qvel), t, inputs_at)?;
        }
        let stages = linear.stages;
        let c = 1.0 / (h * stages.gamma);
        linear.factor(c).map_err(|_| DynamicsError::SingularStep { step: h })?;
        let last = stages.stages - 1;
        for i in 0..stages.stages {
            // The stage's rates f, kept in k_delta/k_qvel as for an explicit step.
            if i == 0 {
                self.first_as_stage_one();
            } else {
                self.delta.fill(0.0);
                self.qvel_stage.copy_from_slice(qvel);
                for j in 0..i {
                    self.delta.axpy(stages.a[i][j], &linear.u_delta[j], 1.0);
                    self.qvel_stage.axpy(stages.a[i][j], &linear.u_qvel[j], 1.0);
                }
                self.evaluate_stage_rates(model, ws, theta, i, t + stages.nodes[i] * h, inputs_at)?;
                if i == last {
                    max_abs(&mut self.nu_size, &ws.nu);
                }
            }
            linear.rhs_delta.copy_from(&self.k_delta[i]);
            linear.rhs_qvel.copy_from(&self.k_qvel[i]);
            for j in 0..i {
                linear.rhs_delta.axpy(stages.c[i][j] / h, &linear.u_delta[j], 1.0);
                linear.rhs_qvel.axpy(stages.c[i][j] / h, &linear.u_qvel[j], 1.0);
            }
            linear.solve(c);
            linear.u_delta[i].copy_from(&linear.rhs_delta);
            linear.u_qvel[i].copy_from(&linear.rhs_qvel);
        }
        self.delta.fill(0.0);
        self.qvel_next.copy_from_slice(qvel);
        self.error_delta.fill(0.0);
        self.error_qvel.fill(0.0);
        for i in 0..stages.stages {
            self.delta.axpy(stages.m[i], &linear.u_delta[i], 1.0);
            self.qvel_next.axpy(stages.m[i], &linear.u_qvel[i], 1.0);
            self.error_delta.axpy(stages.e[i], &linear.u_delta[i], 1.0);
            self.error_qvel.axpy(stages.e[i], &linear.u_qvel[i], 1.0);
        }
        Ok(())
    }

    /// W's derivatives at the step's start (θ, θ̇, t): exact where the
    /// derivatives cover the model and the point, else by differences.
    fn linearize(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        linear: &mut Linearization,
        (theta, qvel): (&[f64], &[f64]),
        t: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<(), DynamicsError> {
        if self.linearize_exactly(model, ws, linear, (theta, qvel), t, inputs_at)? {
            self.exact_jacobians += 1;
        } else {
            self.linearize_by_differences(model, ws, linear, (theta, qvel), t, inputs_at)?;
        }
        linear.held = true;
        linear.fresh = true;
        linear.age = 0;
        self.jacobians += 1;
        Ok(())
    }

    /// W's derivatives at the step's start in closed form or by dual
    /// numbers, when they cover the model and the point and the source
    /// asks for them; whether they were formed. A point the dual numbers
    /// refuse (on a switch of a constraint mode that `ws` does not hold,
    /// where they are one-sided) is left to the differences, which take one
    /// side as a step's stages would.
    fn linearize_exactly(
        &mut self,
        model: &Model,
        ws: &Workspace,
        linear: &mut Linearization,
        (theta, qvel): (&[f64], &[f64]),
        t: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<bool, DynamicsError> {
        if self.jacobian_source == JacobianSource::Differences {
            return Ok(false);
        }
        inputs_at(t, self.eps_stage.as_mut_slice(), self.ctrl_stage.as_mut_slice());
        let qvel = &qvel[..model.nv];
        let blocks = (&mut linear.qacc_by_delta, &mut linear.qacc_by_qvel);
        if let Some(closed_form) = linear.closed_form.as_mut() {
            // The stages apply ε and ctrl, no joint forces T.
            let inputs = (self.eps_stage.as_slice(), linear.no_torque.as_slice(), self.ctrl_stage.as_slice());
            return match closed_form.compute(model, (theta, qvel), inputs, blocks) {
                Ok(()) => Ok(true),
                Err(DerivativeError::Dynamics(cause)) => Err(cause),
                Err(_) => Ok(false),
            };
        }
        let Some(exact) = linear.exact.as_mut() else { return Ok(false) };
        if self.jacobian_source != JacobianSource::Exact {
            return Ok(false);
        }
        let inputs = (self.eps_stage.as_slice(), self.ctrl_stage.as_slice());
        match exact.form(model, ws, (theta, qvel), inputs, t, blocks) {
            Ok(()) => Ok(true),
            Err(DerivativeError::Dynamics(cause)) => Err(cause),
            Err(_) => Ok(false),
        }
    }

    /// W's derivatives at the step's start (θ, θ̇, t), by forward
    /// differences from the first stage: each Δ and θ̇ component is probed
    /// by √ε of its size (at least √ε).
    fn linearize_by_differences(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        linear: &mut Linearization,
        (theta, qvel): (&[f64], &[f64]),
        t: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<(), DynamicsError> {
        for (dof, position) in positions(model, theta) {
            let probe = PROBE * position.map_or(1.0, |y| y.abs().max(1.0));
            self.delta.fill(0.0);
            self.delta[dof] = probe;
            self.theta_stage.copy_from_slice(theta);
            retract(model, self.theta_stage.as_mut_slice(), self.delta.as_slice());
            self.qvel_stage.copy_from_slice(qvel);
            self.evaluate_stage(model, ws, t, inputs_at)?;
            copy_rates(model, &mut linear.probed, ws);
            difference(linear.qacc_by_delta.column_mut(dof).iter_mut(), &linear.probed, &self.first.qacc, probe);
            self.probe_rate_column(model, ws, linear, (theta, qvel), dof, t, inputs_at)?;
        }
        for k in model.nv..qvel.len() {
            self.probe_rate_column(model, ws, linear, (theta, qvel), k, t, inputs_at)?;
        }
        Ok(())
    }

    /// Column `k` of ∂(θ̈, act's rate)/∂(θ̇, act), by a forward difference
    /// from the first stage.
    #[allow(clippy::too_many_arguments)]
    fn probe_rate_column(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        linear: &mut Linearization,
        (theta, qvel): (&[f64], &[f64]),
        k: usize,
        t: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<(), DynamicsError> {
        let moved = qvel[k] + PROBE * qvel[k].abs().max(1.0);
        self.theta_stage.copy_from_slice(theta);
        self.qvel_stage.copy_from_slice(qvel);
        self.qvel_stage[k] = moved;
        self.evaluate_stage(model, ws, t, inputs_at)?;
        copy_rates(model, &mut linear.probed, ws);
        let probe = moved - qvel[k];
        difference(linear.qacc_by_qvel.column_mut(k).iter_mut(), &linear.probed, &self.first.qacc, probe);
        Ok(())
    }
}

/// out = (probed − base) / probe.
fn difference<'a>(out: impl Iterator<Item = &'a mut f64>, probed: &DVector<f64>, base: &DVector<f64>, probe: f64) {
    for ((o, p), b) in out.zip(probed.iter()).zip(base.iter()) {
        *o = (p - b) / probe;
    }
}

#[cfg(test)]
mod tests {
    use super::super::switches::Switches;
    use super::super::tableau::Method;
    use super::*;

    /// The limited arm with its elbow's upper side exactly at its margin,
    /// everything moving, and a workspace for it.
    fn on_a_switch() -> (Model, Vec<f64>, Vec<f64>) {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/constraints/limited_arm.xml");
        let model = Model::compile(&crate::mjcf::load_mjcf(&path).unwrap().vehicle).unwrap();
        let elbow = model.joints.iter().position(|j| j.name == "elbow").unwrap();
        let limit = model.constraints.limits.iter().find(|l| l.joint == elbow).unwrap();
        let mut theta = model.qpos0.clone();
        theta[limit.qpos] = limit.range[1] - limit.margin;
        let qvel = (0..model.nv).map(|k| 0.2 * (k as f64 + 1.0).sin()).collect();
        (model, theta, qvel)
    }

    /// A ROS34PW2 step's W from (θ, θ̇) at t = 0 with `source`, the mode
    /// held as an adaptive run holds it when `held`: its two blocks, and
    /// how many W were formed and how many exactly.
    fn first_w(held: bool, source: JacobianSource) -> (DMatrix<f64>, DMatrix<f64>, usize, usize) {
        let (model, theta, qvel) = on_a_switch();
        let mut ws = model.workspace();
        let mut integrator = Integrator::new(&model, Method::Ros34pw2);
        integrator.jacobian_source = source;
        let ctrl = vec![0.2; model.actuators.len()];
        let mut inputs = |_: f64, eps: &mut [f64], c: &mut [f64]| {
            eps.fill(0.0);
            c.copy_from_slice(&ctrl);
        };
        if held {
            let mut switches = Switches::new(&model);
            switches.establish(&model, &mut ws, &mut integrator, (&theta, &qvel), 0.0, false, &mut inputs).unwrap();
        }
        integrator.attempt(&model, &mut ws, (&theta, &qvel), (0.0, 1e-4), &mut inputs).unwrap();
        let linear = &integrator.linear;
        (linear.qacc_by_delta.clone(), linear.qacc_by_qvel.clone(), integrator.jacobians, integrator.exact_jacobians)
    }

    /// On a switch of the constraint forces: in the mode an adaptive run
    /// holds over the step W is exact (that mode's forces are smooth across
    /// the switch) and equals the differences in the same mode; with no
    /// mode held the derivatives are one-sided there and refused, and W is
    /// by differences, which take the side the step's stages see.
    #[test]
    fn on_a_switch_w_is_exact_in_the_held_mode_and_by_differences_without_one() {
        let (by_delta, by_qvel, formed, exact) = first_w(true, JacobianSource::Exact);
        assert_eq!((formed, exact), (1, 1));
        let (fd_by_delta, fd_by_qvel, formed, exact) = first_w(true, JacobianSource::Differences);
        assert_eq!((formed, exact), (1, 0));
        for (a, b) in [(&by_delta, &fd_by_delta), (&by_qvel, &fd_by_qvel)] {
            let relative = (a - b).amax() / b.amax();
            assert!(relative < 1e-6, "{relative:e} from the differences");
        }
        let (unheld_by_delta, unheld_by_qvel, formed, exact) = first_w(false, JacobianSource::Exact);
        assert_eq!((formed, exact), (1, 0), "refused on the switch, by differences");
        let (fd_by_delta, fd_by_qvel, ..) = first_w(false, JacobianSource::Differences);
        assert_eq!((unheld_by_delta, unheld_by_qvel), (fd_by_delta, fd_by_qvel));
    }

    /// The in-place LU solves a system that needs pivoting as a dense solve
    /// would, and reports a singular one.
    #[test]
    fn lu_solves_with_pivoting() {
        let m = DMatrix::from_row_slice(3, 3, &[0.0, 2.0, 1.0, 1.0, 1.0, 0.0, 3.0, 0.0, 1.0]);
        let x = DVector::from_vec(vec![1.0, -2.0, 0.5]);
        let mut b = &m * &x;
        let mut lu = m.clone();
        let mut pivots = vec![0; 3];
        assert!(lu_factor(&mut lu, &mut pivots).is_ok());
        lu_solve(&lu, &pivots, &mut b);
        assert!((b - x).norm() < 1e-14);
        let mut singular = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 4.0]);
        assert!(lu_factor(&mut singular, &mut pivots[..2]).is_err());
    }
}
