//! Pass 0: link placements from θ (MuJoCo's kinematics), link by link
//! within pass 1, then the world placements base to tip when needed.
//!
//! Joint transforms follow MuJoCo: a hinge or ball rotates the body about
//! its anchor, F_j = F_{j−1} · T(r) · Rot · T(−r); a slide translates along
//! its axis by θ − ref; the translation half of a free joint places the
//! body origin at θ[0..3] in world axes.

use nalgebra::{Rotation3, Unit};

use super::DynamicsError;
use crate::math::{Mat3, Real, Transform, Vec3, normalize_wxyz, quat_from_wxyz, real};
use crate::model::{Link, LinkJoint, Model};
use crate::workspace::Workspace;

/// ⁱX_F: the link frame relative to its joint's inboard frame, for `theta`.
/// Quaternions are normalized in `theta` (as MuJoCo does). Inlined into
/// pass 1, which would otherwise take the transform back through memory.
#[inline]
pub fn joint_transform<S: Real>(link: &Link, theta: &mut [S]) -> Result<Transform<S>, DynamicsError> {
    let q = &mut theta[link.qpos_adr..];
    let (axis, anchor) = (real::<S, 3, 1>(&link.axis), real::<S, 3, 1>(&link.anchor));
    let rotate_about_anchor = |rot: Mat3<S>| Transform::from_pose(&rot, &(anchor - rot * anchor));
    Ok(match link.joint {
        LinkJoint::Hinge => {
            let angle = q[0] - link.reference;
            // At angle 0 nalgebra gives a constant identity, whose derivative
            // is wrong; there the rotation is written as its first-order
            // term, I + [u]× angle, which is the identity in f64 as nalgebra's is.
            let rot = if angle.value() == 0.0 {
                Mat3::identity() + axis.cross_matrix() * angle
            } else {
                Rotation3::from_axis_angle(&Unit::new_unchecked(axis), angle).into_inner()
            };
            rotate_about_anchor(rot)
        }
        LinkJoint::Slide => Transform::from_pose(&Mat3::identity(), &(axis * (q[0] - link.reference))),
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
pub(crate) fn place_link<S: Real, const N: usize, const UNIT: usize>(
    model: &Model,
    ws: &mut Workspace<S>,
    i: usize,
) -> Result<(), DynamicsError> {
    let link = &model.links[i];
    let x_joint = if N == 1 && UNIT < 3 {
        let (sin, cos) = (ws.theta[link.qpos_adr] - link.reference).sin_cos();
        let (a, b) = ((UNIT + 1) % 3, (UNIT + 2) % 3);
        let mut rot = Mat3::identity();
        // 0 ± sin: the signed zeros of nalgebra's formula at θ = 0 too.
        (rot[(a, a)], rot[(a, b)], rot[(b, a)], rot[(b, b)]) = (cos, S::zero() - sin, S::zero() + sin, cos);
        Transform::from_pose(&rot, &Vec3::zeros())
    } else {
        joint_transform(link, ws.theta.as_mut_slice())?
    };
    ws.x_parent[i] = x_joint.compose(&link.x_tree.real());
    Ok(())
}

impl<S: Real> Workspace<S> {
    /// ⁱX₀ of every link for the current configuration, computed now if
    /// pass 0 skipped them (a model without gravity).
    pub fn world_transforms(&mut self, model: &Model) -> &[Transform<S>] {
        if !self.world_transforms_current {
            world_transforms_pass(model, self);
        }
        &self.x_world
    }
}

/// ⁱX₀ = ⁱX_λ · ᵝX₀, base to tip, from `x_parent`.
pub(crate) fn world_transforms_pass<S: Real>(model: &Model, ws: &mut Workspace<S>) {
    for (i, link) in model.links.iter().enumerate() {
        ws.x_world[i] = match link.parent {
            Some(p) => ws.x_parent[i].compose(&ws.x_world[p]),
            None => ws.x_parent[i],
        };
    }
    ws.world_transforms_current = true;
}
