//! Pass 0: link placements from θ (MuJoCo's kinematics), link by link
//! within pass 1, then the world placements base to tip when needed.
//!
//! Joint transforms follow MuJoCo: a hinge or ball rotates the body about
//! its anchor, F_j = F_{j−1} · T(r) · Rot · T(−r); a slide translates along
//! its axis by θ − ref; the translation half of a free joint places the
//! body origin at θ[0..3] in world axes.

use nalgebra::{Rotation3, Unit};

use super::DynamicsError;
use crate::math::{Mat3, Transform, Vec3, normalize_wxyz, quat_from_wxyz};
use crate::model::{Link, LinkJoint, Model};
use crate::workspace::Workspace;

/// ⁱX_F: the link frame relative to its joint's inboard frame, for `theta`.
/// Quaternions are normalized in `theta` (as MuJoCo does). Inlined into
/// pass 1, which would otherwise take the transform back through memory.
#[inline]
pub fn joint_transform(link: &Link, theta: &mut [f64]) -> Result<Transform, DynamicsError> {
    let q = &mut theta[link.qpos_adr..];
    let rotate_about_anchor = |rot: Mat3| Transform::from_pose(&rot, &(link.anchor - rot * link.anchor));
    Ok(match link.joint {
        LinkJoint::Hinge => {
            let angle = q[0] - link.reference;
            rotate_about_anchor(Rotation3::from_axis_angle(&Unit::new_unchecked(link.axis), angle).into_inner())
        }
        LinkJoint::Slide => Transform::from_pose(&Mat3::identity(), &(link.axis * (q[0] - link.reference))),
        LinkJoint::Ball => {
            if normalize_wxyz(q).is_none() {
                return Err(DynamicsError::ZeroQuaternion { joint: link.joint_name.clone(), qpos_adr: link.qpos_adr });
            }
            let unit = nalgebra::UnitQuaternion::new_unchecked(quat_from_wxyz(q));
            rotate_about_anchor(unit.to_rotation_matrix().into_inner())
        }
        LinkJoint::Translation => Transform::from_pose(&Mat3::identity(), &Vec3::new(q[0], q[1], q[2])),
    })
}

/// Pass 0 for link `i`: its `x_parent` for the configuration in `ws.theta`.
/// A link's placement depends on its own joint only, so pass 1 calls this
/// as it reaches each link instead of sweeping the links once more (on long
/// chains every sweep streams the model and workspace through the cache).
///
/// A hinge about a coordinate axis through the link origin (`UNIT` < 3
/// with one dof, subspace.rs) is a rotation with cos θ and ± sin θ in
/// place: the entries nalgebra's axis-angle formula gives for that axis,
/// without its products (bit for bit).
#[inline(always)]
pub(crate) fn place_link<const N: usize, const UNIT: usize>(
    model: &Model,
    ws: &mut Workspace,
    i: usize,
) -> Result<(), DynamicsError> {
    let link = &model.links[i];
    let x_joint = if N == 1 && UNIT < 3 {
        let (sin, cos) = (ws.theta[link.qpos_adr] - link.reference).sin_cos();
        let (a, b) = ((UNIT + 1) % 3, (UNIT + 2) % 3);
        let mut rot = Mat3::identity();
        // 0 ± sin: the signed zeros of nalgebra's formula at θ = 0 too.
        (rot[(a, a)], rot[(a, b)], rot[(b, a)], rot[(b, b)]) = (cos, 0.0 - sin, 0.0 + sin, cos);
        Transform::from_pose(&rot, &Vec3::zeros())
    } else {
        joint_transform(link, ws.theta.as_mut_slice())?
    };
    ws.x_parent[i] = x_joint.compose(&link.x_tree);
    Ok(())
}

impl Workspace {
    /// ⁱX₀ of every link for the current configuration, computed now if
    /// pass 0 skipped them (a model without gravity).
    pub fn world_transforms(&mut self, model: &Model) -> &[Transform] {
        if !self.world_transforms_current {
            world_transforms_pass(model, self);
        }
        &self.x_world
    }
}

/// ⁱX₀ = ⁱX_λ · ᵝX₀, base to tip, from `x_parent`.
pub(crate) fn world_transforms_pass(model: &Model, ws: &mut Workspace) {
    for (i, link) in model.links.iter().enumerate() {
        ws.x_world[i] = match link.parent {
            Some(p) => ws.x_parent[i].compose(&ws.x_world[p]),
            None => ws.x_parent[i],
        };
    }
    ws.world_transforms_current = true;
}
