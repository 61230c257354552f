//! Xᵀ I X in the derivatives' dual numbers ([`Real::add_congruence`]), the
//! passes' largest cost in a directional derivative.
//!
//! The value and the derivative share the transform's values, so the
//! blockwise congruence runs once on (value, derivative) pairs with the
//! transform in `f64`: a dual number times an `f64` is two products, where
//! dual times dual is three and an add. The transform's own derivative
//! enters through the inertia's instead: any rate of a rigid transform is
//! Ẋ = −(v×) X, with v = (ω, E ṙ) in child coordinates and (ω×) = −Ė Eᵀ,
//! so d(Xᵀ I X) = Xᵀ (İ − I (v×) − (I (v×))ᵀ) X, the congruence of a
//! changed rate (I symmetric). About 1 400 instructions against 2 400 for
//! the blockwise congruence in dual arithmetic (bus_arm7, callgrind); the
//! values are the `f64` congruence's bits (the same products, summed in the
//! same order), and the derivative is exact to round-off (ω is read from
//! Ė Eᵀ's antisymmetric part, E a rotation to round-off).
//!
//! The blockwise steps are written again here on arrays of pairs rather than
//! shared with the `f64` congruence: one version generic over the entries,
//! instantiated for `f64`, took 2 % more instructions than nalgebra's there,
//! the passes' largest cost in ν̇.

use num_dual::Dual64;

use super::{Real, SpatialMat, Transform, Vec3};

/// A 3×3 block of an inertia, by rows.
type Block = [[Dual64; 3]; 3];

/// `slot` = Xᵀ I X (if `replace`) or `slot` += Xᵀ I X, as
/// [`Transform::add_inertia_to_parent`]; `inertia` symmetric, its
/// lower-left block not read.
#[inline(always)]
pub(super) fn add_dual_congruence(
    x: &Transform<Dual64>,
    inertia: &SpatialMat<Dual64>,
    slot: &mut SpatialMat<Dual64>,
    replace: bool,
) {
    let values = Transform { rot: x.rot.map(Real::value), trans: x.trans.map(Real::value) };
    let block = |row: usize, col: usize| -> Block {
        std::array::from_fn(|i| std::array::from_fn(|j| inertia[(row + i, col + j)]))
    };
    let (mut a, mut b, mut c) = (block(0, 0), block(0, 3), block(3, 3));
    let rot_rate = x.rot.map(|entry| entry.eps);
    let trans_rate = x.trans.map(|entry| entry.eps);
    if rot_rate.iter().chain(&trans_rate).any(|entry| *entry != 0.0) {
        let spin = rot_rate * values.rot.transpose();
        let omega =
            Vec3::new(spin[(1, 2)] - spin[(2, 1)], spin[(2, 0)] - spin[(0, 2)], spin[(0, 1)] - spin[(1, 0)]) * 0.5;
        // A hinge or ball about the child's origin leaves it still: no linear part.
        let linear = (trans_rate != Vec3::zeros()).then(|| values.rot * trans_rate);
        subtract_turning([&mut a, &mut b, &mut c], &omega, linear.as_ref());
    }
    let term = congruence(&values, &a, &b, &c);
    if replace {
        *slot = term;
    } else {
        *slot += term;
    }
}

