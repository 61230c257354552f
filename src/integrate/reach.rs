//! A step that reaches past the communication point (docs/integration.md,
//! "Steps past the communication point"): while the inputs stay as they
//! were, an adaptive method with a dense output does not end a step at
//! each communication point. The state there is the step's interpolant;
//! the integration goes on from the step's end (its "frontier"), or, when
//! an input, a setting or the state was changed, restarts from the
//! interpolated state at the communication point.
//!
//! Everything the continuation needs is here or in the run's state (the
//! input held, `RunState::input`), saved with the FMU state, so that a
//! restored run continues bit for bit as the run that saved it.

use super::rkmk::{clamp_activations, retract};
use super::tableau::{DENSE_ROWS, nested, nested_slope};
use crate::dynamics::box_qp::Held;
use crate::model::Model;

/// The last step of an advance, which ended past the communication point.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Reach {
    /// Whether the run holds such a step: the state at the communication
    /// point is interpolated in it, and the integration may go on from its end.
    pub held: bool,
    /// The step's start (s).
    pub start: f64,
    /// The step's size (s).
    pub step: f64,
    /// θ at the step's start (nq): the interpolant's θ is this ⊕ Δ(s).
    pub theta_start: Vec<f64>,
    /// θ̇ then act (nv + na), and the work done (J), at the step's start.
    pub origin: Vec<f64>,
    /// The interpolant in the nested form of [`super::tableau::DenseOutput`]:
    /// [`DENSE_ROWS`] rows (0 beyond the method's own) of nv + nv + na + 1
    /// values each: Δ, θ̇ then act, and the work.
    pub rows: Vec<f64>,
    /// Where the step ends (s).
    pub end: f64,
    /// θ at the step's end (nq), as the step left it.
    pub theta_end: Vec<f64>,
    /// θ̇ then act at the step's end.
    pub qvel_end: Vec<f64>,
    /// The work done at the step's end (J).
    pub work_end: f64,
    /// The tolerance the step was taken with.
    pub tolerance: f64,
    /// The `max_step` it was taken with.
    pub max_step: f64,
    /// Where the step was cut to end just past a constraint switch, the
    /// constraint solver's working set at its end, one entry per row
    /// there: the integration goes on from the end in the mode past the
    /// switch, the solver starting from this. Empty otherwise (and where no
    /// row acts there, when the solve has nothing to start).
    pub working_set: Vec<Held>,
}

impl Reach {
    /// Buffers for `model`, holding no step.
    pub fn new(model: &Model) -> Self {
        let (nv, na) = (model.nv, model.activation_count());
        Reach {
            theta_start: vec![0.0; model.nq],
            origin: vec![0.0; nv + na + 1],
            rows: vec![0.0; DENSE_ROWS * (2 * nv + na + 1)],
            theta_end: vec![0.0; model.nq],
            qvel_end: vec![0.0; nv + na],
            working_set: Vec::with_capacity(model.constraints.max_rows()),
            ..Reach::default()
        }
    }

    /// The interpolant at time `t` within the step: θ into `theta` (nq),
    /// θ̇ then act into `qvel` (act clamped to its range, as a step's end
    /// is), Δ into `delta` (nv, scratch); returns the work done.
    pub(super) fn interpolate(
        &self,
        model: &Model,
        t: f64,
        theta: &mut [f64],
        qvel: &mut [f64],
        delta: &mut [f64],
    ) -> f64 {
        let s = (t - self.start) / self.step;
        let width = delta.len() + self.origin.len();
        let at = |column: usize| nested(s, DENSE_ROWS, |row| self.rows[row * width + column]);
        for (dof, d) in delta.iter_mut().enumerate() {
            *d = at(dof);
        }
        theta.copy_from_slice(&self.theta_start);
        retract(model, theta, delta);
        let nv = delta.len();
        for (k, x) in qvel.iter_mut().enumerate() {
            *x = self.origin[k] + at(nv + k);
        }
        clamp_activations(model, &mut qvel[model.nv..]);
        let work = self.origin.len() - 1;
        self.origin[work] + at(nv + work)
    }

    /// The interpolant's θ̈ at time `t` within the step for dof `dof`: the
    /// slope of its θ̇.
    pub(super) fn qacc(&self, t: f64, dof: usize) -> f64 {
        let s = (t - self.start) / self.step;
        // A row holds Δ (nv), then θ̇, act and the work (`origin`'s length).
        let width = self.rows.len() / DENSE_ROWS;
        let nv = width - self.origin.len();
        nested_slope(s, DENSE_ROWS, |row| self.rows[row * width + nv + dof]) / self.step
    }
}
