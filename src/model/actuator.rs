//! Compiled actuators: each actuator's transmission resolved into dofs or
//! link frames, its force law, and its limits, in MuJoCo's actuator order.
//!
//! The force law is MuJoCo's for a stateless actuator (its Computation
//! chapter, "Actuation model"): with L and V the actuator length and
//! velocity, force = gain(L, V) · ctrl + bias(L, V), clamped to `forcerange`;
//! the generalized force is the transmission's moment arms times the force.

use serde::{Deserialize, Serialize};

use crate::math::{Real, Transform, Vec3};
use crate::vehicle::{Activation, ActivationKind, ActuatorKind, BiasType, GainType};

/// A site's frame as the passes see it: fixed to a link, to a node of a
/// flexible body on that link, or to the world.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SiteFrame {
    /// The link carrying the site; `None` for a site fixed to the world.
    pub link: Option<usize>,
    /// ˢX_ₗ: the site frame relative to the link frame (or to the world);
    /// for a site at a node, ˢX_ⱼ relative to the node's frame.
    pub frame: Transform,
    /// The node of a flexible body the site sits at, moving with it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub node: Option<NodeSite>,
}

/// Which node of which flexible body (`Model::flexible`) carries a site.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct NodeSite {
    /// The flexible body, by index into `Model::flexible`.
    pub flexible: usize,
    /// The node, by index into its `modal.nodes`.
    pub node: usize,
}

/// How an actuator's force reaches the dofs (MuJoCo's transmission).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "type")]
pub enum ActuatorTransmission {
    /// A hinge or slide joint: length gear₀·θ, moment arm gear₀ on its dof.
    Scalar {
        /// The joint's dof.
        dof: usize,
        /// The joint's θ entry.
        qpos: usize,
    },
    /// A ball joint: the gear's first three entries are a rotation axis in
    /// the child frame (`in_parent`: in the parent frame, carried into the
    /// child frame by the joint's rotation); length = axis · rotation vector.
    Ball {
        /// The joint's first dof.
        dof: usize,
        /// The joint's quaternion (w first) in θ.
        qpos: usize,
        /// `jointinparent`.
        in_parent: bool,
    },
    /// A free joint: a force along the gear's first three entries (world
    /// axes) and a torque about the last three (body axes, or with
    /// `in_parent` world axes); length 0.
    Free {
        /// The joint's first dof (the translation's).
        dof: usize,
        /// The joint's quaternion (w first) in θ.
        qpos: usize,
        /// `jointinparent`.
        in_parent: bool,
    },
    /// A site: a force along the gear's first three entries and a torque
    /// about the last three, in the site frame; length 0.
    Site {
        /// The site.
        site: SiteFrame,
    },
    /// A site with a reference site: the force and torque along axes of the
    /// reference site's frame, at the site and, opposite, at the reference
    /// site; the length measures the site in the reference frame. As MuJoCo
    /// clears the moment arms of the dofs that move both sites together, a
    /// torque cancels the couple the pair exerts on their common link (or
    /// on the node of a flexible body on it that both hang from).
    RelativeSite {
        /// The site.
        site: SiteFrame,
        /// The reference site.
        reference: SiteFrame,
        /// The deepest link that moves both sites, if any.
        common_link: Option<usize>,
        /// The node of a flexible body on `common_link` that both sites
        /// hang from (on bodies welded at it, or below children at it),
        /// whose modes move both: the couple is cancelled there.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        common_node: Option<NodeSite>,
    },
    /// A tendon: length gear₀·L, moment arms gear₀·J.
    Tendon {
        /// The tendon (index into [`Model::tendons`](super::Model::tendons)).
        tendon: usize,
    },
}

impl ActuatorTransmission {
    /// Whether the transmission applies wrenches to links (else forces on dofs).
    pub fn applies_wrenches(&self) -> bool {
        matches!(self, ActuatorTransmission::Site { .. } | ActuatorTransmission::RelativeSite { .. })
    }
}

/// What an actuator acts on, by name (for descriptions).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ActuatorTarget {
    /// "joint", "jointinparent", "tendon" or "site": MuJoCo's attribute.
    pub attribute: String,
    /// The joint's, tendon's or site's name.
    pub name: String,
    /// The reference site's name.
    pub refsite: Option<String>,
}

