//! The constraint forces' convex problem: minimize ½fᵀHf + gᵀf subject to
//! lower ≤ f ≤ upper, with H symmetric positive definite (A + R: R > 0 makes
//! it so) and 0 within the bounds.
//!
//! A primal active-set method: from a feasible start (the held entries at
//! their bounds, the free ones at 0) it solves for the free entries with
//! the held ones fixed, steps as far as the bounds allow, holds the bound
//! that blocks, and frees the held bound whose multiplier has the wrong
//! sign once no bound blocks. The objective falls at every step and the
//! working sets never repeat, so it ends, at the problem's unique minimizer
//! to round-off: what MuJoCo's solvers approach to their tolerance. The
//! start can be the last solve's working set (`warm`), which along a
//! trajectory is mostly the answer's already: one factorization instead of
//! one per bound reached. The answer is computed from its final working
//! set alone, so which start led there leaves no trace in its bits.
//! Written here because the rows are few and dense and the solve must not
//! allocate; no crate offers a bounded QP with caller-owned buffers.

use super::DynamicsError;
use crate::math::{Real, sum};

/// Where an entry stands in the working set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Held {
    /// Free: solved for.
    Free,
    /// Held at its lower bound.
    Lower,
    /// Held at its upper bound.
    Upper,
}

/// Buffers for [`BoxQp::solve`], sized for the most rows; the data in
/// `S` (a dual number carries the derivative of the minimizer at its
/// working set: the decisions are taken on the values, and the answer is
/// that working set's solve).
#[derive(Clone, Debug)]
pub struct BoxQp<S: Real = f64> {
    /// Each entry's place in the working set (after a solve: the final one).
    pub held: Vec<Held>,
    free: Vec<usize>,
    factor: Vec<S>,
    target: Vec<S>,
}

impl<S: Real> Default for BoxQp<S> {
    fn default() -> Self {
        BoxQp::new(0)
    }
}

impl<S: Real> BoxQp<S> {
    /// Buffers for up to `rows` entries.
    pub fn new(rows: usize) -> Self {
        BoxQp {
            held: vec![Held::Free; rows],
            free: Vec::with_capacity(rows),
            factor: vec![S::zero(); rows * rows],
            target: vec![S::zero(); rows],
        }
    }

    /// Solves for the first `n` entries: `h` is n×n, row-major with row
    /// stride `stride`; the answer goes to `f`. With `warm`, it starts from
    /// the working set `held` holds (the last solve's, for rows of the same
    /// meaning), else from every entry free.
    #[allow(clippy::too_many_arguments)]
    pub fn solve(
        &mut self,
        n: usize,
        h: &[S],
        stride: usize,
        g: &[S],
        lower: &[f64],
        upper: &[f64],
        f: &mut [S],
        warm: bool,
    ) -> Result<(), DynamicsError> {
        let at = |i: usize, j: usize| h[i * stride + j];
        if !warm {
            self.held[..n].fill(Held::Free);
        }
        for i in 0..n {
            f[i] = match self.held[i] {
                Held::Lower if lower[i].is_finite() => S::from(lower[i]),
                Held::Upper if upper[i].is_finite() => S::from(upper[i]),
                _ => {
                    self.held[i] = Held::Free;
                    S::zero()
                }
            };
        }
        // Each working set is visited once; this bound is far above what a
        // solve takes and only stops a loop that round-off could start.
        let limit = 50 + 10 * n * n;
        for _ in 0..limit {
            // The minimizer over the free entries, the held ones fixed.
            self.free.clear();
            self.free.extend((0..n).filter(|&i| self.held[i] == Held::Free));
            let m = self.free.len();
            for (a, &i) in self.free.iter().enumerate() {
                let held_part = sum((0..n).filter(|&j| self.held[j] != Held::Free).map(|j| at(i, j) * f[j]));
                self.target[a] = -(g[i] + held_part);
                for (b, &j) in self.free.iter().enumerate() {
                    self.factor[a * m + b] = at(i, j);
                }
            }
            cholesky_solve(&mut self.factor[..m * m], m, &mut self.target[..m])?;

            // Step towards it as far as the bounds allow (decided on the
            // values; the steps' points are not the answer).
            let mut step = 1.0;
            let mut blocking = None;
            for (a, &i) in self.free.iter().enumerate() {
                let change = (self.target[a] - f[i]).value();
                let (bound, side) = if change < 0.0 { (lower[i], Held::Lower) } else { (upper[i], Held::Upper) };
                if change != 0.0 && bound.is_finite() {
                    let reach = (bound - f[i].value()) / change;
                    if reach < step {
                        step = reach.max(0.0);
                        blocking = Some((i, side, bound));
                    }
                }
            }
            if let Some((i, side, bound)) = blocking {
                for (a, &i) in self.free.iter().enumerate() {
                    f[i] += (self.target[a] - f[i]) * step;
                }
                f[i] = S::from(bound);
                self.held[i] = side;
                continue;
            }
            // The minimizer itself, not f + 1·(target − f): the answer then
            // depends on the final working set alone, not on the path to
            // it (a warm start, an FMU state restored, an output read).
            for (a, &i) in self.free.iter().enumerate() {
                f[i] = self.target[a];
            }

            // At the minimizer of this working set: free the held entry
            // whose gradient points into the box the most.
            let scale = g[..n].iter().fold(1.0_f64, |s, x| s.max(x.value().abs()));
            let mut release = None;
            let mut worst = 1e-14 * scale;
            for i in (0..n).filter(|&i| self.held[i] != Held::Free) {
                let gradient = (g[i] + sum((0..n).map(|j| at(i, j) * f[j]))).value();
                let wrong_way = if self.held[i] == Held::Lower { -gradient } else { gradient };
                if wrong_way > worst {
                    worst = wrong_way;
                    release = Some(i);
                }
            }
            match release {
                Some(i) => self.held[i] = Held::Free,
                None => return Ok(()),
            }
        }
        Err(DynamicsError::ConstraintSolver { rows: n })
    }
}

