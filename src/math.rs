//! Fixed-size spatial algebra (Featherstone's notation).
//!
//! Spatial vectors are ordered **(angular, linear)** everywhere in nudyn:
//! a motion vector is (ω, v) with v the velocity of the frame's origin, a
//! force vector is (n, f) with n the moment about the frame's origin.
//!
//! Every helper but the congruence (`Transform::add_inertia_to_parent`,
//! which says why) is `#[inline]`: the passes call them per link from other
//! codegen units, and out of line they cost a fifth of a ν̇ (bus_arm7
//! 3.30 → 2.70 µs with them inlined, criterion).

use std::borrow::Borrow;
use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

use nalgebra::{
    Const, DMatrix, Dim, Dyn, Matrix, Matrix3, MatrixView, MatrixViewMut, RealField, SMatrix, SVector, Scalar, Storage,
    U1, UnitQuaternion, Vector3,
};
use num_dual::Dual64;
use serde::{Deserialize, Serialize};

mod dual_congruence;

/// The scalar the passes compute in: `f64`, or a dual number that carries
/// a directional derivative through the same code (`dynamics::derivatives`).
/// Branches (a joint limit, a zero quaternion) decide on [`Real::value`].
/// The operations with `f64` let the model's constants enter without
/// conversion; for `f64` every one of them is the plain operation, so the
/// passes' numbers do not change by being generic.
pub trait Real:
    RealField
    + Copy
    + From<f64>
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Div<f64, Output = Self>
    + AddAssign<f64>
    + SubAssign<f64>
    + MulAssign<f64>
    + DivAssign<f64>
    + Neg<Output = Self>
{
    /// The number without its derivative.
    fn value(self) -> f64;

    /// Whether the number and its derivative are both zero: a term that
    /// may be skipped (a force zero in value can still move).
    fn is_still_zero(self) -> bool;

    /// Whether the passes run in their specialized instances (sweeps of
    /// their own for vehicles without flexible bodies, the modal blocks at
    /// fixed sizes): f64's, the evaluations' hot path. The dual numbers of
    /// the derivatives take the general instances alone, which keeps the
    /// FMU's code from doubling them (4.98 against 5.22 MB).
    const SPECIALIZED: bool;

    /// `slot` = Xᵀ I X (if `replace`) or `slot` += Xᵀ I X,
    /// [`Transform::add_inertia_to_parent`]: by blocks in the scalar's own
    /// arithmetic for `f64`, and for dual numbers on (value, derivative)
    /// pairs with the transform in `f64` (dual_congruence.rs).
    fn add_congruence(x: &Transform<Self>, inertia: &SpatialMat<Self>, slot: &mut SpatialMat<Self>, replace: bool);

    /// atan2(self, x), the angle of the point (x, self), whose derivative
    /// is (x ẏ − y ẋ) / (x² + y²) wherever the point is not the origin.
    /// The generic code takes this where atan2 is smooth, not
    /// `RealField::atan2`: num-dual's differentiates atan(y/x), which is NaN
    /// at x = 0 (a side site straight below a cylinder's axis) and where x²
    /// underflows.
    fn atan2_differentiable(self, x: Self) -> Self;
}

impl Real for f64 {
    const SPECIALIZED: bool = true;

    #[inline(always)]
    fn atan2_differentiable(self, x: f64) -> f64 {
        self.atan2(x)
    }

    /// The blockwise congruence itself ([`Transform::add_inertia_to_parent`]
    /// forms it in place for `f64` and calls this for the other scalars only).
    #[inline(always)]
    fn add_congruence(x: &Transform, inertia: &SpatialMat, slot: &mut SpatialMat, replace: bool) {
        x.add_inertia_to_parent(inertia, slot, replace);
    }

    #[inline(always)]
    fn value(self) -> f64 {
        self
    }

    #[inline(always)]
    fn is_still_zero(self) -> bool {
        self == 0.0
    }
}

impl Real for Dual64 {
    const SPECIALIZED: bool = false;

