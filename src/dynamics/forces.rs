//! ε from physical forces and physical torques from ε (docs/DYNAMICS.md §5),
//! each one inward pass over the factor computed by pass 1.
//!
//! ε = ℓ(θ)(T + Jᵀf):  p_i = −f_i + Σ_children Xᵀ(p_c + G_c u_c),
//!                     u_i = T_i − S_iᵀ p_i,  ε_i = R_i⁻¹ u_i.
//! T = m(θ) ε:         u_i = R_i ε_i,  T_i = u_i + S_iᵀ p_i (same p).

use nalgebra::SVector;

use super::flexible::FlexState;
use super::subspace::{by_subspace, s_transpose_times};
use super::{DynamicsError, accumulate, block, check_input, check_length, cols, require};
use crate::math::{Real, SpatialVec, Transform, real};
use crate::model::Model;
use crate::workspace::{Accumulation, NodeParent, Stage, Workspace};

/// Which way the recursion runs.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Direction {
    /// `input` is T; write ε.
    EpsFromTorque,
    /// `input` is ε; write T.
    TorqueFromEps,
}

fn inward_link<S: Real, const N: usize, const UNIT: usize>(
    model: &Model,
    ws: &mut Workspace<S>,
    i: usize,
    direction: Direction,
    input: &[S],
    body_forces: Option<&[SpatialVec<S>]>,
    out: &mut [S],
) {
    let link = &model.links[i];
    let adr = link.dof_adr;
    let s = &link.motion_subspace;
    let mut p = body_forces.map_or(SpatialVec::zeros(), |f| -f[i]);
    if ws.accumulation[i].gathers() {
        p += ws.p_scratch_body[i];
    }
    let x: SVector<S, N> = SVector::from_column_slice(&input[adr..adr + N]);
    let (u, y) = match direction {
        Direction::EpsFromTorque => {
            let u = x - s_transpose_times::<_, N, UNIT>(s, &p);
            (u, block::<_, N>(&ws.r_inv_joint[i]) * u)
        }
        Direction::TorqueFromEps => {
            let u = block::<_, N>(&ws.r_joint[i]) * x;
            (u, u + s_transpose_times::<_, N, UNIT>(s, &p))
        }
    };
    out[adr..adr + N].copy_from_slice(y.as_slice());
    if let Some(parent) = link.parent {
        let p_reduced = p + cols::<_, N>(&ws.gain[i]) * u;
        let opens = ws.accumulation[i].opens_parent;
        match ws.accumulation[i].node {
            Some(at) => child_wrench(model, &mut ws.flex, at, &p_reduced, opens),
            None => {
                let to_parent = ws.x_parent[i].apply_transpose_force(&p_reduced);
                accumulate(&mut ws.p_scratch_body[parent], to_parent, opens);
            }
        }
    }
}

pub(super) fn inward_pass<S: Real>(
    model: &Model,
    ws: &mut Workspace<S>,
    direction: Direction,
    input: &[S],
    body_forces: Option<&[SpatialVec<S>]>,
    out: &mut [S],
) {
    let flexible = !model.flexible.is_empty();
    for i in (0..model.links.len()).rev() {
        if flexible {
            super::flexible::inward(model, ws, i, direction == Direction::TorqueFromEps, input, out);
        }
        by_subspace!(ws.subspaces[i], inward_link(model, ws, i, direction, input, body_forces, out));
    }
}

/// ε = ℓ(θ)T for joint torques `torque`, for passes that have just set the
/// configuration (no stage or length checks: the caller's buffers are the model's).
pub(super) fn eps_of_torque<S: Real>(model: &Model, ws: &mut Workspace<S>, torque: &[S], eps: &mut [S]) {
    inward_pass(model, ws, Direction::EpsFromTorque, torque, None, eps);
}