/// The derivative parts of I's blocks A, B, C (I = [A B; Bᵀ C]) less those
/// of I (v×) + (I (v×))ᵀ for v = (ω, l), read from the values:
/// I (v×) = [A ω× + B l×, B ω×; Bᵀ ω× + C l×, C ω×], so its blocks are
/// S + Sᵀ with S = A ω× + B l×; B ω× − ω× B − l× C; and C ω× − ω× C.
fn subtract_turning([a, b, c]: [&mut Block; 3], omega: &Vec3, linear: Option<&Vec3>) {
    let value = |m: &Block| -> [[f64; 3]; 3] { std::array::from_fn(|i| std::array::from_fn(|j| m[i][j].re)) };
    let (a_value, b_value, c_value) = (value(a), value(b), value(c));
    let b_transposed: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| b_value[j][i]));
    // Row i of m (v×) is row i of m crossed with v.
    let times_cross = |m: &[[f64; 3]; 3], v: &Vec3| -> [[f64; 3]; 3] {
        m.map(|row| [row[1] * v[2] - row[2] * v[1], row[2] * v[0] - row[0] * v[2], row[0] * v[1] - row[1] * v[0]])
    };
    // S = A ω× (+ B l×), and the upper-right block's B ω× − ω× B (− l× C).
    let mut s = times_cross(&a_value, omega);
    let (b_omega, bt_omega) = (times_cross(&b_value, omega), times_cross(&b_transposed, omega));
    let mut upper_right: [[f64; 3]; 3] =
        std::array::from_fn(|i| std::array::from_fn(|j| b_omega[i][j] + bt_omega[j][i]));
    if let Some(linear) = linear {
        let (b_linear, c_linear) = (times_cross(&b_value, linear), times_cross(&c_value, linear));
        for i in 0..3 {
            for j in 0..3 {
                s[i][j] += b_linear[i][j];
                upper_right[i][j] += c_linear[j][i];
            }
        }
    }
    let c_omega = times_cross(&c_value, omega);
    for i in 0..3 {
        for j in 0..3 {
            // ω× B = −(Bᵀ ω×)ᵀ and l× C = −(C l×)ᵀ, C symmetric.
            a[i][j].eps -= s[i][j] + s[j][i];
            b[i][j].eps -= upper_right[i][j];
            c[i][j].eps -= c_omega[i][j] + c_omega[j][i];
        }
    }
}

/// Xᵀ I X by blocks, as [`Transform::add_inertia_to_parent`] forms it
/// (its notes say how), the blocks in dual numbers and X in `f64`.
#[inline(always)]
fn congruence(x: &Transform, a: &Block, b: &Block, c: &Block) -> SpatialMat<Dual64> {
    let e = &x.rot;
    // (Eᵀ M) E, each entry summed in order.
    let rotate = |m: &Block| -> Block {
        let left: Block = std::array::from_fn(|i| {
            std::array::from_fn(|j| m[0][j] * e[(0, i)] + m[1][j] * e[(1, i)] + m[2][j] * e[(2, i)])
        });
        std::array::from_fn(|i| {
            std::array::from_fn(|j| left[i][0] * e[(0, j)] + left[i][1] * e[(1, j)] + left[i][2] * e[(2, j)])
        })
    };
    let symmetric =
        |m: &Block| -> Block { std::array::from_fn(|i| std::array::from_fn(|j| (m[i][j] + m[j][i]) * 0.5)) };
    let (a, b, c) = (rotate(a), rotate(b), symmetric(&rotate(c)));
    let r = &x.trans;
    // r × u, and u × r.
    let cross = |u: [Dual64; 3]| [u[2] * r[1] - u[1] * r[2], u[0] * r[2] - u[2] * r[0], u[1] * r[0] - u[0] * r[1]];
    let cross_right =
        |u: [Dual64; 3]| [u[1] * r[2] - u[2] * r[1], u[2] * r[0] - u[0] * r[2], u[0] * r[1] - u[1] * r[0]];
    let column = |m: &Block, j: usize| [m[0][j], m[1][j], m[2][j]];
    // r×C′ and r×B′ᵀ by columns (column j of r×B′ᵀ is r × row j of B′),
    // then the rows of (r×C′)(r×).
    let r_c_columns = [cross(column(&c, 0)), cross(column(&c, 1)), cross(column(&c, 2))];
    let r_bt_columns = [cross(b[0]), cross(b[1]), cross(b[2])];
    let r_c: Block = std::array::from_fn(|i| std::array::from_fn(|j| r_c_columns[j][i]));
    let r_bt: Block = std::array::from_fn(|i| std::array::from_fn(|j| r_bt_columns[j][i]));
    let r_c_r = [cross_right(r_c[0]), cross_right(r_c[1]), cross_right(r_c[2])];
    let b_parent: Block = std::array::from_fn(|i| std::array::from_fn(|j| b[i][j] + r_c[i][j]));
    let a_parent =
        symmetric(&std::array::from_fn(|i| std::array::from_fn(|j| a[i][j] + r_bt[i][j] + r_bt[j][i] - r_c_r[i][j])));
    SpatialMat::from_fn(|i, j| match (i < 3, j < 3) {
        (true, true) => a_parent[i][j],
        (true, false) => b_parent[i][j - 3],
        (false, true) => b_parent[j][i - 3],
        (false, false) => c[i - 3][j - 3],
    })
}