    #[inline]
    fn atan2_differentiable(self, x: Dual64) -> Dual64 {
        let squared_radius = x.re * x.re + self.re * self.re;
        Dual64::new(self.re.atan2(x.re), (x.re * self.eps - self.re * x.eps) / squared_radius)
    }

    #[inline(always)]
    fn add_congruence(x: &Transform<Self>, inertia: &SpatialMat<Self>, slot: &mut SpatialMat<Self>, replace: bool) {
        dual_congruence::add_dual_congruence(x, inertia, slot, replace);
    }

    #[inline(always)]
    fn value(self) -> f64 {
        self.re
    }

    #[inline(always)]
    fn is_still_zero(self) -> bool {
        self.re == 0.0 && self.eps == 0.0
    }
}

/// The sum of `terms`, as `f64`'s `Sum` adds (from −0.0, in order), so
/// that generic code keeps the plain code's `f64` numbers.
#[inline]
pub fn sum<S: Real>(terms: impl Iterator<Item = S>) -> S {
    terms.fold(S::from(-0.0), |total, term| total + term)
}

/// a · b of two slices of equal length (plain buffers, no nalgebra view),
/// summed as [`sum`] does.
#[inline]
pub fn dot<S: Real>(a: &[S], b: &[S]) -> S {
    sum(a.iter().zip(b).map(|(x, y)| *x * *y))
}

/// A 3-vector.
pub type Vec3<S = f64> = Vector3<S>;
/// A 3×3 matrix.
pub type Mat3<S = f64> = Matrix3<S>;

/// a b for 3×3 matrices, each entry summed in nalgebra's order (so f64
/// results are the same bits): written out because nalgebra's generic
/// product was a call per product in dual numbers, 40 % of a directional
/// derivative's instructions, and slower in f64 too (chain60's ν̇ 14.5 →
/// 11.6 µs with pass 1's congruence written out).
#[inline(always)]
pub fn mat3_product<S: Real>(a: &Mat3<S>, b: &Mat3<S>) -> Mat3<S> {
    let entry = |i: usize, j: usize| a[(i, 0)] * b[(0, j)] + a[(i, 1)] * b[(1, j)] + a[(i, 2)] * b[(2, j)];
    Mat3::new(
        entry(0, 0),
        entry(0, 1),
        entry(0, 2),
        entry(1, 0),
        entry(1, 1),
        entry(1, 2),
        entry(2, 0),
        entry(2, 1),
        entry(2, 2),
    )
}

/// a b for small fixed-size matrices, written out (each entry summed as
/// nalgebra sums it): nalgebra's generic product is a call per product in
/// dual numbers, about a sixth of a directional derivative's instructions on
/// bus_arm7 in passes 1 and 3's per-link products. The passes take it
/// through `times!` for dual numbers only.
#[inline(always)]
pub fn product<S: Real, const R: usize, const K: usize, const C: usize>(
    a: impl Borrow<SMatrix<S, R, K>>,
    b: impl Borrow<SMatrix<S, K, C>>,
) -> SMatrix<S, R, C> {
    let (a, b) = (a.borrow(), b.borrow());
    SMatrix::from_fn(|i, j| (1..K).fold(a[(i, 0)] * b[(0, j)], |sum, k| sum + a[(i, k)] * b[(k, j)]))
}

/// `a * b` in the passes' scalar `S` (in scope where it is used): as
/// written in `f64`, whose code and bits it keeps, and by [`product`] in
/// dual numbers.
macro_rules! times {
    ($a:expr, $b:expr) => {
        if S::SPECIALIZED { $a * $b } else { $crate::math::product($a, $b) }
    };
}
pub(crate) use times;

/// A unit quaternion (MuJoCo order w, x, y, z when read from or written to qpos).
pub type Quat<S = f64> = UnitQuaternion<S>;
/// A spatial motion or force vector, (angular, linear).
pub type SpatialVec<S = f64> = SVector<S, 6>;
/// A 6×6 spatial matrix (inertias, transforms, cross-product operators).
pub type SpatialMat<S = f64> = SMatrix<S, 6, 6>;

