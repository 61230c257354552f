//! The error filter of the explicit methods on vehicles with constraint rows
//! (docs/integration.md, "Where the local errors go").
//!
//! A tolerance per second counts each step's local error as if it added up
//! over the run. On a vehicle with constraint rows nearly all of the
//! estimate lies in modes that the rows damp within a few milliseconds
//! (welds, limits, friction loss sticking: Re λ of −17 to −136 /s on the
//! fixtures), where an error dies out instead: the error delivered was a
//! thousandth of the tolerance and less. So before it is measured the
//! estimate e is filtered as
//!
//!     F·e = (I − P)·e + P·(I − τJ)⁻¹·e,
//!
//! J the Jacobian of (Δ̇, θ̈) in (Δ, θ̇) at a step's start (forward
//! differences of the rates in the constraint mode the step holds: the
//! exact derivatives do not cover constraint rows), P the spectral
//! projector onto its modes with Re λ < −[`FAST_DECAY`] (by the matrix sign
//! function: their eigenvectors are nearly defective pairs), and τ the
//! tolerance's second ([`TOLERANCE_TIME`]). A mode of decay rate σ keeps
//! 1/(1 + στ) of its estimate, about the share of a steady error per second
//! it still holds after τ; the modes that do not decay, whose errors add
//! up, keep all of theirs. (For a damped oscillation, λ = σ ± iω, the
//! factor is 1/|1 − τλ|, smaller than 1/(1 + στ) by up to |λ|/σ.)
//!
//! J costs one θ̈ per Δ and θ̇ component, so the filter is formed only on
//! vehicles with constraint rows, at the start of each advance (so that a
//! run restored from an FMU state forms it where the saved run did) and
//! after [`FILTER_MAX_AGE`] steps. It is kept across switches: formed
//! again after each one, it delivered the same errors on the fixtures for
//! up to 30 % more evaluations.

use nalgebra::{DMatrix, DVector};

use super::adaptive::TOLERANCE_TIME;
use super::rkmk::Integrator;
use crate::dynamics::DynamicsError;
use crate::model::Model;
use crate::workspace::Workspace;

/// A mode counts as one an error dies out in when Re λ < −this (1/s): ten
/// times faster than the tolerance's second.
pub(super) const FAST_DECAY: f64 = 10.0;

/// Steps accepted with one filter before it is formed again at the next
/// step's start.
pub(super) const FILTER_MAX_AGE: u32 = 50;

/// Newton iterations of the sign function before the filter is given up
/// (the identity used): it converges quadratically once its scaling has
/// brought the eigenvalues near ±1, in 8–15 on the fixtures.
const SIGN_ITERATIONS: usize = 60;

/// The filter and its storage; empty on a vehicle without constraint rows.
#[derive(Clone, Debug, Default)]
pub(super) struct ErrorFilter {
    /// ∂θ̈/∂Δ and ∂θ̈/∂θ̇ with act's rows and columns, and a probe's rates.
    by_delta: DMatrix<f64>,
    by_qvel: DMatrix<f64>,
    probed: DVector<f64>,
    /// F (2nv square, on (Δ, θ̇)).
    matrix: DMatrix<f64>,
    /// Whether `matrix` holds the filter formed at some step's start since
    /// the advance began.
    pub(super) formed: bool,
    /// Steps accepted since it was formed.
    pub(super) age: u32,
    /// (Δ, θ̇) of an estimate, and its filtered value (2nv).
    estimate: DVector<f64>,
    filtered: DVector<f64>,
}

impl ErrorFilter {
    /// Storage for `model`: none unless it has constraint rows.
    pub(super) fn new(model: &Model) -> Self {
        if model.constraints.switch_count() == 0 {
            return ErrorFilter::default();
        }
        let (nv, rates) = (model.nv, model.nv + model.activation_count());
        ErrorFilter {
            by_delta: DMatrix::zeros(rates, nv),
            by_qvel: DMatrix::zeros(rates, rates),
            probed: DVector::zeros(rates),
            matrix: DMatrix::identity(2 * nv, 2 * nv),
            formed: false,
            age: 0,
            estimate: DVector::zeros(2 * nv),
            filtered: DVector::zeros(2 * nv),
        }
    }

