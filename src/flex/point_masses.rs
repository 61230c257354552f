//! A flexible body's point-mass nodes summed in closed form (docs/flexible.md,
//! "Point-mass nodes"). A node without rotary inertia and without a
//! rotation in any mode is a point of mass mⱼ at pⱼ(η) = rⱼ + Φⱼη in the
//! body frame R (Φⱼ: 3 × m); every sum the modal block takes over such nodes
//! is then a polynomial of degree two in η whose coefficients are moments of
//! the nodes' masses, shapes and positions (the modal integrals), fixed at
//! compile:
//!
//!   M = Σ mⱼ,  c₀ = Σ mⱼ rⱼ,  Cₖ = Σ mⱼ Φⱼₖ,
//!   P₀ = Σ mⱼ rⱼ rⱼᵀ,  Qₖ = Σ mⱼ rⱼ Φⱼₖᵀ,  Tₖₗ = Σ mⱼ Φⱼₖ Φⱼₗᵀ.
//!
//! With c = c₀ + Cη and S = Σ mⱼ pⱼpⱼᵀ = P₀ + Σ ηₖ(Qₖ + Qₖᵀ) + Σ ηₖηₗTₖₗ:
//!
//!   𝓘_RR = [tr(S)1 − S, c×; (c×)ᵀ, M1],   U's column k = [Σ mⱼ pⱼ × Φⱼₖ; Cₖ],   D = [tr Tₖₗ];
//!
//! each node's velocity-product force is mⱼ ω × (v + ω × pⱼ + 2Φⱼη̇) at pⱼ,
//! so with N = Σ mⱼ Φⱼη̇ pⱼᵀ the block's is, about R's origin and on the modes,
//!
//!   f = ω × (Mv + ω × c + 2Cη̇),   n = c × (ω × v) − ω × Sω + 2(tr(N) ω − Nω),
//!   uₖ = −(Cₖ·(ω × v) + tr((ω×)² Σ mⱼ pⱼΦⱼₖᵀ) + 2 Σₗ η̇ₗ tr((ω×) Tₗₖ)),
//!
//! where tr((ω×) T) = ω · axial(T), axial(T) the vector of T's
//! antisymmetric part, so that the last sum is 2 ω · Σₗ η̇ₗ axial(Tₗₖ);
//! and their rates along η̇: Ṡ = N + Nᵀ, ċ = Cη̇, U̇'s column k = [Σₗ η̇ₗ axial(Tₗₖ); 0],
//! Ḋ = 0. The cost is O(m²) whatever the number of such nodes (a finite-
//! element model's solid elements give only such nodes), and the sums are
//! exact: the same as taking the nodes one by one.

use serde::{Deserialize, Serialize};

use super::ModalBody;
use nalgebra::{DMatrix, Dim, SVector, U3, U6, U9};

use crate::math::{
    Mat3, Real, SpatialMat, SpatialVec, Vec3, angular, leading, leading_mut, linear, real, skew, spatial,
};

/// The modal integrals of a body's point-mass nodes (all zero when it has none).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PointMasses {
    /// M = Σ mⱼ.
    pub mass: f64,
    /// c₀ = Σ mⱼ rⱼ.
    pub first_moment: Vec3,
    /// Cₖ = Σ mⱼ Φⱼₖ, one per mode.
    pub shape_moments: Vec<Vec3>,
    /// P₀ = Σ mⱼ rⱼ rⱼᵀ.
    pub second_moment: Mat3,
    /// Qₖ = Σ mⱼ rⱼ Φⱼₖᵀ, one per mode.
    pub position_shape: Vec<Mat3>,
    /// Tₖₗ = Σ mⱼ Φⱼₖ Φⱼₗᵀ at k·m + l.
    pub shape_shape: Vec<Mat3>,
}

/// Whether node `j` of `body` is a point mass: no rotary inertia, no rotation in any mode.
pub fn is_point_mass(body: &ModalBody, j: usize) -> bool {
    body.nodes[j].rotary_inertia == Mat3::zeros() && body.modes.iter().all(|mode| mode.rotation[j] == Vec3::zeros())
}

/// The vector of a matrix's antisymmetric part: for A = Σ a bᵀ, Σ a × b.
fn axial<S: Real>(a: &Mat3<S>) -> Vec3<S> {
    Vec3::new(a[(1, 2)] - a[(2, 1)], a[(2, 0)] - a[(0, 2)], a[(0, 1)] - a[(1, 0)])
}

