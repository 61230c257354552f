//! A vehicle as described by its MJCF file, with MuJoCo's semantics resolved:
//! defaults applied, angles in radians, orientations as unit quaternions,
//! inertia computed from geoms where the body has no `<inertial>`.
//!
//! This is what the importer produces and what [`crate::model::Model::compile`]
//! turns into the compiled model; it still mirrors the MJCF body tree
//! (bodies without joints are kept, several joints per body are allowed).

use crate::math::{Mat3, Quat, Vec3};

/// A vehicle: the tree of moving and welded bodies below `<worldbody>`.
#[derive(Clone, Debug, PartialEq)]
pub struct Vehicle {
    /// The `model` attribute of `<mujoco>` (or "vehicle").
    pub name: String,
    /// Gravity in world coordinates (zero when `<flag gravity="disable"/>`).
    pub gravity: Vec3,
    /// Bodies in MJCF document order (depth-first, parent before child),
    /// not including the world body.
    pub bodies: Vec<Body>,
}

/// One `<body>`.
#[derive(Clone, Debug, PartialEq)]
pub struct Body {
    /// The body's name, or `body<index>` when it has none.
    pub name: String,
    /// Index of the parent in [`Vehicle::bodies`]; `None` for a child of `<worldbody>`.
    pub parent: Option<usize>,
    /// Position of the body frame in the parent body frame.
    pub pos: Vec3,
    /// Orientation of the body frame in the parent body frame.
    pub quat: Quat,
    /// Mass properties in the body frame; `None` for a massless body.
    pub inertia: Option<MassProperties>,
    /// The body's joints, in document order (MuJoCo applies them in this order).
    pub joints: Vec<Joint>,
    /// Line of the `<body>` element in the MJCF file (1-based).
    pub line: u32,
}

/// Mass, centre of mass and rotational inertia of a body, in its body frame.
#[derive(Clone, Debug, PartialEq)]
pub struct MassProperties {
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass in the body frame (m).
    pub com: Vec3,
    /// Inertia tensor about the centre of mass, in body-frame axes (kg m²).
    pub inertia: Mat3,
}

/// The kinds of MuJoCo joint.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointKind {
    /// Rotation about an axis: 1 qpos (angle, rad), 1 dof.
    Hinge,
    /// Translation along an axis: 1 qpos (m), 1 dof.
    Slide,
    /// Rotation about a point: 4 qpos (unit quaternion w,x,y,z), 3 dofs
    /// (angular velocity in the body frame).
    Ball,
    /// Free motion: 7 qpos (position in world, then quaternion), 6 dofs
    /// (linear velocity in world axes, then angular velocity in the body frame).
    Free,
}

impl JointKind {
    /// Every kind.
    pub const ALL: [JointKind; 4] = [JointKind::Hinge, JointKind::Slide, JointKind::Ball, JointKind::Free];

    /// The MJCF name of the kind (`<joint type="...">`), also its JSON name.
    pub fn name(self) -> &'static str {
        match self {
            JointKind::Hinge => "hinge",
            JointKind::Slide => "slide",
            JointKind::Ball => "ball",
            JointKind::Free => "free",
        }
    }

    /// Number of position coordinates (qpos entries).
    pub fn nq(self) -> usize {
        match self {
            JointKind::Hinge | JointKind::Slide => 1,
            JointKind::Ball => 4,
            JointKind::Free => 7,
        }
    }

    /// Number of degrees of freedom (qvel entries).
    pub fn nv(self) -> usize {
        match self {
            JointKind::Hinge | JointKind::Slide => 1,
            JointKind::Ball => 3,
            JointKind::Free => 6,
        }
    }
}

/// One `<joint>` or `<freejoint>`.
#[derive(Clone, Debug, PartialEq)]
pub struct Joint {
    /// The joint's name, or `<body name>_joint<k>` when it has none.
    pub name: String,
    /// Hinge, slide, ball or free.
    pub kind: JointKind,
    /// Anchor point in the body frame (m); ignored for free joints.
    pub pos: Vec3,
    /// Unit axis in the body frame (hinge and slide).
    pub axis: Vec3,
    /// MuJoCo's `ref`: the qpos value at which the body is in its modelled
    /// pose (rad or m; hinge and slide only, else 0).
    pub reference: f64,
    /// Spring rest position `springref` (rad or m; hinge and slide only).
    pub springref: f64,
    /// Spring stiffness (N m/rad or N/m); zero when `<flag spring="disable"/>`.
    pub stiffness: f64,
    /// Viscous damping (N m s/rad or N s/m); zero when `<flag damper="disable"/>`.
    pub damping: f64,
    /// Armature (rotor inertia) added to every dof of the joint.
    pub armature: f64,
    /// Line of the joint element in the MJCF file (1-based).
    pub line: u32,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_names_are_the_mjcf_names() {
        for kind in JointKind::ALL {
            assert_eq!(serde_json::to_value(kind).unwrap(), kind.name());
        }
    }
}
