//! MuJoCo's invweights at qpos0 (`dof_invweight0`, `body_invweight0`): the
//! inverse inertia a dof or a body sees, which scale the springdampers'
//! stiffness and the constraints' regularizer.

use crate::dynamics::DynamicsError;
use crate::math::{SpatialVec, Vec3, spatial};
use crate::model::{Attachment, JointInfo, Model};
use crate::vehicle::{JointKind, Vehicle};
use crate::workspace::Workspace;

/// MuJoCo's smallest component of an axis that counts as nonzero (mjEPS).
const AXIS_EPSILON: f64 = 1e-14;

/// MuJoCo's `dof_invweight0` at the configuration `ws` holds (qpos0):
/// [`dof_invweight0`], but 1/mass for the dofs of a body moved by slides
/// alone ([`slider_body_mass`]).
pub(super) fn mujoco_dof_invweight0(
    model: &Model,
    vehicle: &Vehicle,
    ws: &mut Workspace,
) -> Result<Vec<f64>, DynamicsError> {
    let mut invweight = dof_invweight0(model, ws)?;
    let mut joint_infos = model.joints.iter();
    for (b, body) in vehicle.bodies.iter().enumerate() {
        // Taken whether used or not: the next body's joints follow.
        let infos: Vec<&JointInfo> = joint_infos.by_ref().take(body.joints.len()).collect();
        if let Some(mass) = slider_body_mass(vehicle, b) {
            for info in infos {
                invweight[info.dof_adr] = 1.0 / mass;
            }
        }
    }
    Ok(invweight)
}

/// MuJoCo's `dof_invweight0` from M alone: the mean diagonal of M⁻¹ over
/// each joint's dofs (a free joint's translation and rotation apart), with
/// diag(M⁻¹)_d = |m⁻¹ e_d|² since M⁻¹ = m⁻ᵀ m⁻¹ (less the tendons'
/// armature's share: MuJoCo's M includes it).
fn dof_invweight0(model: &Model, ws: &mut Workspace) -> Result<Vec<f64>, DynamicsError> {
    let (mut unit, mut eps) = (vec![0.0; model.nv], vec![0.0; model.nv]);
    let mut diagonal = vec![0.0; model.nv];
    for (d, entry) in diagonal.iter_mut().enumerate() {
        unit[d] = 1.0;
        ws.eps_from_forces(model, &unit, None, &mut eps)?;
        unit[d] = 0.0;
        *entry = ws.inverse_mass_quadratic(model, &eps);
    }
    let mut invweight = vec![0.0; model.nv];
    for joint in &model.joints {
        // (first dof, count) of each group MuJoCo averages over.
        let groups: &[(usize, usize)] = match joint.kind {
            JointKind::Free => &[(0, 3), (3, 3)],
            JointKind::Ball => &[(0, 3)],
            JointKind::Hinge | JointKind::Slide => &[(0, 1)],
        };
        for &(first, count) in groups {
            let dofs = joint.dof_adr + first..joint.dof_adr + first + count;
            let mean = diagonal[dofs.clone()].iter().sum::<f64>() / count as f64;
            invweight[dofs].fill(mean);
        }
    }
    Ok(invweight)
}

/// MuJoCo's `body_invweight0` of `body` (translation, rotation) at the
/// configuration `ws` holds, its world transforms current: the mean
/// diagonal of J M⁻¹ Jᵀ for the Jacobian of its centre of mass and its
/// rotation, in world axes; (0, 0) for a body fixed to the world.
pub(super) fn body_invweight0(
    model: &Model,
    vehicle: &Vehicle,
    attachments: &[Attachment],
    ws: &mut Workspace,
    body: Option<usize>,
) -> [f64; 2] {
    let Some(b) = body else { return [0.0; 2] };
    let Some(link) = attachments[b].link else { return [0.0; 2] };
    if let Some(mass) = slider_body_mass(vehicle, b) {
        return [1.0 / mass, 0.0];
    }
    let offset = &attachments[b].offset;
    let com = offset.trans + offset.rot.transpose() * vehicle.bodies[b].inertial_pos;
    let to_link = ws.x_world[link].rot;
    let mut wrenches = vec![SpatialVec::zeros(); model.links.len()];
    let (zero, mut eps) = (vec![0.0; model.nv], vec![0.0; model.nv]);
    let mut means = [0.0; 2];
    for (part, mean) in means.iter_mut().enumerate() {
        for axis in 0..3 {
            let direction = to_link * Vec3::ith(axis, 1.0);
            wrenches[link] = match part {
                0 => spatial(&com.cross(&direction), &direction),
                _ => spatial(&direction, &Vec3::zeros()),
            };
            // Cannot fail: the configuration is set and the lengths are the model's.
            if ws.eps_from_forces(model, &zero, Some(&wrenches), &mut eps).is_ok() {
                *mean += ws.inverse_mass_quadratic(model, &eps) / 3.0;
            }
        }
    }
    means
}

/// The mass of `body` when MuJoCo's compiler marks it `body_simple == 2`,
/// for which its `mj_setConst` takes the invweights as 1/mass (the joints'
/// armature left out) instead of the diagonal of M⁻¹: a leaf body on the
/// world or on a jointless child of the world, its inertial frame its body
/// frame, moved by slides alone, anchored at the origin and along
/// coordinate axes.
fn slider_body_mass(vehicle: &Vehicle, body: usize) -> Option<f64> {
    let bodies = &vehicle.bodies;
    let this = &bodies[body];
    let on_world = match this.parent {
        None => true,
        Some(p) => bodies[p].parent.is_none() && bodies[p].joints.is_empty(),
    };
    let leaf = !bodies.iter().any(|other| other.parent == Some(body));
    let same_frame = this.inertial_pos.amax() <= AXIS_EPSILON
        && this.inertial_quat.is_some_and(|q| (q.w - 1.0).abs() <= AXIS_EPSILON && q.imag().amax() <= AXIS_EPSILON);
    let sliders = !this.joints.is_empty()
        && this.joints.iter().all(|joint| {
            joint.kind == JointKind::Slide
                && joint.pos == Vec3::zeros()
                && joint.axis.iter().filter(|c| c.abs() > AXIS_EPSILON).count() == 1
        });
    let mass = this.inertia.as_ref().map(|inertia| inertia.mass).filter(|&m| m > 0.0)?;
    (on_world && leaf && same_frame && sliders).then_some(mass)
}
