//! MuJoCo's gravity compensation, `qfrc_gravcomp` (docs/DYNAMICS.md §5):
//! on each compensated link the wrench −(h_c × g, m_c g) (g in link
//! coordinates, m_c and h_c its compensated mass and mass moment), turned
//! into joint forces by one inward pass, T_i = S_iᵀ Σ_subtree f. It
//! depends on θ alone, so it is computed with the configuration, before
//! the actuators (which take the share of `actuatorgravcomp` joints) and
//! pass 3 (which takes the rest as a passive force).

use super::forces;
use crate::math::{Real, real, spatial};
use crate::model::Model;
use crate::workspace::Workspace;

/// Fills `qfrc_gravcomp`. Only the compensated links' wrenches are written:
/// the others stay zero from the workspace's creation.
pub(crate) fn gravity_compensation_pass<S: Real>(model: &Model, ws: &mut Workspace<S>) {
    ws.world_transforms(model);
    for compensated in &model.gravity_compensation.links {
        let g_link = ws.x_world[compensated.link].rot * real::<S, 3, 1>(&model.gravity);
        ws.gravcomp_wrench[compensated.link] =
            -spatial(&real::<S, 3, 1>(&compensated.mass_moment).cross(&g_link), &(g_link * S::from(compensated.mass)));
    }
    ws.qfrc_gravcomp.fill(S::zero());
    forces::add_joint_forces_of_wrenches(
        model,
        &ws.x_parent,
        &ws.accumulation,
        &mut ws.flex,
        &mut ws.p_scratch_body,
        &ws.gravcomp_wrench,
        ws.qfrc_gravcomp.as_mut_slice(),
    );
}