/// A model constant (an `f64` matrix) in the passes' scalar.
#[inline(always)]
pub fn real<S: Real, const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> SMatrix<S, R, C> {
    m.map(S::from)
}

/// The cross-product matrix: `skew(a) * b == a.cross(&b)`.
#[inline]
pub fn skew<S: Real>(a: &Vec3<S>) -> Mat3<S> {
    let zero = S::zero();
    Mat3::new(zero, -a.z, a.y, a.z, zero, -a.x, -a.y, a.x, zero)
}

/// The leading `rows` × `cols` block of a buffer. With sizes known at
/// compile time (`Const`), the loops over the view unroll and its bounds
/// checks fold away; `Dyn` sizes give the same code for any size.
#[inline(always)]
pub fn leading<S: Real, R: Dim, C: Dim>(m: &DMatrix<S>, rows: R, cols: C) -> MatrixView<'_, S, R, C, U1, Dyn> {
    m.generic_view((0, 0), (rows, cols))
}

/// [`leading`], mutable.
#[inline(always)]
pub fn leading_mut<S: Real, R: Dim, C: Dim>(
    m: &mut DMatrix<S>,
    rows: R,
    cols: C,
) -> MatrixViewMut<'_, S, R, C, U1, Dyn> {
    m.generic_view_mut((0, 0), (rows, cols))
}

/// A fixed-size view copied out entry by entry. nalgebra's `into_owned`
/// of a view fills the matrix from an iterator, which the compiler leaves
/// out of line in some passes (it cost bus_arm7's pass 2 about 1.1k of a
/// ν̇'s 32k instructions, callgrind).
#[inline(always)]
pub fn owned<T: Scalar + Copy, const R: usize, const C: usize, St: Storage<T, Const<R>, Const<C>>>(
    view: Matrix<T, Const<R>, Const<C>, St>,
) -> SMatrix<T, R, C> {
    SMatrix::from_fn(|r, c| view[(r, c)])
}

/// Angular part of a spatial vector.
#[inline]
pub fn angular<S: Real>(v: &SpatialVec<S>) -> Vec3<S> {
    owned(v.fixed_rows::<3>(0))
}

/// Linear part of a spatial vector.
#[inline]
pub fn linear<S: Real>(v: &SpatialVec<S>) -> Vec3<S> {
    owned(v.fixed_rows::<3>(3))
}

/// Joins an angular and a linear part.
#[inline]
pub fn spatial<S: Real>(angular: &Vec3<S>, linear: &Vec3<S>) -> SpatialVec<S> {
    SpatialVec::new(angular.x, angular.y, angular.z, linear.x, linear.y, linear.z)
}

/// Motion cross product `v × m`.
#[inline]
pub fn cross_motion<S: Real>(v: &SpatialVec<S>, m: &SpatialVec<S>) -> SpatialVec<S> {
    let (w, vl) = (angular(v), linear(v));
    let (mw, ml) = (angular(m), linear(m));
    spatial(&w.cross(&mw), &(w.cross(&ml) + vl.cross(&mw)))
}

/// Force cross product `v ×* f`.
#[inline]
pub fn cross_force<S: Real>(v: &SpatialVec<S>, f: &SpatialVec<S>) -> SpatialVec<S> {
    let (w, vl) = (angular(v), linear(v));
    let (n, fl) = (angular(f), linear(f));
    spatial(&(w.cross(&n) + vl.cross(&fl)), &w.cross(&fl))
}

/// The matrix of `v ×` acting on motion vectors.
#[inline]
pub fn cross_motion_matrix<S: Real>(v: &SpatialVec<S>) -> SpatialMat<S> {
    let (w, vl) = (skew(&angular(v)), skew(&linear(v)));
    let mut out = SpatialMat::zeros();
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&w);
    out.fixed_view_mut::<3, 3>(3, 0).copy_from(&vl);
    out.fixed_view_mut::<3, 3>(3, 3).copy_from(&w);
    out
}

