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
//! Δ is split the same way in m*Δ, and its parts mapped back by m*⁻¹.
//!
//! An error along a direction that decays at rate σ counts towards the
//! error per second by max(h, 1/σ)/(1 s) of it
//! ([`super::adaptive::TOLERANCE_TIME`]): a step of h ≥ 1/σ may leave the
//! tolerance there (it is gone before the next step adds as much), a
//! shorter one σ·(1 s) times its share per second. The directions are
//! formed from the fastest row to the slowest, each with the rate of the
//! row that adds it, the slowest of those spanning it.

use super::adaptive::TOLERANCE_TIME;
use crate::dynamics::constraint::ConstraintRows;
use crate::math::dot;
use crate::model::Model;

/// A column of E whose part outside the columns before it is below this
/// share of its length adds no direction (redundant rows: a weld and a
/// connect on one body).
const DEPENDENT_COLUMN: f64 = 1e-8;

/// Orthonormal directions in ν with their decay rates.
#[derive(Clone, Debug)]
struct Directions {
    /// Unit columns, nv each, column after column.
    basis: Vec<f64>,
    /// The decay rate of each (1/s).
    rates: Vec<f64>,
    count: usize,
}

impl Directions {
    fn new(rows: usize, nv: usize) -> Self {
        Directions { basis: vec![0.0; rows * nv], rates: vec![0.0; rows], count: 0 }
    }

    /// Adds E's column of row `k`, decaying at `rate` (no faster than the
    /// columns before it), if it adds a direction; a redundant one slows
    /// the directions it lies along to its rate.
    fn add(&mut self, nv: usize, rows: &ConstraintRows, k: usize, rate: f64) {
        let original = &rows.eps_columns[k * nv..(k + 1) * nv];
        let (kept, rest) = self.basis.split_at_mut(self.count * nv);
        let column = &mut rest[..nv];
        column.copy_from_slice(original);
        let length = norm(column);
        // Gram–Schmidt, twice (one pass loses orthogonality between nearly parallel rows).
        for _ in 0..2 {
            for unit in kept.chunks_exact(nv) {
                let along = dot(unit, column);
                column.iter_mut().zip(unit).for_each(|(c, u)| *c -= along * u);
            }
        }
        let left = norm(column);
        if left > DEPENDENT_COLUMN * length {
            column.iter_mut().for_each(|c| *c /= left);
            self.rates[self.count] = rate;
            self.count += 1;
        } else {
            for (unit, kept_rate) in kept.chunks_exact(nv).zip(&mut self.rates) {
                if dot(unit, original).abs() > DEPENDENT_COLUMN * length {
                    *kept_rate = kept_rate.min(rate);
                }
            }
        }
    }

    /// `x`'s parts along the directions: all of it in `plain`, and each
    /// direction's weighted by max(`step`, 1/σ)/(1 s) (at most 1) in
    /// `weighted`.
    fn split(&self, nv: usize, step: f64, x: &[f64], (plain, weighted): (&mut [f64], &mut [f64])) {
        plain.fill(0.0);
        weighted.fill(0.0);
        for (unit, rate) in self.basis[..self.count * nv].chunks_exact(nv).zip(&self.rates) {
            let along = dot(unit, x);
            let weight = (step.max(1.0 / rate) / TOLERANCE_TIME).min(1.0);
            for ((p, w), u) in plain.iter_mut().zip(weighted.iter_mut()).zip(unit) {
                *p += along * u;
                *w += weight * along * u;
            }
        }
    }
}

/// The free rows' directions in ν, and the parts of a step's errors along
/// them (preallocated for the model's most rows).
#[derive(Clone, Debug)]
pub(super) struct DampedDirections {
    /// Along which velocity errors decay: every free row's.
    velocities: Directions,
    /// Along which position errors decay: those of the free rows with a stiffness.
    positions: Directions,
    /// The free rows, fastest first: (rate, row, has a stiffness).
    order: Vec<(f64, usize, bool)>,
    /// The ν error being split, and its parts along the free rows' directions,
    /// plain and weighted (nv each).
    pub(super) error_nu: Vec<f64>,
    pub(super) damped_nu: Vec<f64>,
    pub(super) weighted_nu: Vec<f64>,
    /// m*Δ's parts likewise (nv each), for m*⁻¹ to map back.
    pub(super) damped_delta_nu: Vec<f64>,
    pub(super) weighted_delta_nu: Vec<f64>,
    /// Δ's parts, mapped back (nv each).
    pub(super) damped_delta: Vec<f64>,
    pub(super) weighted_delta: Vec<f64>,
}