/// The spatial inertia [tr(S)1 − S, c×; (c×)ᵀ, M1] (about the origin), or
/// its rate with `mass` 0.
fn inertia_of<S: Real>(mass: S, c: &Vec3<S>, s: &Mat3<S>) -> SpatialMat<S> {
    let mut out = SpatialMat::zeros();
    let cross = skew(c);
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&(Mat3::identity() * s.trace() - s));
    out.fixed_view_mut::<3, 3>(0, 3).copy_from(&cross);
    out.fixed_view_mut::<3, 3>(3, 0).copy_from(&cross.transpose());
    out.fixed_view_mut::<3, 3>(3, 3).copy_from(&(Mat3::identity() * mass));
    out
}

impl PointMasses {
    /// The integrals of `body`'s nodes other than those in `one_by_one`
    /// (every node that is not a point mass, and those carrying a child body).
    pub fn of(body: &ModalBody, one_by_one: &[usize]) -> PointMasses {
        let m = body.modes.len();
        let mut out = PointMasses {
            shape_moments: vec![Vec3::zeros(); m],
            position_shape: vec![Mat3::zeros(); m],
            shape_shape: vec![Mat3::zeros(); m * m],
            ..PointMasses::default()
        };
        for (j, node) in body.nodes.iter().enumerate().filter(|(j, _)| !one_by_one.contains(j)) {
            let (mass, r) = (node.mass, node.position);
            out.mass += mass;
            out.first_moment += r * mass;
            out.second_moment += r * r.transpose() * mass;
            for (k, mode) in body.modes.iter().enumerate() {
                let phi = mode.translation[j];
                out.shape_moments[k] += phi * mass;
                out.position_shape[k] += r * phi.transpose() * mass;
                for (l, other) in body.modes.iter().enumerate() {
                    out.shape_shape[k * m + l] += phi * other.translation[j].transpose() * mass;
                }
            }
        }
        out
    }

    fn modes(&self) -> usize {
        self.shape_moments.len()
    }

    fn shape_shape<S: Real>(&self, k: usize, l: usize) -> Mat3<S> {
        real(&self.shape_shape[k * self.modes() + l])
    }
}

/// Mat3 entry (row, col) of a matrix kept as a column of 9 (column-major).
const fn at(row: usize, col: usize) -> usize {
    row + 3 * col
}

/// The vector of the antisymmetric part of a matrix kept as 9 entries.
fn axial_of<S: Real>(a: impl Fn(usize) -> S) -> Vec3<S> {
    Vec3::new(a(at(1, 2)) - a(at(2, 1)), a(at(2, 0)) - a(at(0, 2)), a(at(0, 1)) - a(at(1, 0)))
}

/// A body's point-mass integrals in the passes' scalar, laid out for the
/// passes' loops (made once, with the workspace), and the sums at the
/// workspace's state, kept from pass to pass. The methods take the mode
/// count as a dimension (`Const` for the fixed-size instances).
#[derive(Clone, Debug)]
pub struct State<S: Real> {
    /// Whether the body has point masses at all.
    present: bool,
    /// M.
    mass: S,
    /// c₀.
    first_moment_0: Vec3<S>,
    /// P₀.
    second_moment_0: Mat3<S>,
    /// Cₖ as columns (3 × m).
    shape_moments: DMatrix<S>,
    /// Qₖ as columns of 9, column-major (9 × m).
    position_shape_0: DMatrix<S>,
    /// Per mode k, Tₗₖ as columns of 9 (9 × m each).
    shape_shape: Vec<DMatrix<S>>,
    /// Per mode k, the vectors of Tₗₖ's antisymmetric parts as columns
    /// (3 × m each): tr((ω×) Tₗₖ) = ω · axial(Tₗₖ).
    shape_shape_axial: Vec<DMatrix<S>>,
    /// The point masses' D = [tr Tₖₗ] (m × m), constant.
    pub modal_mass: DMatrix<S>,
    /// c = c₀ + Cη (pass 1).
    first_moment: Vec3<S>,
    /// S = Σ mⱼ pⱼpⱼᵀ (pass 1).
    second_moment: Mat3<S>,
    /// Σ mⱼ pⱼΦⱼₖᵀ = Qₖ + Σₗ ηₗTₗₖ as columns of 9 (pass 1).
    position_shape: DMatrix<S>,
    /// N = Σ mⱼ Φⱼη̇ pⱼᵀ (pass 3).
    rate_moment: Mat3<S>,
    /// Cη̇ (pass 3).
    shape_rate: Vec3<S>,
    /// Σₗ η̇ₗ axial(Tₗₖ) as columns (3 × m; pass 3): the angular rows of U̇.
    axial_rate: DMatrix<S>,
}

