//! Pass 1, tip to base (θ only): articulated-body inertias and the
//! innovations factor (docs/DYNAMICS.md §3, §4 pass 1).
//!
//! I^A_i = I_i + Σ_children Xᵀ I^a_c X,  U = I^A S,  D = SᵀU + armature,
//! D = R Rᵀ with R upper triangular,  G = U D⁻¹,  I^a = I^A − G Uᵀ.

use nalgebra::{Dim, Matrix, SMatrix, Storage, StorageMut};

use super::subspace::{by_subspace, s_transpose_times_columns, times_s};
use super::{DynamicsError, kinematics};
use crate::math::{Mat3, Real, SpatialMat, times};
use crate::model::Model;
use crate::workspace::Workspace;

/// The upper-triangular R with R Rᵀ = D and a positive diagonal (the
/// "reverse" Cholesky factor), or `None` if D is not positive definite.
/// Written by hand: nalgebra's Cholesky gives the lower factor L Lᵀ, and
/// the unique factor m of docs/DYNAMICS.md §3 needs this one.
pub fn upper_cholesky<S: Real, const N: usize>(d: &SMatrix<S, N, N>) -> Option<SMatrix<S, N, N>> {
    let mut r = SMatrix::<S, N, N>::zeros();
    upper_cholesky_into(d, &mut r).then_some(r)
}

/// [`upper_cholesky`] into `r` (any square size, a flexible body's modal
/// block too); false if `d` is not positive definite.
pub fn upper_cholesky_into<S: Real, D: Dim, A: Storage<S, D, D>, B: StorageMut<S, D, D>>(
    d: &Matrix<S, D, D, A>,
    r: &mut Matrix<S, D, D, B>,
) -> bool {
    let n = d.nrows();
    r.fill(S::zero());
    for j in (0..n).rev() {
        let mut diag = d[(j, j)];
        for k in j + 1..n {
            diag -= r[(j, k)] * r[(j, k)];
        }
        // Also refuses NaN, which `diag <= 0.0` would let through.
        if diag.value().partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return false;
        }
        let rjj = diag.sqrt();
        r[(j, j)] = rjj;
        for i in 0..j {
            let mut s = d[(i, j)];
            for k in j + 1..n {
                s -= r[(i, k)] * r[(j, k)];
            }
            r[(i, j)] = s / rjj;
        }
    }
    true
}

/// Inverse of an upper-triangular matrix with a nonzero diagonal.
pub fn upper_triangular_inverse<S: Real, const N: usize>(r: &SMatrix<S, N, N>) -> SMatrix<S, N, N> {
    let mut inv = SMatrix::<S, N, N>::zeros();
    upper_triangular_inverse_into(r, &mut inv);
    inv
}

/// [`upper_triangular_inverse`] into `inv` (any square size).
pub fn upper_triangular_inverse_into<S: Real, D: Dim, A: Storage<S, D, D>, B: StorageMut<S, D, D>>(
    r: &Matrix<S, D, D, A>,
    inv: &mut Matrix<S, D, D, B>,
) {
    let n = r.nrows();
    inv.fill(S::zero());
    for j in 0..n {
        inv[(j, j)] = S::one() / r[(j, j)];
        for i in (0..j).rev() {
            let mut s = S::zero();
            for k in i + 1..=j {
                s += r[(i, k)] * inv[(k, j)];
            }
            inv[(i, j)] = -s / r[(i, i)];
        }
    }
}

