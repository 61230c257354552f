//! Pass 2, base to tip: velocities, and the maps between ν and θ̇
//! (docs/DYNAMICS.md §4 pass 2).
//!
//! V⁺_i = X V_λ,  w_i = θ̇_i + G_iᵀV⁺_i = R_i⁻ᵀ ν_i,  V_i = V⁺_i + S θ̇_i.
//! From ν this is θ̇ = ℓ*ν; from θ̇ it is ν = m*θ̇.

use nalgebra::SVector;

use super::{block, cols};
use crate::math::{Real, SpatialVec, owned, real};
use crate::model::Model;
use crate::workspace::Workspace;

/// Which of ν and θ̇ is given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Given {
    /// ν is in `ws.nu`; compute θ̇.
    Nu,
    /// θ̇ is in `ws.qvel`; compute ν.
    Qvel,
}

/// Pass 2 for one link with N dofs, whose V⁺ (its parent's V in its
/// frame) is `v_plus`; returns its V.
#[inline(always)]
fn velocity_link<S: Real, const N: usize>(
    model: &Model,
    ws: &mut Workspace<S>,
    i: usize,
    given: Given,
    v_plus: SpatialVec<S>,
) -> SpatialVec<S> {
    let link = &model.links[i];
    let adr = link.dof_adr;
    let gain_t = cols::<_, N>(&ws.gain[i]).transpose();
    let gv: SVector<S, N> = gain_t * v_plus;
    let (w, qvel) = match given {
        Given::Nu => {
            let nu: SVector<S, N> = owned(ws.nu.fixed_rows::<N>(adr));
            let w = block::<_, N>(&ws.r_inv_joint[i]).transpose() * nu;
            (w, w - gv)
        }
        Given::Qvel => {
            let qvel: SVector<S, N> = owned(ws.qvel.fixed_rows::<N>(adr));
            let w = qvel + gv;
            let nu = block::<_, N>(&ws.r_joint[i]).transpose() * w;
            ws.nu.fixed_rows_mut::<N>(adr).copy_from(&nu);
            (w, qvel)
        }
    };
    ws.qvel.fixed_rows_mut::<N>(adr).copy_from(&qvel);
    ws.w_joint.fixed_rows_mut::<N>(adr).copy_from(&w);
    ws.v_plus_body[i] = v_plus;
    let v = v_plus + real(&cols::<_, N>(&link.motion_subspace)) * qvel;
    ws.v_body[i] = v;
    v
}

/// Pass 2 over all links.
pub(crate) fn velocity_pass<S: Real>(model: &Model, ws: &mut Workspace<S>, given: Given) {
    if S::SPECIALIZED && model.flexible.is_empty() {
        velocity_sweep::<_, false>(model, ws, given);
    } else {
        velocity_sweep::<_, true>(model, ws, given);
    }
}

/// Pass 2's sweep; without `FLEXIBLE` (a vehicle without flexible bodies)
/// it has no modal blocks and no children at nodes to look for.
fn velocity_sweep<S: Real, const FLEXIBLE: bool>(model: &Model, ws: &mut Workspace<S>, given: Given) {
    // The previous link's V, handed over in registers when it is the
    // parent (as along a chain): read back from `v_body` right after its
    // store, its linear half straddles two of the store's 16-byte writes,
    // which stalls the load until they retire.
    let mut v_previous = SpatialVec::zeros();
    for i in 0..model.links.len() {
        let node = if FLEXIBLE { ws.accumulation[i].node } else { None };
        let v_plus = match (model.links[i].parent, node) {
            // A child at a node: the node's V_j, in the link's frame.
            (_, Some(at)) => super::flexible::child_velocity(model, ws, at),
            (Some(p), None) if p + 1 == i => ws.x_parent[i].apply_motion(&v_previous),
            (Some(p), None) => ws.x_parent[i].apply_motion(&ws.v_body[p]),
            (None, None) => SpatialVec::zeros(),
        };
        v_previous = match model.links[i].ndof {
            1 => velocity_link::<_, 1>(model, ws, i, given, v_plus),
            _ => velocity_link::<_, 3>(model, ws, i, given, v_plus),
        };
        if FLEXIBLE {
            super::flexible::velocities(model, ws, i, given == Given::Nu);
        }
    }
}