impl<S: Real> State<S> {
    /// The integrals of `points` and buffers for their sums, for a body of
    /// `modes` modes (`points` has as many, or none if it is the default).
    pub fn new(points: &PointMasses, modes: usize) -> Self {
        let m = modes;
        let present = points.mass != 0.0;
        let shape_shape = |k: usize, l: usize| if present { points.shape_shape::<S>(k, l) } else { Mat3::zeros() };
        let mat9 = |a: &Mat3| DMatrix::from_fn(9, 1, |e, _| S::from(a[e]));
        State {
            present,
            mass: S::from(points.mass),
            first_moment_0: real(&points.first_moment),
            second_moment_0: real(&points.second_moment),
            shape_moments: DMatrix::from_fn(3, m, |r, k| {
                if present { S::from(points.shape_moments[k][r]) } else { S::zero() }
            }),
            position_shape_0: DMatrix::from_fn(9, m, |e, k| {
                if present { mat9(&points.position_shape[k])[e] } else { S::zero() }
            }),
            shape_shape: (0..m).map(|k| DMatrix::from_fn(9, m, |e, l| shape_shape(l, k)[e])).collect(),
            shape_shape_axial: (0..m).map(|k| DMatrix::from_fn(3, m, |r, l| axial(&shape_shape(l, k))[r])).collect(),
            modal_mass: DMatrix::from_fn(m, m, |k, l| shape_shape(k, l).trace()),
            first_moment: Vec3::zeros(),
            second_moment: Mat3::zeros(),
            position_shape: DMatrix::zeros(9, m),
            rate_moment: Mat3::zeros(),
            shape_rate: Vec3::zeros(),
            axial_rate: DMatrix::zeros(3, m),
        }
    }

    /// c, S and Σ mⱼ pⱼΦⱼₖᵀ at `eta`: with Y = Σ ηₖQₖ and
    /// Z = Σ ηₖ Σ mⱼ pⱼΦⱼₖᵀ = Y + Σ ηₖηₗTₗₖ, S = P₀ + Yᵀ + Z.
    pub fn configure<M: Dim>(&mut self, modes: M, eta: &[S]) {
        let m = modes.value();
        let eta = &eta[..m];
        let (shape_moments, q) = (leading(&self.shape_moments, U3, modes), leading(&self.position_shape_0, U9, modes));
        let mut position_shape = leading_mut(&mut self.position_shape, U9, modes);
        let mut c = self.first_moment_0;
        let (mut y, mut z) = (SVector::<S, 9>::zeros(), SVector::<S, 9>::zeros());
        for k in 0..m {
            let t = leading(&self.shape_shape[k], U9, modes);
            for e in 0..9 {
                let mut entry = q[(e, k)];
                for l in 0..m {
                    entry += t[(e, l)] * eta[l];
                }
                position_shape[(e, k)] = entry;
                y[e] += q[(e, k)] * eta[k];
                z[e] += entry * eta[k];
            }
            for r in 0..3 {
                c[r] += shape_moments[(r, k)] * eta[k];
            }
        }
        self.first_moment = c;
        self.second_moment = self.second_moment_0
            + Mat3::from_column_slice(y.as_slice()).transpose()
            + Mat3::from_column_slice(z.as_slice());
    }

    /// Adds the point masses' 𝓘_RR to `rigid` and their U to `coupling`
    /// (6 × m); their D is [`State::modal_mass`].
    pub fn add_inertia<M: Dim>(&self, modes: M, rigid: &mut SpatialMat<S>, coupling: &mut DMatrix<S>) {
        if !self.present {
            return;
        }
        *rigid += inertia_of(self.mass, &self.first_moment, &self.second_moment);
        let (shape_moments, position_shape) =
            (leading(&self.shape_moments, U3, modes), leading(&self.position_shape, U9, modes));
        let mut coupling = leading_mut(coupling, U6, modes);
        for k in 0..modes.value() {
            let angular = axial_of(|e| position_shape[(e, k)]);
            for row in 0..3 {
                coupling[(row, k)] += angular[row];
                coupling[(row + 3, k)] += shape_moments[(row, k)];
            }
        }
    }