/// `m · (v ×)` for a 6×6 `m`, row by row: (v ×) = [ω× 0; v× ω×], and a
/// row vector times a skew matrix is a cross product, (xᵀ a×) = (x × a)ᵀ;
/// so each row costs three cross products instead of 3×3 products with
/// skew matrices (half of whose entries are zero).
#[inline]
pub fn mul_cross_motion<S: Real>(m: &SpatialMat<S>, v: &SpatialVec<S>) -> SpatialMat<S> {
    let (w, vl) = (angular(v), linear(v));
    let mut out = SpatialMat::zeros();
    for row in 0..6 {
        let left = Vec3::new(m[(row, 0)], m[(row, 1)], m[(row, 2)]);
        let right = Vec3::new(m[(row, 3)], m[(row, 4)], m[(row, 5)]);
        let out_left = left.cross(&w) + right.cross(&vl);
        let out_right = right.cross(&w);
        for k in 0..3 {
            out[(row, k)] = out_left[k];
            out[(row, k + 3)] = out_right[k];
        }
    }
    out
}

/// The spatial inertia, about the frame origin, of a rigid body with mass
/// `mass`, centre of mass `com` and inertia `inertia_com` about the centre of mass.
#[inline]
pub fn rigid_inertia(mass: f64, com: &Vec3, inertia_com: &Mat3) -> SpatialMat {
    let c = skew(com);
    let mut out = SpatialMat::zeros();
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&(inertia_com + mass * c * c.transpose()));
    out.fixed_view_mut::<3, 3>(0, 3).copy_from(&(mass * c));
    out.fixed_view_mut::<3, 3>(3, 0).copy_from(&(mass * c.transpose()));
    out.fixed_view_mut::<3, 3>(3, 3).copy_from(&(mass * Mat3::identity()));
    out
}

/// A Plücker transform ᶜX_ₚ from a parent frame p to a child frame c.
///
/// `rot` (E) maps parent coordinates to child coordinates; `trans` (r) is
/// the child origin in parent coordinates. As a motion transform
/// X = [E 0; −E r× E].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Transform<S: Real = f64> {
    /// E: parent → child coordinates.
    pub rot: Mat3<S>,
    /// r: child origin in parent coordinates.
    pub trans: Vec3<S>,
}

impl<S: Real> Default for Transform<S> {
    fn default() -> Self {
        Self::identity()
    }
}

impl Transform {
    /// This (model) transform in the passes' scalar.
    #[inline(always)]
    pub fn real<S: Real>(&self) -> Transform<S> {
        Transform { rot: real(&self.rot), trans: real(&self.trans) }
    }
}

impl<S: Real> Transform<S> {
    /// The identity transform.
    #[inline]
    pub fn identity() -> Self {
        Self { rot: Mat3::identity(), trans: Vec3::zeros() }
    }

    /// The transform to a child frame whose axes are `child_to_parent` (its
    /// columns are the child axes in parent coordinates) and whose origin is
    /// `origin` in parent coordinates.
    #[inline]
    pub fn from_pose(child_to_parent: &Mat3<S>, origin: &Vec3<S>) -> Self {
        Self { rot: child_to_parent.transpose(), trans: *origin }
    }

    /// ᶜX_ₐ = ᶜX_b · ᵇX_ₐ, with `self` = ᶜX_b and `inner` = ᵇX_ₐ.
    #[inline]
    pub fn compose(&self, inner: &Transform<S>) -> Transform<S> {
        Transform { rot: mat3_product(&self.rot, &inner.rot), trans: inner.trans + inner.rot.transpose() * self.trans }
    }

    /// X m: a parent-frame motion vector in child coordinates.
    #[inline]
    pub fn apply_motion(&self, m: &SpatialVec<S>) -> SpatialVec<S> {
        let w = angular(m);
        let v = linear(m) - self.trans.cross(&w);
        spatial(&(self.rot * w), &(self.rot * v))
    }

