//! The equality constraints with what MuJoCo computes for them at qpos0:
//! a connect's second anchor, a weld's first anchor and relative pose when
//! `relpose` leaves them to qpos0, and the invweights of the rows'
//! regularizer.

use super::invweight::body_invweight0;
use crate::math::{Mat3, Quat, Transform, Vec3};
use crate::model::{CompiledEquality, EqualityRows, ModelError, SiteFrame, TendonConstants, Tree};
use crate::vehicle::{Equality, EqualityKind, EqualityObjects, Vehicle};
use crate::workspace::Workspace;

/// The invweights at qpos0 that joint and tendon equalities take theirs from.
pub(super) struct Invweights<'a> {
    /// MuJoCo's `dof_invweight0`.
    pub dofs: &'a [f64],
    /// The tendons' constants.
    pub tendons: &'a [TendonConstants],
}

/// The active equality `equality` (the `index`th of the file) compiled at
/// the configuration `ws` holds (qpos0, world transforms current).
pub(super) fn compile(
    tree: &Tree,
    vehicle: &Vehicle,
    ws: &mut Workspace,
    invweights: &Invweights,
    index: usize,
    equality: &Equality,
) -> Result<CompiledEquality, ModelError> {
    let label = equality_label(equality, index);
    let rows = equality_rows(tree, vehicle, ws, invweights, equality).map_err(|reason| ModelError::Equality {
        equality: label.clone(),
        line: equality.line,
        reason,
    })?;
    Ok(CompiledEquality { label, rows, soft: equality.soft })
}

/// One equality's rows.
fn equality_rows(
    tree: &Tree,
    vehicle: &Vehicle,
    ws: &mut Workspace,
    invweights: &Invweights,
    equality: &Equality,
) -> Result<EqualityRows, String> {
    let (model, attachments, sites) = (&tree.model, &tree.attachments, &tree.sites);
    let frame_of_body = |body: Option<usize>| match body {
        Some(b) => SiteFrame { link: attachments[b].link, frame: attachments[b].offset, node: None },
        None => SiteFrame { link: None, frame: Transform::identity(), node: None },
    };
    let resolve = |objects: &EqualityObjects| match *objects {
        EqualityObjects::Bodies(a, b) => ([frame_of_body(a), frame_of_body(b)], [a, b], true),
        EqualityObjects::Sites(a, b) => ([sites[a], sites[b]], [vehicle.sites[a].body, vehicle.sites[b].body], false),
    };
    let in_world = |ws: &Workspace, frame: &SiteFrame| match frame.link {
        Some(link) => frame.frame.compose(&ws.x_world[link]),
        None => frame.frame,
    };
    let rows = match &equality.kind {
        EqualityKind::Connect { objects, anchor } => {
            let (frames, bodies, body_semantics) = resolve(objects);
            let anchors = if body_semantics {
                let (first, second) = (in_world(ws, &frames[0]), in_world(ws, &frames[1]));
                let point = first.trans + first.rot.transpose() * anchor;
                [*anchor, second.rot * (point - second.trans)]
            } else {
                [Vec3::zeros(); 2]
            };
            let weights = bodies.map(|b| body_invweight0(model, vehicle, attachments, ws, b));
            EqualityRows::Connect { frames, anchors, invweight: weights[0][0] + weights[1][0] }
        }
        EqualityKind::Weld { objects, anchor, relpose, torquescale } => {
            let (frames, bodies, body_semantics) = resolve(objects);
            let (anchors, relative) = match (body_semantics, relpose) {
                (false, _) => ([Vec3::zeros(); 2], Quat::identity()),
                (true, Some((position, quat))) => ([*position, *anchor], *quat),
                (true, None) => {
                    let (first, second) = (in_world(ws, &frames[0]), in_world(ws, &frames[1]));
                    let point = second.trans + second.rot.transpose() * anchor;
                    let rotation = |t: &Transform| rotation_quat(&t.rot.transpose());
                    ([first.rot * (point - first.trans), *anchor], rotation(&first).inverse() * rotation(&second))
                }
            };
            let weights = bodies.map(|b| body_invweight0(model, vehicle, attachments, ws, b));
            EqualityRows::Weld {
                frames,
                anchors,
                relative,
                torquescale: *torquescale,
                invweight: [weights[0][0] + weights[1][0], weights[0][1] + weights[1][1]],
            }
        }
        EqualityKind::Joint { joint1, joint2, polycoef } => {
            let find = |name: &str| {
                model
                    .joints
                    .iter()
                    .find(|j| j.name == name)
                    .map(|j| [j.dof_adr, j.qpos_adr])
                    .ok_or(format!("no joint '{name}'"))
            };
            let first = find(joint1)?;
            let second = joint2.as_deref().map(find).transpose()?;
            let weights = invweights.dofs;
            let invweight = weights[first[0]] + second.map_or(0.0, |s| weights[s[0]]);
            EqualityRows::Joint { first, second, polycoef: *polycoef, invweight }
        }
        EqualityKind::Tendon { tendon1, tendon2, polycoef } => {
            let weight = |k: usize| invweights.tendons[k].invweight0;
            let invweight = weight(*tendon1) + tendon2.map_or(0.0, weight);
            EqualityRows::Tendon { first: *tendon1, second: *tendon2, polycoef: *polycoef, invweight }
        }
    };
    Ok(rows)
}

/// The rotation matrix `frame_to_world` as a unit quaternion.
fn rotation_quat(frame_to_world: &Mat3) -> Quat {
    Quat::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(*frame_to_world))
}

/// How messages name an equality: its element and name, or its index.
fn equality_label(equality: &Equality, index: usize) -> String {
    let tag = match equality.kind {
        EqualityKind::Connect { .. } => "connect",
        EqualityKind::Weld { .. } => "weld",
        EqualityKind::Joint { .. } => "joint",
        EqualityKind::Tendon { .. } => "tendon",
    };
    match &equality.name {
        Some(name) => format!("<{tag}> '{name}'"),
        None => format!("<{tag}> {index}"),
    }
}