/// One compiled actuator.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Actuator {
    /// The actuator's name, if it has one.
    pub name: Option<String>,
    /// The element it was written with.
    pub kind: ActuatorKind,
    /// What it acts on.
    pub target: ActuatorTarget,
    /// How its force reaches the dofs.
    pub transmission: ActuatorTransmission,
    /// MuJoCo's `gear`.
    pub gear: [f64; 6],
    /// The gain's type.
    pub gain_type: GainType,
    /// gainprm[0..3].
    pub gain: [f64; 3],
    /// The bias's type.
    pub bias_type: BiasType,
    /// biasprm[0..3], with a damping ratio already turned into a damping.
    pub bias: [f64; 3],
    /// The ctrl range when ctrl is limited.
    pub ctrl_range: Option<[f64; 2]>,
    /// The force range when the force is limited.
    pub force_range: Option<[f64; 2]>,
    /// The activation state, if the force takes act for ctrl (absent from
    /// the model files of vehicles without one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub activation: Option<Activation>,
    /// False when `<option actuatorgroupdisable>` disables the actuator's group.
    pub enabled: bool,
    /// For a position servo on a rotation (a ball joint, or a reference site
    /// with a purely rotational gear), whose length wraps at ±π·|gear|: the
    /// period 2π·|gear| on which MuJoCo takes the setpoint nearest the
    /// length; 0 for every other actuator.
    pub setpoint_period: f64,
    /// Line of the actuator element in the MJCF file (1-based).
    pub line: u32,
}

impl Actuator {
    /// The actuator as messages name it: its element and name, or its index.
    pub fn label(&self, index: usize) -> String {
        match &self.name {
            Some(name) => format!("{} '{name}'", self.kind.name()),
            None => format!("{} {index}", self.kind.name()),
        }
    }

    /// Whether MuJoCo takes it for a position servo: fixed gain kp, affine
    /// bias with biasprm\[1\] = −kp (its `dampratio` and setpoint wrapping apply).
    pub fn is_position_servo(&self) -> bool {
        self.gain_type == GainType::Fixed && self.bias_type == BiasType::Affine && self.gain[0] == -self.bias[1]
    }

    /// Whether MuJoCo's compiler reads biasprm\[2\] as a damping ratio: a
    /// positive biasprm\[2\] when gainprm\[0\] = −biasprm\[1\], whatever the types.
    pub fn has_damping_ratio(&self) -> bool {
        self.gain[0] == -self.bias[1] && self.bias[2] > 0.0
    }

    /// act's rate (MuJoCo's `act_dot`) at activation `act` and control
    /// `ctrl` (already clamped to its range); 0 for a stateless actuator.
    pub fn activation_rate<S: Real>(&self, ctrl: S, act: S) -> S {
        match self.activation {
            None => S::zero(),
            Some(Activation { kind: ActivationKind::Integrator, .. }) => ctrl,
            // MuJoCo divides by at least mjMINVAL.
            Some(Activation { time_constant, .. }) => (ctrl - act) / time_constant.max(MIN_TIME_CONSTANT),
        }
    }

    /// The activation the force takes: act, or with `actearly` the
    /// activation one `timestep` ahead from rate `act_dot` (MuJoCo's
    /// `mj_nextActivation`; a filterexact's step is exact), clamped to its
    /// range. MuJoCo's force reads act unclamped, but its step keeps act
    /// within the range, so that the two differ only where act is outside
    /// it: within an integrator's step that crosses the bound, where
    /// the clamp keeps the force what the projected motion gives.
    pub fn activation_input<S: Real>(&self, act: S, act_dot: S, timestep: f64) -> S {
        let Some(activation) = self.activation else {
            return act;
        };
        if !activation.early {
            return activation.clamp(act);
        }
        activation.clamp(ahead(activation, act, act_dot, timestep))
    }

    /// What the actuator's `actrange` clamps in its force: act, or with
    /// `actearly` the unclamped look-ahead from `ctrl` (clamped to its
    /// range already) and `act`. The force kinks where it crosses a bound.
    pub fn clamped_activation(&self, ctrl: f64, act: f64, timestep: f64) -> f64 {
        match self.activation {
            Some(activation) if activation.early => ahead(activation, act, self.activation_rate(ctrl, act), timestep),
            _ => act,
        }
    }

    /// The gear's translation part.
    pub fn gear_translation(&self) -> Vec3 {
        Vec3::new(self.gear[0], self.gear[1], self.gear[2])
    }

    /// The gear's rotation part.
    pub fn gear_rotation(&self) -> Vec3 {
        Vec3::new(self.gear[3], self.gear[4], self.gear[5])
    }
}

/// MuJoCo's mjMINVAL: the least time constant a filter divides by.
const MIN_TIME_CONSTANT: f64 = 1e-15;

/// The activation one `timestep` ahead of `act` at rate `act_dot`
/// (`actearly`, MuJoCo's `mj_nextActivation`, in its order of operations):
/// a filterexact's step is exact.
fn ahead<S: Real>(activation: Activation, act: S, act_dot: S, timestep: f64) -> S {
    match activation.kind {
        ActivationKind::FilterExact => {
            let tau = activation.time_constant.max(MIN_TIME_CONSTANT);
            act + act_dot * tau * (1.0 - (-timestep / tau).exp())
        }
        ActivationKind::Integrator | ActivationKind::Filter => act + act_dot * timestep,
    }
}

/// A joint's limits on the total actuator force at its dof (MuJoCo's
/// `actuatorfrcrange`, hinge and slide joints only).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DofForceLimit {
    /// The joint's dof.
    pub dof: usize,
    /// The force range.
    pub range: [f64; 2],
}