    /// The point masses' velocity-product force about R's origin (added to
    /// `p`) and on the modes (subtracted from `u`), R moving with `v_r`;
    /// keeps N, Cη̇ and U̇'s angular rows for [`State::add_inertia_rates`].
    pub fn add_bias<M: Dim>(&mut self, modes: M, rate: &[S], v_r: &SpatialVec<S>, p: &mut SpatialVec<S>, u: &mut [S]) {
        if !self.present {
            return;
        }
        let m = modes.value();
        let (rate, u) = (&rate[..m], &mut u[..m]);
        let (shape_moments, position_shape) =
            (leading(&self.shape_moments, U3, modes), leading(&self.position_shape, U9, modes));
        let (omega, v) = (angular(v_r), linear(v_r));
        let (c, s) = (&self.first_moment, &self.second_moment);
        let (mut shape_rate, mut n) = (Vec3::zeros(), SVector::<S, 9>::zeros());
        for k in 0..m {
            for r in 0..3 {
                shape_rate[r] += shape_moments[(r, k)] * rate[k];
            }
            for e in 0..9 {
                n[e] += position_shape[(e, k)] * rate[k];
            }
        }
        let n = Mat3::from_column_slice(n.as_slice()).transpose();
        let omega_v = omega.cross(&v);
        let force = omega.cross(&(v * self.mass + omega.cross(c) + shape_rate * S::from(2.0)));
        let moment = c.cross(&omega_v) - omega.cross(&(s * omega)) + (omega * n.trace() - n * omega) * S::from(2.0);
        *p += spatial(&moment, &force);
        let w2 = skew(&omega) * skew(&omega);
        let mut axial_rate = leading_mut(&mut self.axial_rate, U3, modes);
        for k in 0..m {
            let axial_shape_shape = leading(&self.shape_shape_axial[k], U3, modes);
            let mut a = Vec3::zeros();
            for l in 0..m {
                for r in 0..3 {
                    a[r] += axial_shape_shape[(r, l)] * rate[l];
                }
            }
            let mut on_mode = omega.dot(&a) * S::from(2.0);
            for r in 0..3 {
                on_mode += shape_moments[(r, k)] * omega_v[r];
                for col in 0..3 {
                    on_mode += w2[(r, col)] * position_shape[(at(col, r), k)];
                }
            }
            u[k] -= on_mode;
            axial_rate.column_mut(k).copy_from(&a);
        }
        (self.rate_moment, self.shape_rate) = (n, shape_rate);
    }

    /// Gravity `g` (R's axes) on the point masses: −f_ext about R's origin
    /// added to `p`, and the modal force added to `u`.
    pub fn add_gravity<M: Dim>(&self, modes: M, g: &Vec3<S>, p: &mut SpatialVec<S>, u: &mut [S]) {
        if !self.present {
            return;
        }
        *p -= spatial(&self.first_moment.cross(g), &(g * self.mass));
        let shape_moments = leading(&self.shape_moments, U3, modes);
        for (k, u) in u[..modes.value()].iter_mut().enumerate() {
            for r in 0..3 {
                *u += shape_moments[(r, k)] * g[r];
            }
        }
    }

    /// The rates along η̇ of 𝓘_RR (added to `rigid_rate`) and of U (added
    /// to `coupling_rate`, 6 × m), after [`State::add_bias`]; D's is zero.
    pub fn add_inertia_rates<M: Dim>(&self, modes: M, rigid_rate: &mut SpatialMat<S>, coupling_rate: &mut DMatrix<S>) {
        if !self.present {
            return;
        }
        let n = self.rate_moment;
        *rigid_rate += inertia_of(S::zero(), &self.shape_rate, &(n + n.transpose()));
        let axial_rate = leading(&self.axial_rate, U3, modes);
        let mut coupling_rate = leading_mut(coupling_rate, U6, modes);
        for k in 0..modes.value() {
            for row in 0..3 {
                coupling_rate[(row, k)] += axial_rate[(row, k)];
            }
        }
    }
}