    /// X⁻¹ m: a child-frame motion vector in parent coordinates.
    #[inline]
    pub fn apply_inverse_motion(&self, m: &SpatialVec<S>) -> SpatialVec<S> {
        let w = self.rot.transpose() * angular(m);
        spatial(&w, &(self.rot.transpose() * linear(m) + self.trans.cross(&w)))
    }

    /// Xᵀ f: a child-frame force vector in parent coordinates.
    #[inline]
    pub fn apply_transpose_force(&self, f: &SpatialVec<S>) -> SpatialVec<S> {
        let n = self.rot.transpose() * angular(f);
        let fl = self.rot.transpose() * linear(f);
        spatial(&(n + self.trans.cross(&fl)), &fl)
    }

    /// The 6×6 motion-transform matrix X.
    #[inline]
    pub fn motion_matrix(&self) -> SpatialMat<S> {
        let mut out = SpatialMat::zeros();
        out.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.rot);
        out.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-self.rot * skew(&self.trans)));
        out.fixed_view_mut::<3, 3>(3, 3).copy_from(&self.rot);
        out
    }

    /// `slot` = Xᵀ I X (if `replace`) or `slot` += Xᵀ I X: a child-frame
    /// inertia (or its derivative) in parent coordinates. The term is
    /// assembled whole and added to the slot in one 6×6 operation: the
    /// parent reads the slot right after (the next link of a chain), and a
    /// slot written block by block, each block's columns half a 6-column,
    /// is read back by loads that straddle two writes and wait for them.
    ///
    /// `inertia` must be symmetric, [A B; Bᵀ C] in (angular, linear)
    /// blocks; its lower-left block is not read. By blocks rather than as
    /// 6×6 products (this congruence is the passes' largest cost): with
    /// X = diag(E, E)·[1 0; −r× 1], first A′ = EᵀAE, B′ = EᵀBE, C′ = EᵀCE,
    /// then Xᵀ I X = [A′ + r×B′ᵀ + (r×B′ᵀ)ᵀ − r×C′r×,  B′ + r×C′;  ·,  C′].
    /// The products with r× are cross products, which round as the 3×3
    /// products with the skew matrix do (the same two terms, summed in the
    /// same order) without multiplying its three zeros.
    ///
    /// The term is exactly symmetric (its diagonal blocks are symmetrized): the
    /// passes accumulate these along the tree, and formulas that rely on
    /// symmetry would let a round-off asymmetry grow link by link.
    ///
    /// Unlike the other helpers it is kept out of line, a call with its
    /// operands in memory: with only its 3×3 rotations out of line, as the
    /// compiler chose before, every example's ν̇ took 2–8 % longer than now
    /// (2026-11-30, side by side), and a variant inlined whole into the
    /// passes' link functions made chain60's pass 3 about twice as slow
    /// (the link function's values and the congruence's compete for the registers).
    ///
    /// The dual numbers of the derivatives take it apart instead
    /// ([`Real::add_congruence`]).
    #[inline(never)]
    pub fn add_inertia_to_parent(&self, inertia: &SpatialMat<S>, slot: &mut SpatialMat<S>, replace: bool) {
        if !S::SPECIALIZED {
            return S::add_congruence(self, inertia, slot, replace);
        }
        let (e, e_t) = (self.rot, self.rot.transpose());
        let symmetric = |m: Mat3<S>| (m + m.transpose()) * S::from(0.5);
        let rotate = |row: usize, col: usize| {
            mat3_product(&mat3_product(&e_t, &inertia.fixed_view::<3, 3>(row, col).into_owned()), &e)
        };
        let (a, b, c) = (rotate(0, 0), rotate(0, 3), symmetric(rotate(3, 3)));
        let r = &self.trans;
        // r×C′ column by column; r×B′ᵀ has column j = r × (row j of B′);
        // row i of (r×C′)(r×) is (row i of r×C′) × r, as xᵀ(r×) = (x × r)ᵀ.
        let r_c = Mat3::from_columns(&[r.cross(&c.column(0)), r.cross(&c.column(1)), r.cross(&c.column(2))]);
        let r_bt = Mat3::from_columns(&[
            r.cross(&b.row(0).transpose()),
            r.cross(&b.row(1).transpose()),
            r.cross(&b.row(2).transpose()),
        ]);
        let r_c_r = Mat3::from_rows(&[
            r_c.row(0).transpose().cross(r).transpose(),
            r_c.row(1).transpose().cross(r).transpose(),
            r_c.row(2).transpose().cross(r).transpose(),
        ]);
        let b_parent = b + r_c;
        let a_parent = symmetric(a + r_bt + r_bt.transpose() - r_c_r);
        let mut term = SpatialMat::zeros();
        for (row, col, block) in [(0, 0, a_parent), (0, 3, b_parent), (3, 0, b_parent.transpose()), (3, 3, c)] {
            term.fixed_view_mut::<3, 3>(row, col).copy_from(&block);
        }
        if replace {
            *slot = term;
        } else {
            *slot += term;
        }
    }
}