impl<S: Real> BoxQp<S> {
    /// The minimizer over the free entries with the held ones at their
    /// bounds, for the working set `held` holds (kept as it is): the answer
    /// of the last solve's working set at new data, smooth in the data,
    /// which may leave the box where the working set no longer fits.
    #[allow(clippy::too_many_arguments)]
    pub fn solve_in_working_set(
        &mut self,
        n: usize,
        h: &[S],
        stride: usize,
        g: &[S],
        lower: &[f64],
        upper: &[f64],
        f: &mut [S],
    ) -> Result<(), DynamicsError> {
        for i in 0..n {
            f[i] = match self.held[i] {
                Held::Lower => S::from(lower[i]),
                Held::Upper => S::from(upper[i]),
                Held::Free => S::zero(),
            };
        }
        self.free.clear();
        self.free.extend((0..n).filter(|&i| self.held[i] == Held::Free));
        let m = self.free.len();
        for (a, &i) in self.free.iter().enumerate() {
            let held_part = sum((0..n).filter(|&j| self.held[j] != Held::Free).map(|j| h[i * stride + j] * f[j]));
            self.target[a] = -(g[i] + held_part);
            for (b, &j) in self.free.iter().enumerate() {
                self.factor[a * m + b] = h[i * stride + j];
            }
        }
        cholesky_solve(&mut self.factor[..m * m], m, &mut self.target[..m])?;
        for (a, &i) in self.free.iter().enumerate() {
            f[i] = self.target[a];
        }
        Ok(())
    }

    /// How far the answer `f` of the working set `held` holds is from
    /// leaving it, per entry, into `out`: a free entry's distance to its
    /// nearer finite bound (+∞ without one), a held entry's multiplier
    /// (the objective's slope into the box). Negative where the working set
    /// is no longer the minimizer's: these are the switching functions of
    /// a force's kink.
    #[allow(clippy::too_many_arguments)]
    pub fn working_set_margins(
        &self,
        n: usize,
        h: &[S],
        stride: usize,
        g: &[S],
        (lower, upper): (&[f64], &[f64]),
        f: &[S],
        out: &mut [f64],
    ) {
        for i in 0..n {
            let slope = || (g[i] + sum((0..n).map(|j| h[i * stride + j] * f[j]))).value();
            let force = f[i].value();
            out[i] = match self.held[i] {
                Held::Free => (force - lower[i]).min(upper[i] - force),
                Held::Lower => slope(),
                Held::Upper => -slope(),
            };
        }
    }
}

