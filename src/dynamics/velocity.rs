//! Pass 2, base to tip: velocities, and the maps between ν and θ̇
//! (docs/DYNAMICS.md §4 pass 2).
//!
//! V⁺_i = X V_λ,  w_i = θ̇_i + G_iᵀV⁺_i = R_i⁻ᵀ ν_i,  V_i = V⁺_i + S θ̇_i.
//! From ν this is θ̇ = ℓ*ν; from θ̇ it is ν = m*θ̇.

use nalgebra::SVector;

use super::{block, cols};
use crate::math::SpatialVec;
use crate::model::Model;
use crate::workspace::Workspace;

/// Which of ν and θ̇ is given.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Given {
    /// ν is in `ws.nu`; compute θ̇.
    Nu,
    /// θ̇ is in `ws.qvel`; compute ν.
    Qvel,
}

fn velocity_link<const N: usize>(model: &Model, ws: &mut Workspace, i: usize, given: Given) {
    let link = &model.links[i];
    let adr = link.dof_adr;
    let v_plus = match link.parent {
        Some(p) => ws.x_parent[i].apply_motion(&ws.v_body[p]),
        None => SpatialVec::zeros(),
    };
    let gain_t = cols::<N>(&ws.gain[i]).transpose();
    let gv: SVector<f64, N> = gain_t * v_plus;
    let (w, qvel) = match given {
        Given::Nu => {
            let nu: SVector<f64, N> = ws.nu.fixed_rows::<N>(adr).into_owned();
            let w = block::<N>(&ws.r_inv_joint[i]).transpose() * nu;
            (w, w - gv)
        }
        Given::Qvel => {
            let qvel: SVector<f64, N> = ws.qvel.fixed_rows::<N>(adr).into_owned();
            let w = qvel + gv;
            let nu = block::<N>(&ws.r_joint[i]).transpose() * w;
            ws.nu.fixed_rows_mut::<N>(adr).copy_from(&nu);
            (w, qvel)
        }
    };
    ws.qvel.fixed_rows_mut::<N>(adr).copy_from(&qvel);
    ws.w_joint.fixed_rows_mut::<N>(adr).copy_from(&w);
    ws.v_plus_body[i] = v_plus;
    ws.v_body[i] = v_plus + cols::<N>(&link.motion_subspace) * qvel;
}

/// Pass 2 over all links.
pub(crate) fn velocity_pass(model: &Model, ws: &mut Workspace, given: Given) {
    for i in 0..model.links.len() {
        match model.links[i].ndof {
            1 => velocity_link::<1>(model, ws, i, given),
            _ => velocity_link::<3>(model, ws, i, given),
        }
    }
}