/// Quaternion from MuJoCo's (w, x, y, z) order, not normalized.
#[inline]
pub fn quat_from_wxyz<S: Real>(q: &[S]) -> nalgebra::Quaternion<S> {
    nalgebra::Quaternion::new(q[0], q[1], q[2], q[3])
}

/// The unit quaternion of the turn by the rotation vector `rho`, exp(ρ/2).
/// nalgebra's `from_scaled_axis` is a constant identity for |ρ/2| ≤ ε, which
/// in dual numbers loses the derivative at ρ = 0 (a flexible body's modes at
/// rest); there its first-order form (1, ρ/2), the identity to within ε², keeps it.
#[inline]
pub fn quat_from_rotation_vector<S: Real>(rho: Vec3<S>) -> Quat<S> {
    let half = rho * S::from(0.5);
    if half.norm_squared().value() <= f64::EPSILON * f64::EPSILON {
        Quat::new_unchecked(nalgebra::Quaternion::from_parts(S::one(), half))
    } else {
        Quat::from_scaled_axis(rho)
    }
}

/// Scales the (w, x, y, z) quaternion `q[..4]` to unit length in place and
/// returns its norm before; `None`, and `q` untouched, when it is zero.
///
/// Any finite non-zero quaternion comes out a unit one to rounding, as
/// `hypot` would give it: when the squares underflow (components near
/// 1e-160) or overflow (near 1e160), the components are first divided by
/// the largest one. The common case pays one range check.
#[inline]
pub fn normalize_wxyz<S: Real>(q: &mut [S]) -> Option<S> {
    let q = &mut q[..4];
    // nalgebra's order of summation: trajectories that round-off decides keep the
    // bits they were measured with (tests/all/adaptive_integration.rs).
    let squared = quat_from_wxyz(q).norm_squared();
    if (1e-290..=1e290).contains(&squared.value()) {
        let norm = squared.sqrt();
        q.iter_mut().for_each(|c| *c /= norm);
        return Some(norm);
    }
    let largest = q.iter().fold(S::zero(), |m, c| m.max(c.abs()));
    if largest.value() == 0.0 || !largest.value().is_finite() {
        return None;
    }
    q.iter_mut().for_each(|c| *c /= largest);
    // f64's `sum` starts from −0; from +0 the sum of squares (never −0) is the same.
    let scaled_norm = q.iter().fold(S::zero(), |sum, c| sum + *c * *c).sqrt();
    q.iter_mut().for_each(|c| *c /= scaled_norm);
    Some(largest * scaled_norm)
}

/// The unit quaternion along the (w, x, y, z) quaternion `q`, scaled as
/// [`normalize_wxyz`] does; `None` when `q` is zero.
#[inline]
pub fn unit_quat_from_wxyz(q: &[f64]) -> Option<Quat> {
    let mut unit = [q[0], q[1], q[2], q[3]];
    normalize_wxyz(&mut unit)?;
    Some(Quat::new_unchecked(quat_from_wxyz(&unit)))
}

