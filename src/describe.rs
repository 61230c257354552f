//! `nudyn describe`: the vehicle's structure as data, so that scripts find
//! joints, kinds and coordinate addresses without reading description prose.
//! The field names are a contract with users' scripts.

use serde::Serialize;

use crate::model::Model;
use crate::vehicle::JointKind;

/// The structure of a compiled vehicle.
#[derive(Clone, Debug, Serialize)]
pub struct Description {
    /// The model's name (MJCF `<mujoco model>`).
    pub name: String,
    /// Number of position coordinates (MuJoCo's nq).
    pub nq: usize,
    /// Number of degrees of freedom (MuJoCo's nv).
    pub nv: usize,
    /// Gravity acting on the vehicle (m/s², world axes): 0 where `<flag gravity="disable"/>` turns it off.
    pub gravity: [f64; 3],
    /// θ at the pose drawn in the file (MuJoCo's qpos0).
    pub qpos0: Vec<f64>,
    /// The joints in MuJoCo's order (that of qpos and qvel).
    pub joints: Vec<JointDescription>,
}

/// One joint: which entries of θ and ν it owns.
#[derive(Clone, Debug, Serialize)]
pub struct JointDescription {
    /// The joint's name (MuJoCo's, or the one nudyn gives an unnamed joint).
    pub name: String,
    /// The body it moves.
    pub body: String,
    /// hinge, slide, ball or free.
    pub kind: JointKind,
    /// First qpos (θ) entry, 0-based.
    pub qpos_adr: usize,
    /// Number of qpos entries.
    pub nq: usize,
    /// First qvel (ν, ε) entry, 0-based.
    pub dof_adr: usize,
    /// Number of dofs.
    pub nv: usize,
    /// The 0-based θ index of each unit quaternion's w (ball: qpos_adr; free: qpos_adr + 3).
    pub quaternion_adr: Option<usize>,
}

impl Description {
    /// The description of `model`.
    pub fn of(model: &Model) -> Self {
        let joints = model
            .joints
            .iter()
            .map(|joint| JointDescription {
                name: joint.name.clone(),
                body: joint.body_name.clone(),
                kind: joint.kind,
                qpos_adr: joint.qpos_adr,
                nq: joint.kind.nq(),
                dof_adr: joint.dof_adr,
                nv: joint.kind.nv(),
                quaternion_adr: match joint.kind {
                    JointKind::Ball => Some(joint.qpos_adr),
                    JointKind::Free => Some(joint.qpos_adr + 3),
                    JointKind::Hinge | JointKind::Slide => None,
                },
            })
            .collect();
        Description {
            name: model.name.clone(),
            nq: model.nq,
            nv: model.nv,
            gravity: [model.gravity.x, model.gravity.y, model.gravity.z],
            qpos0: model.qpos0.clone(),
            joints,
        }
    }
}