/// Solves S x = b in place (b becomes x) for symmetric positive definite S
/// (m×m, row-major), by its Cholesky factor S = L Lᵀ written over S. Each
/// entry's sum runs in the order of the textbook loops; where entries are
/// independent (the rows below a column of L, the forward substitution's
/// remaining entries) several are carried at once, so that their running
/// sums overlap instead of each waiting on its last addition (the rows'
/// factor was the constraint forces' largest cost on the docked servicer).
fn cholesky_solve<S: Real>(s: &mut [S], m: usize, b: &mut [S]) -> Result<(), DynamicsError> {
    const ROWS_AT_ONCE: usize = 4;
    for j in 0..m {
        let (row_j, below) = s[j * m..].split_at_mut(m);
        let mut diagonal = row_j[j];
        for l_jk in &row_j[..j] {
            diagonal -= *l_jk * *l_jk;
        }
        if diagonal.value().is_nan() || diagonal.value() <= 0.0 {
            return Err(DynamicsError::ConstraintSolver { rows: m });
        }
        let root = diagonal.sqrt();
        row_j[j] = root;
        let row_j = &row_j[..j];
        for group in below.chunks_mut(ROWS_AT_ONCE * m) {
            let count = group.len() / m;
            let mut values = [S::zero(); ROWS_AT_ONCE];
            for (q, value) in values.iter_mut().enumerate().take(count) {
                *value = group[q * m + j];
            }
            for (k, l_jk) in row_j.iter().enumerate() {
                for (q, value) in values.iter_mut().enumerate().take(count) {
                    *value -= group[q * m + k] * *l_jk;
                }
            }
            for (q, value) in values.into_iter().enumerate().take(count) {
                group[q * m + j] = value / root;
            }
        }
    }
    // L y = b: y_i found, it is taken off every entry below at once.
    for i in 0..m {
        b[i] /= s[i * m + i];
        let y_i = b[i];
        for k in i + 1..m {
            b[k] -= s[k * m + i] * y_i;
        }
    }
    // Lᵀ x = y.
    for i in (0..m).rev() {
        let mut value = b[i];
        for k in i + 1..m {
            value -= s[k * m + i] * b[k];
        }
        b[i] = value / s[i * m + i];
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force: the minimizer is the best of every assignment of each
    /// entry to free, lower or upper whose free solve lies in the box.
    fn brute_force(n: usize, h: &[f64], g: &[f64], lower: &[f64], upper: &[f64]) -> Vec<f64> {
        let objective = |f: &[f64]| {
            let mut value = 0.0;
            for i in 0..n {
                value += g[i] * f[i];
                for j in 0..n {
                    value += 0.5 * f[i] * h[i * n + j] * f[j];
                }
            }
            value
        };
        let mut best: Option<(f64, Vec<f64>)> = None;
        for code in 0..3usize.pow(n as u32) {
            let mut f = vec![0.0; n];
            let mut free = Vec::new();
            let mut c = code;
            let mut feasible = true;
            for i in 0..n {
                match c % 3 {
                    0 => free.push(i),
                    1 => f[i] = lower[i],
                    _ => f[i] = upper[i],
                }
                feasible &= f[i].is_finite();
                c /= 3;
            }
            if !feasible {
                continue;
            }
            let m = free.len();
            let mut s = vec![0.0; m * m];
            let mut b = vec![0.0; m];
            for (a, &i) in free.iter().enumerate() {
                b[a] = -g[i] - (0..n).filter(|j| !free.contains(j)).map(|j| h[i * n + j] * f[j]).sum::<f64>();
                for (bb, &j) in free.iter().enumerate() {
                    s[a * m + bb] = h[i * n + j];
                }
            }
            cholesky_solve(&mut s, m, &mut b).unwrap();
            for (a, &i) in free.iter().enumerate() {
                f[i] = b[a];
            }
            if (0..n).any(|i| f[i] < lower[i] - 1e-12 || f[i] > upper[i] + 1e-12) {
                continue;
            }
            let value = objective(&f);
            if best.as_ref().is_none_or(|(v, _)| value < *v) {
                best = Some((value, f));
            }
        }
        best.unwrap().1
    }

    #[test]
    fn finds_the_minimizer_of_random_box_problems() {
        let mut state = 0x2545f4914f6cdd1d_u64;
        let mut uniform = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let mut same_set = 0;
        for trial in 0..300 {
            let n = 1 + trial % 6;
            // H = BᵀB + diag(r): A + R as the constraints build it.
            let b: Vec<f64> = (0..n * n).map(|_| uniform()).collect();
            let mut h = vec![0.0; n * n];
            for i in 0..n {
                for j in 0..n {
                    h[i * n + j] = (0..n).map(|k| b[k * n + i] * b[k * n + j]).sum();
                }
                h[i * n + i] += 0.01 + uniform().abs();
            }
            let g: Vec<f64> = (0..n).map(|_| 3.0 * uniform()).collect();
            let (mut lower, mut upper) = (vec![0.0; n], vec![0.0; n]);
            for i in 0..n {
                (lower[i], upper[i]) = match trial % 3 {
                    0 => (f64::NEG_INFINITY, f64::INFINITY),
                    1 => (0.0, f64::INFINITY),
                    _ => {
                        let width = uniform().abs();
                        (-width, width)
                    }
                };
                if (i + trial) % 4 == 0 {
                    (lower[i], upper[i]) = (0.0, f64::INFINITY);
                }
            }
            let mut qp = BoxQp::new(n);
            let mut f = vec![0.0; n];
            qp.solve(n, &h, n, &g, &lower, &upper, &mut f, false).unwrap();
            let expected = brute_force(n, &h, &g, &lower, &upper);
            for i in 0..n {
                assert!((f[i] - expected[i]).abs() < 1e-10, "trial {trial}: {f:?} against {expected:?}");
            }
            let (cold, cold_set) = (f.clone(), qp.held[..n].to_vec());
            // From any working set (here a scrambled one) it reaches the same
            // minimizer, and to the bit when it ends in the same working set.
            for (i, held) in qp.held[..n].iter_mut().enumerate() {
                *held = [Held::Free, Held::Lower, Held::Upper][(i + trial) % 3];
            }
            qp.solve(n, &h, n, &g, &lower, &upper, &mut f, true).unwrap();
            for i in 0..n {
                assert!((f[i] - expected[i]).abs() < 1e-10, "warm, trial {trial}: {f:?} against {expected:?}");
            }
            if qp.held[..n] == cold_set[..] {
                same_set += 1;
                assert_eq!(f, cold, "trial {trial}: the same working set, another path");
            }
        }
        assert!(same_set > 200, "{same_set} of 300 trials ended in the cold start's working set");
    }
}