/// Writes a quaternion in MuJoCo's (w, x, y, z) order.
#[inline]
pub fn quat_to_wxyz(q: &Quat, out: &mut [f64]) {
    out[0] = q.w;
    out[1] = q.i;
    out[2] = q.j;
    out[3] = q.k;
}

/// The rotation vector of `qa ⊖ qb`: the local-frame rotation r with
/// qa = qb · exp(r) (MuJoCo's `mju_subQuat`), taking the shorter way round.
///
/// At qa = qb nalgebra's `scaled_axis` gives a constant zero, whose
/// derivative is wrong (r's is 2 × the vector part's); there r is written
/// as that first-order term, 2v/w, which is +0 in f64 as nalgebra's zero is.
#[inline]
pub fn quat_difference<S: Real>(qa: &Quat<S>, qb: &Quat<S>) -> Vec3<S> {
    let mut d = qb.inverse() * qa;
    if d.w.value() < 0.0 {
        d = Quat::new_unchecked(-d.into_inner());
    }
    if d.imag().iter().all(|c| c.value() == 0.0) {
        return Vec3::zeros() + d.imag() * (S::from(2.0) / d.w);
    }
    d.scaled_axis()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// atan2's derivative in dual numbers against central differences of
    /// f64's atan2, at points on and beside the y axis (num-dual's own gives
    /// NaN on it and, along x, where x² underflows) and off it, in every quadrant
    /// clear of the cut along the negative x axis.
    #[test]
    fn atan2_is_differentiable_wherever_it_is_smooth() {
        let points =
            [(0.0, -0.08), (-0.0, 0.3), (1e-170, -0.08), (-1e-170, 2.0), (0.3, 0.4), (-0.7, 0.2), (-0.5, -1e-3)];
        for (x, y) in points {
            for (dx, dy) in [(1.0, 0.0), (0.0, 1.0), (0.6, -0.8)] {
                let exact = Dual64::new(y, dy).atan2_differentiable(Dual64::new(x, dx));
                let at = |h: f64| (y + h * dy).atan2(x + h * dx);
                let central = |h: f64| (at(h) - at(-h)) / (2.0 * h);
                let differenced = (4.0 * central(5e-5) - central(1e-4)) / 3.0;
                assert_eq!(exact.re, y.atan2(x), "({x}, {y})");
                assert!(
                    (exact.eps - differenced).abs() < 1e-8 * (1.0 + differenced.abs()),
                    "({x}, {y}) along ({dx}, {dy}): {} against {differenced}",
                    exact.eps
                );
            }
        }
    }

    #[test]
    fn quaternions_normalize_exactly_at_any_finite_scale() {
        let direction = [0.3, -0.5, 0.7, 0.1];
        let norm = direction.iter().map(|c: &f64| c * c).sum::<f64>().sqrt();
        let expected = direction.map(|c| c / norm);
        // Powers of two scale exactly, except that at 2^-1050 the components are
        // subnormal and keep only about 20 bits (the result can be no better).
        for exponent in [-1050, -1000, -530, -10, 0, 10, 520, 1000, 1020] {
            // In two factors: 2^-1050 alone would be computed as 1/2^1050 = 0.
            let scale = 2f64.powi(exponent / 2) * 2f64.powi(exponent - exponent / 2);
            let mut q = direction.map(|c| c * scale);
            let before = normalize_wxyz(&mut q).unwrap();
            let digits = if exponent < -1020 { 1e-5 } else { 1e-15 };
            assert!((before / (norm * scale) - 1.0).abs() < digits, "2^{exponent}: norm {before:e}");
            for (got, want) in q.iter().zip(&expected) {
                assert!((got - want).abs() < digits, "2^{exponent}: {q:?}");
            }
            assert!((q.iter().map(|c| c * c).sum::<f64>() - 1.0).abs() < 4e-16, "2^{exponent}: {q:?}");
        }
        let mut huge = [f64::MAX; 4];
        normalize_wxyz(&mut huge).unwrap();
        assert_eq!(huge, [0.5; 4]);
        let mut zero = [0.0, -0.0, 0.0, 0.0];
        assert_eq!(normalize_wxyz(&mut zero), None);
        assert_eq!(zero, [0.0, -0.0, 0.0, 0.0]);
    }

    /// A random-looking but fixed symmetric 6×6 matrix and transform.
    fn sample() -> (SpatialMat, Transform, SpatialVec) {
        let m =
            SpatialMat::from_fn(|i, j| ((i * 7 + j * 3) as f64 * 0.37).sin() + ((j * 7 + i * 3) as f64 * 0.37).sin());
        let rot = nalgebra::Rotation3::from_euler_angles(0.3, -1.1, 2.0).into_inner();
        let x = Transform { rot, trans: Vec3::new(0.4, -0.2, 0.9) };
        (m, x, SpatialVec::new(0.5, -0.3, 0.8, 1.2, 0.1, -0.7))
    }

    #[test]
    fn blockwise_congruence_equals_the_dense_product() {
        let (m, x, _) = sample();
        let dense = x.motion_matrix().transpose() * m * x.motion_matrix();
        // Replacing overwrites whatever the slot held.
        let mut slot = SpatialMat::from_element(7.0);
        x.add_inertia_to_parent(&m, &mut slot, true);
        assert!((slot - dense).abs().max() < 1e-13);
    }

    #[test]
    fn adding_into_a_slot_adds_the_dense_congruence() {
        let (m, x, _) = sample();
        let dense = x.motion_matrix().transpose() * m * x.motion_matrix();
        let mut slot = m;
        x.add_inertia_to_parent(&m, &mut slot, false);
        assert!((slot - (m + dense)).abs().max() < 1e-13);
    }

    /// In dual numbers, with the transform still, turning, and turning and
    /// moving, against the dense product in dual arithmetic; into an empty
    /// slot and added to one. The values are the f64 congruence's, bit for bit.
    #[test]
    fn dual_congruences_equal_the_dense_product_still_or_moving() {
        let (m, x, _) = sample();
        let rate = SpatialMat::from_fn(|i, j| ((i * 5 + j * 5) as f64 * 0.21).cos() + (i + j) as f64 * 0.1);
        let inertia = m.zip_map(&rate, Dual64::new);
        // A turn's rate, Ė = −(ω×) E.
        let turning = -skew(&Vec3::new(0.7, -0.4, 1.1)) * x.rot;
        // Still; turning about the child's origin; turning and moving it.
        for (turn, shift) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)] {
            let moving = (turn, shift);
            let x = Transform {
                rot: x.rot.zip_map(&turning, |value, rate| Dual64::new(value, turn * rate)),
                trans: x.trans.map(|value| Dual64::new(value, shift * (value - 0.3))),
            };
            let dense = x.motion_matrix().transpose() * inertia * x.motion_matrix();
            for replace in [true, false] {
                let mut slot = if replace { SpatialMat::from_element(Dual64::new(7.0, 3.0)) } else { inertia };
                let mut values = slot.map(|entry| entry.re);
                x.add_inertia_to_parent(&inertia, &mut slot, replace);
                let real_x = Transform { rot: x.rot.map(|entry| entry.re), trans: x.trans.map(|entry| entry.re) };
                real_x.add_inertia_to_parent(&inertia.map(|entry| entry.re), &mut values, replace);
                assert_eq!(slot.map(|entry| entry.re), values, "moving {moving:?}, replace {replace}");
                let expected = if replace { dense } else { inertia + dense };
                for (got, want) in slot.iter().zip(&expected) {
                    assert!((got.re - want.re).abs() < 1e-13, "moving {moving:?}, replace {replace}: {got} {want}");
                    assert!((got.eps - want.eps).abs() < 1e-13, "moving {moving:?}, replace {replace}: {got} {want}");
                }
            }
        }
    }

    #[test]
    fn blockwise_cross_product_equals_the_dense_product() {
        let (m, _, v) = sample();
        assert!((mul_cross_motion(&m, &v) - m * cross_motion_matrix(&v)).abs().max() < 1e-14);
    }
}
