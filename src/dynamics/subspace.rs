//! The shape of each link's motion subspace S, which the passes specialize
//! on. Most MJCF hinges turn about a coordinate axis of their body through
//! its origin, a ball joint usually turns about the origin, and a free
//! joint's halves have S = [1 0]ᵀ and [0 1]ᵀ: S's columns are then columns
//! of the identity, and the products with S are rows or columns picked out,
//! with no multiplications (pass 0 places such a hinge with its rotation's
//! entries in place, kinematics.rs). The numbers are those of the full
//! products (their other terms are zeros times finite values, so each sum
//! is exact), and tests check the passes bit for bit against the general
//! ones: the shapes change speed only, 9 % of bus_arm7's time in the
//! native host. Passes 1 and 3 and the θ̈ pass are specialized; pass 2 is
//! not (its instances measured slower: one product per link is little to
//! save, and more code to lay out). The cross products with a joint's
//! velocity v_J = S θ̇ (pass 3's V⁺ × v_J and I^a (v_J ×), the θ̈ pass's
//! V⁺ × v_J) take only v_J's nonzero entries: 1.4k fewer instructions per
//! ν̇ on bus_arm7 (of 31k), 6.6k on chain60 (of 216k; callgrind, 2026-11-30).
//!
//! The passes are generic over `N` (the link's dofs) and `UNIT` (the row of
//! S where the identity's columns start, or [`GENERAL`] for any other S);
//! `by_subspace!` calls the instance of a link's shape.

use nalgebra::{SMatrix, SVector};

use super::cols;
use crate::math::{
    Real, SpatialMat, SpatialVec, Vec3, angular, cross_motion, linear, mul_cross_motion, owned, real, spatial,
};
use crate::model::MotionSubspace;

/// `UNIT` of a link whose S is not columns of the identity.
pub const GENERAL: usize = 6;

/// A link's S, by shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Subspace {
    /// One dof, S = e₀: a hinge about the x axis through the origin.
    AboutX,
    /// One dof, S = e₁: a hinge about the y axis through the origin.
    AboutY,
    /// One dof, S = e₂: a hinge about the z axis through the origin.
    AboutZ,
    /// Three dofs, S = [1 0]ᵀ: a ball joint about the origin.
    Rotation,
    /// Three dofs, S = [0 1]ᵀ: a free joint's translation.
    Translation,
    /// One dof, any other S (slides among them: rarer, and cheap anyway).
    General1,
    /// Three dofs, any other S.
    General3,
}

impl Subspace {
    /// The shape of the first `ndof` columns of `s`.
    pub fn of(s: &MotionSubspace, ndof: usize) -> Subspace {
        let identity_from =
            |row: usize, n: usize| (0..n).all(|c| (0..6).all(|r| s[(r, c)] == if r == row + c { 1.0 } else { 0.0 }));
        if ndof == 1 {
            let about = [Subspace::AboutX, Subspace::AboutY, Subspace::AboutZ];
            (0..3).find(|&row| identity_from(row, 1)).map_or(Subspace::General1, |row| about[row])
        } else if identity_from(0, 3) {
            Subspace::Rotation
        } else if identity_from(3, 3) {
            Subspace::Translation
        } else {
            Subspace::General3
        }
    }
}

/// `f(args)` or `f::<EXTRA...>(args)` calls `f::<N, UNIT, EXTRA...>(args)`
/// for a link's [`Subspace`].
macro_rules! by_subspace {
    ($shape:expr, $f:ident $(::<$($extra:ident),*>)? ($($arg:expr),* $(,)?)) => {{
        use $crate::dynamics::subspace::{GENERAL, Subspace};
        match $shape {
            Subspace::AboutX => $f::<_, 1, 0 $($(, $extra)*)?>($($arg),*),
            Subspace::AboutY => $f::<_, 1, 1 $($(, $extra)*)?>($($arg),*),
            Subspace::AboutZ => $f::<_, 1, 2 $($(, $extra)*)?>($($arg),*),
            Subspace::Rotation => $f::<_, 3, 0 $($(, $extra)*)?>($($arg),*),
            Subspace::Translation => $f::<_, 3, 3 $($(, $extra)*)?>($($arg),*),
            Subspace::General1 => $f::<_, 1, GENERAL $($(, $extra)*)?>($($arg),*),
            Subspace::General3 => $f::<_, 3, GENERAL $($(, $extra)*)?>($($arg),*),
        }
    }};
}
pub(crate) use by_subspace;

/// S x.
#[inline(always)]
pub(crate) fn s_times<S: Real, const N: usize, const UNIT: usize>(
    s: &MotionSubspace,
    x: &SVector<S, N>,
) -> SpatialVec<S> {
    if UNIT == GENERAL {
        real(&cols::<f64, N>(s)) * x
    } else {
        let mut out = SpatialVec::zeros();
        out.fixed_rows_mut::<N>(UNIT).copy_from(x);
        out
    }
}

