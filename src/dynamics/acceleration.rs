//! Outward pass after pass 3, base to tip: θ̈ (MuJoCo's qacc) and the links'
//! spatial accelerations, for the acceleration sensors (docs/DYNAMICS.md §5).
//!
//! Pass 3 gives ν̇_i = R_i⁻¹u_i + (Ṙ_iᵀw_i + R_iᵀĠ_iᵀV⁺_i) with u_i the
//! joint term of the whole force recursion, and stores ν̇ without the
//! bracket (`nu_dot_joint`, which pass 3 can also give alone, without the
//! factor's rates). The articulated-body algorithm's joint equation then
//! gives θ̈ without another inward pass:
//!
//!   θ̈_i = D_i⁻¹u_i − G_iᵀ(X A_λ + c_i) = R_i⁻ᵀ nu_dot_joint_i − G_iᵀ(X A_λ + c_i),
//!   A_i = X A_λ + c_i + S_i θ̈_i,   c_i = V⁺_i × S_i θ̇_i.

use nalgebra::SVector;

use super::subspace::{add_s_times, by_subspace, cross_s_times};
use super::{DynamicsError, block, cols, require};
use crate::math::{Real, SpatialVec, owned};
use crate::model::Model;
use crate::workspace::{Stage, Workspace};

/// The outward pass for one link with N dofs, whose parent's A in its
/// frame is `a_plus`; returns its A.
#[inline(always)]
fn acceleration_link<S: Real, const N: usize, const UNIT: usize>(
    model: &Model,
    ws: &mut Workspace<S>,
    i: usize,
    a_plus: SpatialVec<S>,
) -> SpatialVec<S> {
    let link = &model.links[i];
    let adr = link.dof_adr;
    let s = &link.motion_subspace;
    let qvel: SVector<S, N> = owned(ws.qvel.fixed_rows::<N>(adr));
    let a_passed = a_plus + cross_s_times::<_, N, UNIT>(&ws.v_plus_body[i], s, &qvel);
    let joint_term: SVector<S, N> = owned(ws.nu_dot_joint.fixed_rows::<N>(adr));
    let qacc =
        block::<_, N>(&ws.r_inv_joint[i]).transpose() * joint_term - cols::<_, N>(&ws.gain[i]).transpose() * a_passed;
    ws.qacc.fixed_rows_mut::<N>(adr).copy_from(&qacc);
    let mut a = a_passed;
    add_s_times::<_, N, UNIT>(&mut a, s, &qacc);
    ws.a_body[i] = a;
    a
}

impl<S: Real> Workspace<S> {
    /// θ̈ (`qacc`) and the link accelerations (`a_body`) for the inputs of
    /// the last pass 3 (with or without the factor's rates). Needs pass 3.
    pub fn compute_accelerations(&mut self, model: &Model) -> Result<(), DynamicsError> {
        require(self, Stage::JointRates, "compute_accelerations")?;
        if S::SPECIALIZED && model.flexible.is_empty() {
            acceleration_sweep::<_, false>(model, self);
        } else {
            acceleration_sweep::<_, true>(model, self);
        }
        Ok(())
    }
}

/// The outward sweep; without `FLEXIBLE` (a vehicle without flexible
/// bodies) it has no modal blocks and no children at nodes to look for.
fn acceleration_sweep<S: Real, const FLEXIBLE: bool>(model: &Model, ws: &mut Workspace<S>) {
    // The parent's A in registers when it is the previous link, as pass 2 hands over V.
    let mut a_previous = SpatialVec::zeros();
    for i in 0..model.links.len() {
        let node = if FLEXIBLE { ws.accumulation[i].node } else { None };
        let a_plus = match (model.links[i].parent, node) {
            // A child at a node: the node's A_j, in the link's frame.
            (_, Some(at)) => super::flexible::child_acceleration(model, ws, at),
            (Some(p), None) if p + 1 == i => ws.x_parent[i].apply_motion(&a_previous),
            (Some(p), None) => ws.x_parent[i].apply_motion(&ws.a_body[p]),
            (None, None) => SpatialVec::zeros(),
        };
        a_previous = by_subspace!(ws.subspaces[i], acceleration_link(model, ws, i, a_plus));
        if FLEXIBLE {
            super::flexible::accelerations(model, ws, i);
        }
    }
}
