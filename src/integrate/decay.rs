//! The part of a step's error estimate that the constraint rows damp out
//! (docs/integration.md, "Errors the constraint rows damp out").
//!
//! A row whose force is free pulls its velocity Jθ̇ back to its reference
//! within a few time constants, and its position too where the reference
//! has a stiffness, so an error a step leaves along the directions the row
//! moves dies out instead of adding up from step to step. In ν the row
//! moves along its column of E = m⁻¹Jᵀ and reads Jθ̇ = Eᵀν, so those
//! directions are range(E) and the rest, which no row acts on, its
//! orthogonal complement: the split of a ν error is an orthogonal
//! projection, the paper's coordinates making it one. A position error
//! Δ is split the same way in m*Δ, and its part mapped back by m*⁻¹.

use crate::dynamics::constraint::ConstraintRows;
use crate::model::Model;

/// A column of E whose part outside the columns before it is below this
/// share of its length adds no direction (redundant rows: a weld and a
/// connect on one body).
const DEPENDENT_COLUMN: f64 = 1e-8;

/// An orthonormal basis of the free rows' directions in ν, and the parts
/// of a step's errors along them (preallocated for the model's most rows).
#[derive(Clone, Debug, Default)]
pub(super) struct DampedDirections {
    /// Orthonormal columns, nv each, column after column: first those of
    /// the rows with a stiffness, then the others'.
    basis: Vec<f64>,
    /// How many columns span the rows with a stiffness, and all free rows.
    stiff: usize,
    all: usize,
    /// The ν error being split, and its part along all the free rows (nv).
    pub(super) error_nu: Vec<f64>,
    pub(super) damped_nu: Vec<f64>,
    /// The part of a Δ error along the rows with a stiffness (nv), and m*Δ's (scratch).
    pub(super) damped_delta: Vec<f64>,
    scratch: Vec<f64>,
}

impl DampedDirections {
    pub(super) fn new(model: &Model) -> Self {
        let rows = model.constraints.max_rows();
        let per_dof = if rows > 0 { model.nv } else { 0 };
        DampedDirections {
            basis: vec![0.0; rows * model.nv],
            stiff: 0,
            all: 0,
            error_nu: vec![0.0; per_dof],
            damped_nu: vec![0.0; per_dof],
            damped_delta: vec![0.0; per_dof],
            scratch: vec![0.0; per_dof],
        }
    }

    /// Forms the basis of the free rows of `rows` (from the last
    /// evaluation) and returns the slowest of their decay rates (1/s); 0
    /// when no row is free.
    pub(super) fn form(&mut self, model: &Model, rows: &ConstraintRows) -> f64 {
        let nv = model.nv;
        let mut slowest = f64::INFINITY;
        self.all = 0;
        for stiff_pass in [true, false] {
            for k in 0..rows.count {
                let Some((rate, stiff)) = rows.free_row_decay(model, k) else { continue };
                if stiff != stiff_pass {
                    continue;
                }
                // Redundant columns add no direction, but their rates still bound how fast
                // the directions decay.
                slowest = slowest.min(rate);
                // Gram–Schmidt, twice over the columns kept (one pass loses
                // orthogonality between nearly parallel rows).
                let (kept, rest) = self.basis.split_at_mut(self.all * nv);
                let column = &mut rest[..nv];
                column.copy_from_slice(&rows.eps_columns[k * nv..(k + 1) * nv]);
                let length = norm(column);
                for _ in 0..2 {
                    for unit in kept.chunks_exact(nv) {
                        let along = dot(unit, column);
                        column.iter_mut().zip(unit).for_each(|(c, u)| *c -= along * u);
                    }
                }
                let left = norm(column);
                if left > DEPENDENT_COLUMN * length {
                    column.iter_mut().for_each(|c| *c /= left);
                    self.all += 1;
                }
            }
            if stiff_pass {
                self.stiff = self.all;
            }
        }
        if self.all == 0 || !slowest.is_finite() { 0.0 } else { slowest }
    }

    /// Whether the basis spans rows with a stiffness (whose positions return).
    pub(super) fn holds_positions(&self) -> bool {
        self.stiff > 0
    }

    /// `damped_nu`: `error_nu`'s part along all the free rows.
    pub(super) fn split_nu(&mut self, nv: usize) {
        project(&self.basis[..self.all * nv], nv, &self.error_nu, &mut self.damped_nu);
    }

    /// `scratch`: the part of `delta_nu` (m*Δ) along the rows with a
    /// stiffness, to be mapped back by m*⁻¹ into `damped_delta`.
    pub(super) fn split_delta(&mut self, nv: usize, delta_nu: &[f64]) -> &[f64] {
        project(&self.basis[..self.stiff * nv], nv, delta_nu, &mut self.scratch);
        &self.scratch
    }
}

/// `out`: `x`'s orthogonal projection on the orthonormal columns `basis`.
fn project(basis: &[f64], nv: usize, x: &[f64], out: &mut [f64]) {
    out.fill(0.0);
    for unit in basis.chunks_exact(nv) {
        let along = dot(unit, x);
        out.iter_mut().zip(unit).for_each(|(o, u)| *o += along * u);
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}