/// v += S x (in place: a unit S adds into v's rows, with no vector of zeros
/// written and read back).
#[inline(always)]
pub(crate) fn add_s_times<S: Real, const N: usize, const UNIT: usize>(
    v: &mut SpatialVec<S>,
    s: &MotionSubspace,
    x: &SVector<S, N>,
) {
    if UNIT == GENERAL {
        *v += real(&cols::<f64, N>(s)) * x;
    } else {
        for k in 0..N {
            v[UNIT + k] += x[k];
        }
    }
}

/// Sᵀ f.
#[inline(always)]
pub(crate) fn s_transpose_times<S: Real, const N: usize, const UNIT: usize>(
    s: &MotionSubspace,
    f: &SpatialVec<S>,
) -> SVector<S, N> {
    if UNIT == GENERAL { real(&cols::<f64, N>(s)).transpose() * f } else { owned(f.fixed_rows::<N>(UNIT)) }
}

/// M S.
#[inline(always)]
pub(crate) fn times_s<S: Real, const N: usize, const UNIT: usize>(
    m: &SpatialMat<S>,
    s: &MotionSubspace,
) -> SMatrix<S, 6, N> {
    if UNIT == GENERAL { m * real(&cols::<f64, N>(s)) } else { owned(m.fixed_columns::<N>(UNIT)) }
}

/// Sᵀ M for M = U (6×N): the N×N block of its rows.
#[inline(always)]
pub(crate) fn s_transpose_times_columns<S: Real, const N: usize, const UNIT: usize>(
    s: &MotionSubspace,
    m: &SMatrix<S, 6, N>,
) -> SMatrix<S, N, N> {
    if UNIT == GENERAL { real(&cols::<f64, N>(s)).transpose() * m } else { owned(m.fixed_rows::<N>(UNIT)) }
}

/// a × m, with m the nonzero half of a unit S's S x (its angular half
/// for `UNIT` < 3, else its linear half): with one dof m = x₀ e_k, and of
/// the cross product's six products only the two with x₀ are taken (the
/// others are zeros, so the numbers are those of the full product).
#[inline(always)]
fn cross_half<S: Real, const N: usize, const UNIT: usize>(a: &Vec3<S>, x: &SVector<S, N>) -> Vec3<S> {
    if N == 1 {
        let k = UNIT % 3;
        let (i, j) = ((k + 1) % 3, (k + 2) % 3);
        let mut out = Vec3::zeros();
        out[i] = a[j] * x[0];
        out[j] = -(a[i] * x[0]);
        out
    } else {
        a.cross(&Vec3::new(x[0], x[1], x[2]))
    }
}

/// V × (S x), the motion cross product with a joint velocity: for a unit S,
/// [`cross_motion`] without its products with S x's zeros (the same numbers).
#[inline(always)]
pub(crate) fn cross_s_times<S: Real, const N: usize, const UNIT: usize>(
    v: &SpatialVec<S>,
    s: &MotionSubspace,
    x: &SVector<S, N>,
) -> SpatialVec<S> {
    if UNIT == GENERAL {
        return cross_motion(v, &s_times::<_, N, UNIT>(s, x));
    }
    let (w, v_linear) = (angular(v), linear(v));
    if UNIT < 3 {
        // S x = (m, 0): (ω × m, v × m).
        spatial(&cross_half::<_, N, UNIT>(&w, x), &cross_half::<_, N, UNIT>(&v_linear, x))
    } else {
        // S x = (0, m): (0, ω × m).
        spatial(&Vec3::zeros(), &cross_half::<_, N, UNIT>(&w, x))
    }
}

/// M (S x ×) for a 6×6 M: for a unit S, [`mul_cross_motion`] without its
/// products with S x's zeros (the same numbers).
#[inline(always)]
pub(crate) fn mul_cross_s_times<S: Real, const N: usize, const UNIT: usize>(
    m: &SpatialMat<S>,
    s: &MotionSubspace,
    x: &SVector<S, N>,
) -> SpatialMat<S> {
    if UNIT == GENERAL {
        return mul_cross_motion(m, &s_times::<_, N, UNIT>(s, x));
    }
    let mut out = SpatialMat::zeros();
    for row in 0..6 {
        let left = Vec3::new(m[(row, 0)], m[(row, 1)], m[(row, 2)]);
        let right = Vec3::new(m[(row, 3)], m[(row, 4)], m[(row, 5)]);
        // Row by row as mul_cross_motion: (left, right) (ω×, 0; v×, ω×).
        let (out_left, out_right) = if UNIT < 3 {
            (cross_half::<_, N, UNIT>(&left, x), cross_half::<_, N, UNIT>(&right, x))
        } else {
            (cross_half::<_, N, UNIT>(&right, x), Vec3::zeros())
        };
        for k in 0..3 {
            out[(row, k)] = out_left[k];
            out[(row, k + 3)] = out_right[k];
        }
    }
    out
}