/// [`eps_of_torque`] for torques on few links, as a constraint row's
/// Jacobian is (a weld between two free bodies moves their dofs and those
/// of their ancestors only): a link none of whose subtree carries torque
/// has ε = 0 and hands nothing on, so its arithmetic is skipped. The
/// results are eps_of_torque's. Vehicles with flexible bodies, whose nodes
/// gather their children apart from the links, take the full pass.
/// Returns the dofs outside which ε is zero.
pub(super) fn eps_of_sparse_torque<S: Real>(
    model: &Model,
    ws: &mut Workspace<S>,
    torque: &[S],
    eps: &mut [S],
) -> (usize, usize) {
    if !model.flexible.is_empty() {
        eps_of_torque(model, ws, torque, eps);
        return (0, model.nv);
    }
    let mut span = (model.nv, 0);
    for i in (0..model.links.len()).rev() {
        let link = &model.links[i];
        let dofs = link.dof_adr..link.dof_adr + link.ndof;
        let accumulation = ws.accumulation[i];
        let carries = (accumulation.has_children && ws.subtree_carries[i])
            || torque[dofs.clone()].iter().any(|t| !t.is_still_zero());
        if let Some(parent) = link.parent {
            ws.subtree_carries[parent] = carries || (!accumulation.opens_parent && ws.subtree_carries[parent]);
            if !carries && accumulation.opens_parent {
                ws.p_scratch_body[parent] = SpatialVec::zeros();
            }
        }
        if !carries {
            eps[dofs].fill(S::zero());
            continue;
        }
        span = (span.0.min(dofs.start), span.1.max(dofs.end));
        by_subspace!(ws.subspaces[i], inward_link(model, ws, i, Direction::EpsFromTorque, torque, None, eps));
    }
    span
}

/// A child at a node hands wrench `f` (its frame) to the node's slot, in the node's frame.
fn child_wrench<S: Real>(model: &Model, flex: &mut [FlexState<S>], at: NodeParent, f: &SpatialVec<S>, opens: bool) {
    let (f_index, c, slot) = super::flexible::node_of(model, at);
    let state = &mut flex[f_index];
    accumulate(&mut state.child_scratch[slot], state.child_x[c].apply_transpose_force(f), opens);
}

/// T += Σ Jᵢᵀfᵢ, the joint forces of per-link wrenches `wrenches` (link
/// coordinates, about the link origin): p_i = f_i + Σ_children Xᵀ p_c,
/// T_i += S_iᵀ p_i; a node carrying children takes their p_c and gives
/// its modes Ψ_jᵀ p_j and its link X_jᵀ p_j. `p` holds each link's share
/// from its children (set by the first child the pass reaches, so it needs
/// no clearing).
pub(crate) fn add_joint_forces_of_wrenches<S: Real>(
    model: &Model,
    x_parent: &[Transform<S>],
    accumulation: &[Accumulation],
    flex: &mut [FlexState<S>],
    p: &mut [SpatialVec<S>],
    wrenches: &[SpatialVec<S>],
    torque: &mut [S],
) {
    let flexible = !model.flexible.is_empty();
    for i in (0..model.links.len()).rev() {
        let link = &model.links[i];
        if flexible {
            for f in super::flexible::on_link(model, i) {
                let (body, state) = (&model.flexible[f], &mut flex[f]);
                let mut on_link = SpatialVec::zeros();
                for r in (0..body.rotating.len()).filter(|&r| body.carries(r)) {
                    let p_node = state.child_scratch[r];
                    on_link += state.node_x[r].apply_transpose_force(&p_node);
                    for k in 0..body.mode_count() {
                        let column = SpatialVec::from_fn(|row, _| state.psi[r][(row, k)]);
                        torque[body.dof_adr + k] += column.dot(&p_node);
                    }
                }
                accumulate(&mut p[i], on_link, state.opens_link);
            }
        }
        let mut total = wrenches[i];
        if accumulation[i].gathers() {
            total += p[i];
        }
        for k in 0..link.ndof {
            torque[link.dof_adr + k] += real::<S, 6, 1>(&link.motion_subspace.column(k).into_owned()).dot(&total);
        }
        match (link.parent, accumulation[i].node) {
            (_, Some(at)) => child_wrench(model, flex, at, &total, accumulation[i].opens_parent),
            (Some(parent), None) => {
                accumulate(&mut p[parent], x_parent[i].apply_transpose_force(&total), accumulation[i].opens_parent)
            }
            (None, None) => {}
        }
    }
}

