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
//!   uₖ = −(Cₖ·(ω × v) + tr((ω×)² Σ mⱼ pⱼΦⱼₖᵀ) + 2 Σₗ η̇ₗ tr((ω×) Tₗₖ));
//!
//! and their rates along η̇: Ṡ = N + Nᵀ, ċ = Cη̇, U̇'s column k = [Σₗ η̇ₗ Σ mⱼ Φⱼₗ × Φⱼₖ; 0],
//! Ḋ = 0. The cost is O(m²) whatever the number of such nodes (a finite-
//! element model's solid elements give only such nodes), and the sums are
//! exact: the same as taking the nodes one by one.

use serde::{Deserialize, Serialize};

use super::ModalBody;
use crate::math::{Mat3, Real, SpatialMat, SpatialVec, Vec3, angular, linear, real, skew, spatial};

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

/// The point masses' sums at the workspace's state, kept from pass to pass.
#[derive(Clone, Debug)]
pub struct Configuration<S: Real> {
    /// c = c₀ + Cη (pass 1).
    first_moment: Vec3<S>,
    /// S = Σ mⱼ pⱼpⱼᵀ (pass 1).
    second_moment: Mat3<S>,
    /// Σ mⱼ pⱼΦⱼₖᵀ = Qₖ + Σₗ ηₗTₗₖ per mode (pass 1).
    position_shape: Vec<Mat3<S>>,
    /// N = Σ mⱼ Φⱼη̇ pⱼᵀ (pass 3).
    rate_moment: Mat3<S>,
    /// Cη̇ (pass 3).
    shape_rate: Vec3<S>,
}

impl<S: Real> Configuration<S> {
    /// Buffers for `modes` modes.
    pub fn new(modes: usize) -> Self {
        Configuration {
            first_moment: Vec3::zeros(),
            second_moment: Mat3::zeros(),
            position_shape: vec![Mat3::zeros(); modes],
            rate_moment: Mat3::zeros(),
            shape_rate: Vec3::zeros(),
        }
    }
}