    /// Whether the vehicle has a filter and it must be formed before the next step.
    pub(super) fn due(&self) -> bool {
        !self.estimate.is_empty() && (!self.formed || self.age >= FILTER_MAX_AGE)
    }

    /// Drops the filter: the next step forms it afresh.
    pub(super) fn drop_formed(&mut self) {
        self.formed = false;
    }

    /// F from the derivatives probed (module docs); the identity where the
    /// sign function does not converge (an eigenvalue at Re λ = −FAST_DECAY).
    fn form_matrix(&mut self) {
        let nv = self.by_delta.ncols();
        let n = 2 * nv;
        let mut jacobian = DMatrix::zeros(n, n);
        jacobian.view_mut((0, nv), (nv, nv)).fill_with_identity();
        jacobian.view_mut((nv, 0), (nv, nv)).copy_from(&self.by_delta.view((0, 0), (nv, nv)));
        jacobian.view_mut((nv, nv), (nv, nv)).copy_from(&self.by_qvel.view((0, 0), (nv, nv)));
        let identity = DMatrix::<f64>::identity(n, n);
        let resolvent = (&identity - &jacobian * TOLERANCE_TIME).try_inverse();
        self.matrix = match (fast_projector(&jacobian), resolvent) {
            (Some(projector), Some(resolvent)) => &identity + &projector * (resolvent - &identity),
            _ => identity,
        };
    }

    /// Filters an estimate of Δ (nv) and θ̇ then act (nv + na) in place;
    /// act's part is left as it is.
    fn apply(&mut self, delta: &mut DVector<f64>, qvel: &mut DVector<f64>) {
        let nv = delta.len();
        self.estimate.rows_mut(0, nv).copy_from(delta);
        self.estimate.rows_mut(nv, nv).copy_from(&qvel.rows(0, nv));
        self.filtered.gemv(1.0, &self.matrix, &self.estimate, 0.0);
        delta.copy_from(&self.filtered.rows(0, nv));
        qvel.rows_mut(0, nv).copy_from(&self.filtered.rows(nv, nv));
    }
}

/// The spectral projector onto the modes of `jacobian` with Re λ <
/// −[`FAST_DECAY`]: (I − sign(J + FAST_DECAY·I))/2, the sign function by
/// Newton's iteration with norm scaling; None if it does not converge.
fn fast_projector(jacobian: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = jacobian.nrows();
    let identity = DMatrix::<f64>::identity(n, n);
    let mut sign = jacobian + &identity * FAST_DECAY;
    for _ in 0..SIGN_ITERATIONS {
        let inverse = sign.clone().try_inverse()?;
        let scale = (inverse.norm() / sign.norm()).sqrt();
        let next = (&sign * scale + inverse / scale) * 0.5;
        let change = (&next - &sign).norm();
        sign = next;
        if !change.is_finite() {
            return None;
        }
        if change <= 1e-12 * sign.norm() {
            return Some((identity - sign) * 0.5);
        }
    }
    None
}

impl Integrator {
    /// Forms the error filter at a step's start (θ, θ̇, t), whose rates
    /// `first` holds (evaluated here if it does not).
    pub(super) fn form_filter(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        (theta, qvel): (&[f64], &[f64]),
        t: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<(), DynamicsError> {
        if !self.first.valid {
            self.evaluate_start(model, ws, (theta, qvel), t, inputs_at)?;
        }
        let mut filter = std::mem::take(&mut self.filter);
        let derivatives = (&mut filter.by_delta, &mut filter.by_qvel, &mut filter.probed);
        let probed = self.rate_derivatives(model, ws, (theta, qvel), t, inputs_at, derivatives);
        if probed.is_ok() {
            filter.form_matrix();
            filter.formed = true;
            filter.age = 0;
        }
        self.filter = filter;
        probed
    }

    /// Filters the attempted step's error estimates, if a filter is formed.
    pub(super) fn filter_estimates(&mut self) {
        if !self.filter.formed {
            return;
        }
        self.filter.apply(&mut self.error_delta, &mut self.error_qvel);
        self.filter.apply(&mut self.error_delta_low, &mut self.error_qvel_low);
    }
}