/// Pass 1 for one link with N dofs; `ia_reduced[i]` holds its children's share of I^A.
#[inline(always)]
fn factor_link<S: Real, const N: usize, const UNIT: usize>(
    model: &Model,
    ws: &mut Workspace<S>,
    i: usize,
) -> Result<(), DynamicsError> {
    let link = &model.links[i];
    let mut ia = if ws.accumulation[i].gathers() { ws.ia_reduced[i] } else { SpatialMat::zeros() };
    link.add_spatial_inertia_to(&mut ia);
    let u = times_s::<_, N, UNIT>(&ia, &link.motion_subspace);
    let mut d = s_transpose_times_columns::<_, N, UNIT>(&link.motion_subspace, &u);
    if !model.shortcuts.no_armature {
        d += SMatrix::<S, N, N>::identity() * S::from(link.armature);
    }
    let (r, r_inv, d_inv) = if N == 1 {
        // A hinge or slide: D⁻¹ straight from D, so that the gain (on the
        // pass's critical path) does not wait for the square root.
        let d = d[(0, 0)];
        if d.value().partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return Err(DynamicsError::Singular { link: i });
        }
        let (root, d_inv) = (d.sqrt(), S::one() / d);
        (SMatrix::from_element(root), SMatrix::from_element(root * d_inv), SMatrix::from_element(d_inv))
    } else {
        let r = upper_cholesky(&d).ok_or(DynamicsError::Singular { link: i })?;
        let r_inv = upper_triangular_inverse(&r);
        let d_inv = times!(r_inv.transpose(), r_inv);
        (r, r_inv, d_inv)
    };
    let gain = times!(u, d_inv);
    // Only a parent takes in I^a (passes 1 and 3); a base link has none.
    if link.parent.is_some() {
        ws.ia_reduced[i] = ia - times!(gain, u.transpose());
    }
    ws.gain[i].fixed_columns_mut::<N>(0).copy_from(&gain);
    write_block(&mut ws.r_joint[i], &r);
    write_block(&mut ws.r_inv_joint[i], &r_inv);
    Ok(())
}

/// Passes 0 and 1 for link `i`.
#[inline(always)]
fn place_and_factor_link<S: Real, const N: usize, const UNIT: usize>(
    model: &Model,
    ws: &mut Workspace<S>,
    i: usize,
) -> Result<(), DynamicsError> {
    kinematics::place_link::<_, N, UNIT>(model, ws, i)?;
    factor_link::<_, N, UNIT>(model, ws, i)
}

/// Stores an N×N block in the top-left of a 3×3 buffer.
fn write_block<S: Real, const N: usize>(out: &mut Mat3<S>, m: &SMatrix<S, N, N>) {
    out.fixed_view_mut::<N, N>(0, 0).copy_from(m);
}

/// Passes 0 and 1: each link's placement, then I^a, G, R, R⁻¹ for it
/// (I^A, U and D are intermediates).
pub(crate) fn articulated_pass<S: Real>(model: &Model, ws: &mut Workspace<S>) -> Result<(), DynamicsError> {
    if S::SPECIALIZED && model.flexible.is_empty() {
        articulated_sweep::<_, false>(model, ws)
    } else {
        articulated_sweep::<_, true>(model, ws)
    }
}

/// Passes 0 and 1's sweep; without `FLEXIBLE` (a vehicle without flexible
/// bodies) it has no modal blocks and no children at nodes to look for.
fn articulated_sweep<S: Real, const FLEXIBLE: bool>(model: &Model, ws: &mut Workspace<S>) -> Result<(), DynamicsError> {
    for i in (0..model.links.len()).rev() {
        if FLEXIBLE {
            super::flexible::factor_modes(model, ws, i)?;
        }
        by_subspace!(ws.subspaces[i], place_and_factor_link(model, ws, i))?;
        let node = if FLEXIBLE { ws.accumulation[i].node } else { None };
        if let Some(at) = node {
            super::flexible::place_child(model, ws, i, at);
        } else if let Some(p) = model.links[i].parent {
            // Parents precede their children in the link order (p < i).
            let (parents, children) = ws.ia_reduced.split_at_mut(i);
            ws.x_parent[i].add_inertia_to_parent(&children[0], &mut parents[p], ws.accumulation[i].opens_parent);
        }
    }
    Ok(())
}
