//! The descriptions of the controller's variables, per element: each
//! names the controlled joint or body and its unit.

use nudyn::control::{ControlLaw, Objective};
use nudyn::model::{LinkJoint, Model};

/// What controlled quantity k is, and its unit, for descriptions.
fn quantity(model: &Model, law: &ControlLaw, k: usize) -> (String, &'static str, &'static str) {
    const AXES: [&str; 3] = ["x", "y", "z"];
    match &law.objective {
        Objective::Joints(joints) => {
            let joint = &joints[k];
            let slide = model.links.iter().any(|l| l.qpos_adr == joint.qpos_adr && l.joint == LinkJoint::Slide);
            let (kind, unit, gain_unit) = if slide { ("slide", "m", "N/m") } else { ("hinge", "rad", "N*m/rad") };
            (format!("{kind} joint '{}'", joint.name), unit, gain_unit)
        }
        Objective::Pose(frame) if k < 3 => {
            (format!("position {} of body '{}' in world", AXES[k], frame.body), "m", "N/m")
        }
        Objective::Pose(frame) => (
            format!("rotation of body '{}' about the target frame's {} axis", frame.body, AXES[k - 3]),
            "rad",
            "N*m/rad",
        ),
    }
}

pub(super) fn target_gain(model: &Model, law: &ControlLaw, k: usize) -> String {
    let (what, _, unit) = quantity(model, law, k);
    format!("gain c2 on the error of the {what} ({unit})")
}

/// Target value k: of the pose (position, then quaternion) or of a joint.
pub(super) fn target(model: &Model, law: &ControlLaw, k: usize) -> String {
    const QUATERNION: [&str; 4] = ["w", "x", "y", "z"];
    match &law.objective {
        Objective::Pose(frame) if k < 3 => {
            format!("target position {} of body '{}' in world (m)", ["x", "y", "z"][k], frame.body)
        }
        Objective::Pose(frame) => format!(
            "target orientation of body '{}', quaternion {} (body to world; normalized when used) (1)",
            frame.body,
            QUATERNION[k - 3]
        ),
        Objective::Joints(_) => {
            let (what, unit, _) = quantity(model, law, k);
            format!("target of the {what} ({unit})")
        }
    }
}

pub(super) fn target_error(model: &Model, law: &ControlLaw, k: usize) -> String {
    let (what, unit, _) = quantity(model, law, k);
    match &law.objective {
        Objective::Pose(_) if k >= 3 => {
            format!("error Yhat - Y = -phi, phi = log(Rhat^T R): {what} relative to the target ({unit})")
        }
        _ => format!("error Yhat - Y of the {what} ({unit})"),
    }
}