/// tr(a b) without forming the product.
fn trace_of_product<S: Real>(a: &Mat3<S>, b: &Mat3<S>) -> S {
    let mut t = S::zero();
    for i in 0..3 {
        for j in 0..3 {
            t += a[(i, j)] * b[(j, i)];
        }
    }
    t
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

    /// c, S and Σ mⱼ pⱼΦⱼₖᵀ at `eta` into `at`: with Y = Σ ηₖQₖ and
    /// Z = Σ ηₖ Σ mⱼ pⱼΦⱼₖᵀ = Y + Σ ηₖηₗTₗₖ, S = P₀ + Yᵀ + Z.
    pub fn configure<S: Real>(&self, eta: &[S], at: &mut Configuration<S>) {
        let m = self.modes();
        let mut c: Vec3<S> = real(&self.first_moment);
        let (mut y, mut z) = (Mat3::zeros(), Mat3::zeros());
        for k in 0..m {
            let q: Mat3<S> = real(&self.position_shape[k]);
            let position_shape = (0..m).fold(q, |a, l| a + self.shape_shape::<S>(l, k) * eta[l]);
            c += real::<S, 3, 1>(&self.shape_moments[k]) * eta[k];
            y += q * eta[k];
            z += position_shape * eta[k];
            at.position_shape[k] = position_shape;
        }
        at.first_moment = c;
        at.second_moment = real::<S, 3, 3>(&self.second_moment) + y.transpose() + z;
    }

    /// Adds the point masses' 𝓘_RR to `rigid`, their U to `coupling` (6 × m)
    /// and their D to `d` (upper triangle).
    pub fn add_inertia<S: Real>(
        &self,
        at: &Configuration<S>,
        rigid: &mut SpatialMat<S>,
        coupling: &mut nalgebra::DMatrix<S>,
        d: &mut nalgebra::DMatrix<S>,
    ) {
        if self.mass == 0.0 {
            return;
        }
        *rigid += inertia_of(S::from(self.mass), &at.first_moment, &at.second_moment);
        for k in 0..self.modes() {
            let angular = axial(&at.position_shape[k]);
            let linear: Vec3<S> = real(&self.shape_moments[k]);
            for row in 0..3 {
                coupling[(row, k)] += angular[row];
                coupling[(row + 3, k)] += linear[row];
            }
            for l in 0..=k {
                d[(l, k)] += self.shape_shape::<S>(l, k).trace();
            }
        }
    }

    /// The point masses' velocity-product force about R's origin (added to
    /// `p`) and on the modes (subtracted from `u`), R moving with `v_r`;
    /// keeps N and Cη̇ in `at` for [`PointMasses::add_inertia_rates`].
    pub fn add_bias<S: Real>(
        &self,
        at: &mut Configuration<S>,
        rate: &[S],
        v_r: &SpatialVec<S>,
        p: &mut SpatialVec<S>,
        u: &mut nalgebra::DVector<S>,
    ) {
        if self.mass == 0.0 {
            return;
        }
        let m = self.modes();
        let (omega, v) = (angular(v_r), linear(v_r));
        let (c, s) = (&at.first_moment, &at.second_moment);
        let shape_rate = (0..m).fold(Vec3::zeros(), |a, k| a + real::<S, 3, 1>(&self.shape_moments[k]) * rate[k]);
        let omega_v = omega.cross(&v);
        let force = omega.cross(&(v * S::from(self.mass) + omega.cross(c) + shape_rate * S::from(2.0)));
        let n = (0..m).fold(Mat3::zeros(), |n, k| n + at.position_shape[k].transpose() * rate[k]);
        let moment = c.cross(&omega_v) - omega.cross(&(s * omega)) + (omega * n.trace() - n * omega) * S::from(2.0);
        *p += spatial(&moment, &force);
        let (w, w2) = (skew(&omega), skew(&omega) * skew(&omega));
        for k in 0..m {
            let mut on_mode =
                real::<S, 3, 1>(&self.shape_moments[k]).dot(&omega_v) + trace_of_product(&w2, &at.position_shape[k]);
            for (l, rate_l) in rate.iter().enumerate() {
                on_mode += trace_of_product(&w, &self.shape_shape::<S>(l, k)) * (*rate_l * S::from(2.0));
            }
            u[k] -= on_mode;
        }
        (at.rate_moment, at.shape_rate) = (n, shape_rate);
    }

    /// Gravity `g` (R's axes) on the point masses: −f_ext about R's origin
    /// added to `p`, and the modal force added to `u`.
    pub fn add_gravity<S: Real>(
        &self,
        at: &Configuration<S>,
        g: &Vec3<S>,
        p: &mut SpatialVec<S>,
        u: &mut nalgebra::DVector<S>,
    ) {
        if self.mass == 0.0 {
            return;
        }
        *p -= spatial(&at.first_moment.cross(g), &(g * S::from(self.mass)));
        for k in 0..self.modes() {
            u[k] += real::<S, 3, 1>(&self.shape_moments[k]).dot(g);
        }
    }

    /// The rates along η̇ of 𝓘_RR (added to `rigid_rate`) and of U (added to
    /// `coupling_rate`), after [`PointMasses::add_bias`]; D's is zero.
    pub fn add_inertia_rates<S: Real>(
        &self,
        at: &Configuration<S>,
        rate: &[S],
        rigid_rate: &mut SpatialMat<S>,
        coupling_rate: &mut nalgebra::DMatrix<S>,
    ) {
        if self.mass == 0.0 {
            return;
        }
        let m = self.modes();
        let n = at.rate_moment;
        *rigid_rate += inertia_of(S::zero(), &at.shape_rate, &(n + n.transpose()));
        for k in 0..m {
            let angular = (0..m).fold(Vec3::zeros(), |a, l| a + axial(&self.shape_shape::<S>(l, k)) * rate[l]);
            for row in 0..3 {
                coupling_rate[(row, k)] += angular[row];
            }
        }
    }
}