impl DampedDirections {
    pub(super) fn new(model: &Model) -> Self {
        let (rows, nv) = (model.constraints.max_rows(), model.nv);
        let per_dof = || vec![0.0; if rows > 0 { nv } else { 0 }];
        DampedDirections {
            velocities: Directions::new(rows, nv),
            positions: Directions::new(rows, nv),
            order: Vec::with_capacity(rows),
            error_nu: per_dof(),
            damped_nu: per_dof(),
            weighted_nu: per_dof(),
            damped_delta_nu: per_dof(),
            weighted_delta_nu: per_dof(),
            damped_delta: per_dof(),
            weighted_delta: per_dof(),
        }
    }

    /// Forms the directions of the free rows of `rows` (from the last
    /// evaluation); whether there are any.
    pub(super) fn form(&mut self, model: &Model, rows: &ConstraintRows) -> bool {
        self.order.clear();
        self.order.extend(
            (0..rows.count).filter_map(|k| rows.free_row_decay(model, k).map(|(rate, stiff)| (rate, k, stiff))),
        );
        self.order.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
        self.velocities.count = 0;
        self.positions.count = 0;
        for &(rate, k, stiff) in &self.order {
            self.velocities.add(model.nv, rows, k, rate);
            if stiff {
                self.positions.add(model.nv, rows, k, rate);
            }
        }
        self.velocities.count > 0
    }

    /// `error_nu`, here a defect of the rates in ν, carried over `span` as
    /// an interpolant strays with it (`Integrator::interpolant_strays`):
    /// along a free row's direction, which pulls a state off it back at σ,
    /// only over 1/σ where that is shorter (the state's offset there, not
    /// its drift).
    pub(super) fn carry_defect(&mut self, nv: usize, span: f64) {
        let x = &mut self.error_nu;
        x.iter_mut().for_each(|entry| *entry *= span);
        let directions = &self.velocities;
        for (unit, rate) in directions.basis[..directions.count * nv].chunks_exact(nv).zip(&directions.rates) {
            let dropped = 1.0 - span.min(1.0 / rate) / span;
            let along = dot(unit, x);
            x.iter_mut().zip(unit).for_each(|(entry, u)| *entry -= dropped * along * u);
        }
    }

    /// Whether position errors have directions to decay along.
    pub(super) fn holds_positions(&self) -> bool {
        self.positions.count > 0
    }

    /// `damped_nu` and `weighted_nu`: `error_nu`'s parts along the free
    /// rows, for a step of `step`.
    pub(super) fn split_nu(&mut self, nv: usize, step: f64) {
        let parts = (&mut self.damped_nu[..], &mut self.weighted_nu[..]);
        self.velocities.split(nv, step, &self.error_nu, parts);
    }

    /// `damped_delta_nu` and `weighted_delta_nu`: `delta_nu`'s (m*Δ's)
    /// parts along the free rows with a stiffness.
    pub(super) fn split_delta(&mut self, nv: usize, step: f64, delta_nu: &[f64]) {
        let parts = (&mut self.damped_delta_nu[..], &mut self.weighted_delta_nu[..]);
        self.positions.split(nv, step, delta_nu, parts);
    }
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Directions over two dofs: (1, 1)/√2 decaying at `rate`.
    fn one_direction(rate: f64, error_nu: Vec<f64>) -> DampedDirections {
        let diagonal = Directions { basis: vec![std::f64::consts::FRAC_1_SQRT_2; 2], rates: vec![rate], count: 1 };
        DampedDirections {
            velocities: diagonal.clone(),
            positions: diagonal,
            order: Vec::new(),
            error_nu,
            damped_nu: vec![0.0; 2],
            weighted_nu: vec![0.0; 2],
            damped_delta_nu: vec![0.0; 2],
            weighted_delta_nu: vec![0.0; 2],
            damped_delta: vec![0.0; 2],
            weighted_delta: vec![0.0; 2],
        }
    }

    #[test]
    fn a_defect_is_carried_along_a_fast_direction_over_its_time_constant_only() {
        // (3, 1) = 2·(1, 1) + (1, −1): the first part over 1/σ = 0.01, the second over the span 0.05.
        let mut fast = one_direction(100.0, vec![3.0, 1.0]);
        fast.carry_defect(2, 0.05);
        let expected = [0.01 * 2.0 + 0.05, 0.01 * 2.0 - 0.05];
        for (carried, expected) in fast.error_nu.iter().zip(expected) {
            assert!((carried - expected).abs() < 1e-15, "{:?}", fast.error_nu);
        }
        // A direction slower than the span carries the whole defect over it.
        let mut slow = one_direction(10.0, vec![3.0, 1.0]);
        slow.carry_defect(2, 0.05);
        assert!(slow.error_nu.iter().zip([0.15, 0.05]).all(|(c, e)| (c - e).abs() < 1e-15), "{:?}", slow.error_nu);
    }
}