impl Workspace {
    /// ε = ℓ(θ)(T + Σ Jᵢᵀfᵢ) for joint torques `torque` (MuJoCo's
    /// qfrc_applied convention) and optional per-link wrenches `body_forces`
    /// (link coordinates, about the link origin). Needs the configuration.
    pub fn eps_from_forces(
        &mut self,
        model: &Model,
        torque: &[f64],
        body_forces: Option<&[SpatialVec]>,
        eps: &mut [f64],
    ) -> Result<(), DynamicsError> {
        require(self, Stage::Configuration, "eps_from_forces")?;
        check_input("torque", torque, model.nv)?;
        check_length("output", eps, model.nv)?;
        if let Some(f) = body_forces
            && f.len() != model.links.len()
        {
            return Err(DynamicsError::Length { what: "body_forces", expected: model.links.len(), found: f.len() });
        }
        inward_pass(model, self, Direction::EpsFromTorque, torque, body_forces, eps);
        Ok(())
    }

    /// T = m(θ) ε: the joint torques whose ε is `eps`. Needs the configuration.
    pub fn torque_from_eps(&mut self, model: &Model, eps: &[f64], torque: &mut [f64]) -> Result<(), DynamicsError> {
        require(self, Stage::Configuration, "torque_from_eps")?;
        check_input("eps", eps, model.nv)?;
        check_length("output", torque, model.nv)?;
        inward_pass(model, self, Direction::TorqueFromEps, eps, None, torque);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sparse pass gives the full pass's ε bit for bit, and zero
    /// outside the span it returns, for torque on each dof alone, on each
    /// pair of dofs and on all of them, on vehicles whose trees branch
    /// (the hand's two fingers, the arm's tool and sensor pod on the
    /// servicer), away from their file pose.
    #[test]
    fn the_sparse_pass_gives_the_full_pass_results() {
        for file in ["tests/fixtures/constraints/slider_hand.xml", "tests/fixtures/constraints/docked_servicer.xml"] {
            let (model, mut ws) = crate::dynamics::test_vehicle(file, 0.1);
            let nv = model.nv;
            let mut torques = vec![vec![1.0; nv]];
            for a in 0..nv {
                for b in a..nv {
                    let mut torque = vec![0.0; nv];
                    torque[a] = 1.0;
                    torque[b] -= 0.5;
                    torques.push(torque);
                }
            }
            let full: Vec<Vec<f64>> = (torques.iter())
                .map(|torque| {
                    let mut eps = vec![0.0; nv];
                    eps_of_torque(&model, &mut ws, torque, &mut eps);
                    eps
                })
                .collect();
            // One sparse pass after another, as the rows are formed: what one
            // leaves in the slots must not reach the next.
            let mut sparse = vec![f64::NAN; nv];
            let bits = |v: &[f64]| v.iter().map(|x| (x + 0.0).to_bits()).collect::<Vec<_>>();
            for (torque, full) in torques.iter().zip(&full) {
                let (first, end) = eps_of_sparse_torque(&model, &mut ws, torque, &mut sparse);
                assert_eq!(bits(&sparse), bits(full), "{file}, torque {torque:?}");
                assert!(
                    full.iter().enumerate().all(|(d, e)| (first..end).contains(&d) || *e == 0.0),
                    "{file}: {torque:?}"
                );
            }
        }
    }
}
