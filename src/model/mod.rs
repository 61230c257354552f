//! The compiled vehicle model: immutable, serializable (it is what an FMU
//! loads from its resources), and laid out for the O(N) passes.
//!
//! Compilation turns the MJCF body tree into a parent-first array of
//! *links*, one per joint, each with a constant motion subspace in its own
//! frame (docs/DYNAMICS.md §2):
//! - a body with several joints becomes a chain of links; the frames
//!   between its joints are massless and the body's inertia sits on the last;
//! - a free joint becomes a world-aligned 3-dof translation link followed by
//!   a 3-dof ball link at the body origin (massless in between);
//! - a body without joints is welded: its inertia is added to the link it
//!   is attached to (or dropped, if it is welded to the world).
//!
//! The links' order is MuJoCo's dof order, so link `k`'s dofs are the
//! qvel entries `dof_adr..dof_adr + ndof` and its coordinates the qpos
//! entries `qpos_adr..`.
//!
//! Actuators keep MuJoCo's order (that of ctrl); their transmissions become
//! dof addresses or site frames fixed to links (`actuator`).

use std::collections::HashMap;

use nalgebra::SMatrix;
use serde::{Deserialize, Serialize};

use crate::math::{
    Mat3, Quat, Real, SpatialMat, SpatialVec, Transform, Vec3, angular, linear, real, rigid_inertia, skew, spatial,
};
use crate::vehicle::{
    Actuation, ActuatorKind, BiasType, GainType, JointKind, MassProperties, SensorKind, Transmission, Vehicle,
};

mod actuator;
mod constraint;
mod flexible;
mod gravity_compensation;
mod interaction;
mod sensor;
mod tendon;
mod validate;
pub use actuator::{Actuator, ActuatorTarget, ActuatorTransmission, DofForceLimit, NodeSite, SiteFrame};
pub use constraint::{CompiledEquality, Constraints, DofFriction, EqualityRows, Limit, TendonFriction, TendonLimit};
pub use flexible::{FlexBody, NodeChild};
pub use gravity_compensation::{CompensatedLink, GravityCompensation};
pub use interaction::InteractionBodies;
pub use sensor::{BodyMass, Sensor, SensorSource};
pub use tendon::{FixedTerm, InertiaTerm, Path, PathStop, Tendon, WRAP_SWITCHES};
pub use validate::InvalidModel;

/// Motion subspace storage: up to three columns, the first `ndof` used.
pub type MotionSubspace = SMatrix<f64, 6, 3>;

/// The joint of one link, as the passes see it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LinkJoint {
    /// Rotation about `axis` through `anchor`; 1 qpos, 1 dof.
    Hinge,
    /// Translation along `axis`; 1 qpos, 1 dof.
    Slide,
    /// Rotation about `anchor`; quaternion qpos (w,x,y,z), 3 dofs (body-frame ω).
    Ball,
    /// World-aligned translation (the first half of a free joint); 3 qpos, 3 dofs.
    Translation,
}

/// One link: a joint and the rigid body that moves with it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Link {
    /// Name of the MJCF joint this link implements.
    pub joint_name: String,
    /// Name of the MJCF body this link belongs to.
    pub body_name: String,
    /// Parent link; `None` for a link attached to the world.
    pub parent: Option<usize>,
    /// Fixed placement of the joint's inboard frame relative to the parent
    /// link frame (or world); for the first link of a child body at a node
    /// of a flexible body, relative to that node's frame
    /// (`FlexBody::node_children`), which the modes move on the parent link.
    pub x_tree: Transform,
    /// The joint type.
    pub joint: LinkJoint,
    /// Unit axis (hinge, slide), in link coordinates.
    pub axis: Vec3,
    /// Rotation centre (hinge, ball), in link coordinates.
    pub anchor: Vec3,
    /// MuJoCo's `ref` (hinge, slide): the joint value of the modelled pose;
    /// kinematics use θ − reference.
    pub reference: f64,
    /// Number of dofs (1 or 3).
    pub ndof: usize,
    /// Constant motion subspace S in link coordinates (first `ndof` columns).
    pub motion_subspace: MotionSubspace,
    /// First qpos entry of this link.
    pub qpos_adr: usize,
    /// First qvel entry of this link.
    pub dof_adr: usize,
    /// Armature added to each of this link's dofs.
    pub armature: f64,
    /// Spring stiffness acting on this link's dofs.
    pub stiffness: f64,
    /// Viscous damping acting on this link's dofs.
    pub damping: f64,
    /// Rotational inertia about the link origin, in link coordinates
    /// (including bodies welded to it). With `mass` and `mass_moment` it
    /// makes the link's spatial inertia ([`Link::spatial_inertia`]), which
    /// is not stored: ten numbers where the 6×6 matrix takes 36, and the
    /// passes stream every link's model data on long chains.
    pub rotational_inertia: Mat3,
    /// Mass of the link (including bodies welded to it).
    pub mass: f64,
    /// First mass moment m·c (c: centre of mass in link coordinates).
    pub mass_moment: Vec3,
}

impl Link {
    /// The spatial inertia about the link origin, in link coordinates:
    /// [Ī h×; h×ᵀ m·1] with Ī the rotational inertia and h the mass moment.
    #[inline]
    pub fn spatial_inertia(&self) -> SpatialMat {
        let mut out = SpatialMat::zeros();
        self.add_spatial_inertia_to(&mut out);
        out
    }

    /// `sum` += the spatial inertia, adding only its nonzero entries (pass
    /// 1 adds it to the children's share, which a zero matrix filled and
    /// added whole would cost 36 stores and additions more).
    #[inline(always)]
    pub fn add_spatial_inertia_to<S: Real>(&self, sum: &mut SpatialMat<S>) {
        let h = &self.mass_moment;
        for row in 0..3 {
            for col in 0..3 {
                sum[(row, col)] += self.rotational_inertia[(row, col)];
            }
            sum[(row + 3, row + 3)] += self.mass;
        }
        // h× = [0 −h₃ h₂; h₃ 0 −h₁; −h₂ h₁ 0] top right, its transpose bottom left.
        for (row, col, value) in [(0, 1, -h[2]), (0, 2, h[1]), (1, 0, h[2]), (1, 2, -h[0]), (2, 0, -h[1]), (2, 1, h[0])]
        {
            sum[(row, col + 3)] += value;
            sum[(col + 3, row)] += value;
        }
    }

    /// The spatial inertia times a motion vector (ω, v): (Īω + h × v, m v − h × ω).
    #[inline]
    pub fn inertia_times<S: Real>(&self, motion: &SpatialVec<S>) -> SpatialVec<S> {
        let (w, v) = (angular(motion), linear(motion));
        let h = real::<S, 3, 1>(&self.mass_moment);
        spatial(&(real(&self.rotational_inertia) * w + h.cross(&v)), &(v * S::from(self.mass) - h.cross(&w)))
    }
}

/// Descriptive information on one MJCF joint (for variable descriptions).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointInfo {
    /// Joint name.
    pub name: String,
    /// Body it moves.
    pub body_name: String,
    /// Joint kind.
    pub kind: JointKind,
    /// First qpos entry.
    pub qpos_adr: usize,
    /// First qvel entry.
    pub dof_adr: usize,
}

/// Terms of the dynamics that a vehicle does not have, found by
/// [`Model::compile`]; the passes then skip computing them.
///
/// Turning a shortcut off is always safe: the passes compute the term, which
/// is then zero, and give the same numbers (tests check this). A shortcut
/// turned on for a vehicle that has the term would drop it:
/// [`Shortcuts::not_allowed_for`] tells, and the FMU refuses such a model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shortcuts {
    /// Gravity is zero: no gravity wrenches in pass 3, and no world
    /// transforms in pass 0 (only the momentum needs them then, and it
    /// computes them when asked).
    pub no_gravity: bool,
    /// No joint has stiffness: no spring forces (for ball and free joints,
    /// no rotation vector from the spring pose).
    pub no_springs: bool,
    /// No joint has damping: no damper forces.
    pub no_dampers: bool,
    /// No joint has armature: D = SᵀI^A S.
    pub no_armature: bool,
}

impl Shortcuts {
    /// Every shortcut the links and gravity allow.
    pub fn of(links: &[Link], gravity: &Vec3) -> Shortcuts {
        Shortcuts {
            no_gravity: *gravity == Vec3::zeros(),
            no_springs: links.iter().all(|l| l.stiffness == 0.0),
            no_dampers: links.iter().all(|l| l.damping == 0.0),
            no_armature: links.iter().all(|l| l.armature == 0.0),
        }
    }

    /// No shortcut: the passes compute every term.
    pub fn none() -> Shortcuts {
        Shortcuts::default()
    }

    /// Whether pass 3 can skip the inward recursion of joint and gravity
    /// forces altogether (their ε is zero).
    pub fn no_passive_forces(&self) -> bool {
        self.no_gravity && self.no_springs && self.no_dampers
    }

    /// The first shortcut that would drop a term `model` has, if any.
    pub fn not_allowed_for(&self, model: &Model) -> Option<&'static str> {
        let allowed = Shortcuts::of(&model.links, &model.gravity);
        [
            ("no_gravity", self.no_gravity, allowed.no_gravity),
            ("no_springs", self.no_springs, allowed.no_springs),
            ("no_dampers", self.no_dampers, allowed.no_dampers),
            ("no_armature", self.no_armature, allowed.no_armature),
        ]
        .into_iter()
        .find(|(_, taken, allowed)| *taken && !allowed)
        .map(|(name, _, _)| name)
    }
}

/// The compiled vehicle model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Model {
    /// Vehicle name.
    pub name: String,
    /// Number of position coordinates θ (MuJoCo's nq).
    pub nq: usize,
    /// Number of dofs, the length of ν and ε (MuJoCo's nv).
    pub nv: usize,
    /// Gravity in world coordinates.
    pub gravity: Vec3,
    /// The magnetic field in world coordinates, which magnetometers read.
    #[serde(default)]
    pub magnetic: Vec3,
    /// Links in parent-first (MuJoCo dof) order.
    pub links: Vec<Link>,
    /// MJCF joints in qpos order.
    pub joints: Vec<JointInfo>,
    /// The configuration in which the vehicle is modelled (MuJoCo's qpos0).
    pub qpos0: Vec<f64>,
    /// Spring rest configuration (MuJoCo's qpos_spring).
    pub qpos_spring: Vec<f64>,
    /// The terms the passes skip; none when absent from a model file.
    #[serde(default)]
    pub shortcuts: Shortcuts,
    /// Actuators in MuJoCo's order (that of ctrl).
    #[serde(default)]
    pub actuators: Vec<Actuator>,
    /// Joint limits on the total actuator force at a dof.
    #[serde(default)]
    pub actuator_force_limits: Vec<DofForceLimit>,
    /// Whether actuators act at all, and whether ctrl is clamped.
    #[serde(default)]
    pub actuation: Actuation,
    /// Sensors in MuJoCo's order (that of sensordata).
    #[serde(default)]
    pub sensors: Vec<Sensor>,
    /// The bodies' masses on their links, in body order, when a subtree,
    /// force or torque sensor needs them (else empty).
    #[serde(default)]
    pub body_masses: Vec<BodyMass>,
    /// Each link's `x_tree` rotation as a quaternion composed as MuJoCo
    /// composes `xquat`, when a framequat sensor needs it (else empty).
    #[serde(default)]
    pub link_tree_quats: Vec<Quat>,
    /// The bodies that take an external wrench as input (MuJoCo's
    /// `xfrc_applied`), in input order. Each adds six actuators after the
    /// MJCF's: a force along the world's x, y, z at the body's centre of
    /// mass, then a torque about them, their ctrl the wrench's components.
    #[serde(default)]
    pub wrench_bodies: Vec<String>,
    /// Friction loss and joint limits: MuJoCo's constraint rows.
    #[serde(default)]
    pub constraints: Constraints,
    /// The bodies external forces act on, when a force or torque sensor
    /// needs them (else empty).
    #[serde(default)]
    pub interaction_bodies: InteractionBodies,
    /// `<flag sensor="disable"/>`: the sensors keep their places in
    /// sensordata, which stays 0 as MuJoCo leaves it.
    #[serde(default)]
    pub sensors_disabled: bool,
    /// Body `gravcomp` and joint `actuatorgravcomp`: MuJoCo's gravity compensation.
    #[serde(default)]
    pub gravity_compensation: GravityCompensation,
    /// Tendons in MuJoCo's order.
    #[serde(default)]
    pub tendons: Vec<Tendon>,
    /// The tendons' armature in the mass matrix, as MuJoCo adds it (empty
    /// when no tendon has armature): derived from `tendons` and the links.
    #[serde(default)]
    pub tendon_inertia: Vec<InertiaTerm>,
    /// The flexible bodies with modes, in body order; their modal
    /// coordinates follow the rigid ones in θ and ν (docs/flexible.md).
    /// Left out of a rigid model's file, which stays as it was.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub flexible: Vec<FlexBody>,
}

/// Why a vehicle cannot be compiled.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ModelError {
    /// The compiled model is not consistent (a number overflowed while compiling).
    #[error("the compiled model is not consistent: {0}")]
    Invalid(#[from] InvalidModel),
    /// No joints: nothing moves.
    #[error("the vehicle has no joints: nothing moves")]
    NoJoints,
    /// A flexible body welded to the world: its modes would move no reference frame the passes carry.
    #[error("body '{body}' is flexible but welded to the world: give it (or a body it hangs from) a joint")]
    FlexibleOnWorld {
        /// The body.
        body: String,
    },
    /// A flexible body's modes together with a part of the model that does
    /// not take them in yet (docs/flexible.md, "Status").
    #[error("body '{body}' is flexible: {feature} do not take modal degrees of freedom in yet")]
    FlexibleWith {
        /// The body.
        body: String,
        /// What the vehicle has that does not.
        feature: &'static str,
    },
    /// A flexible body without joints at a node of another flexible body
    /// that its modes move: its own modal block would sit on the other's
    /// undeformed frame (docs/flexible.md, "Bodies welded at nodes").
    #[error(
        "body '{body}' is flexible and welded at node '{node}' of the flexible body '{carrier}', which its modes \
         move: a flexible body rides another's node through a joint of its own (give it one)"
    )]
    FlexibleWeldedAtNode {
        /// The welded flexible body.
        body: String,
        /// The flexible body it is welded to.
        carrier: String,
        /// The node's name in the carrier's modal file.
        node: String,
    },
    /// A free joint that is not on a child of the world body.
    #[error("free joint '{joint}' (line {line}) must be the only joint of a body placed directly in <worldbody>")]
    MisplacedFreeJoint {
        /// Joint name.
        joint: String,
        /// MJCF line.
        line: u32,
    },
    /// The articulated inertia seen by a joint is singular.
    #[error(
        "joint '{joint}' moves no mass or inertia in some direction (articulated inertia \
         not positive definite in the initial configuration): give the bodies it moves \
         mass and inertia, or armature to the joint"
    )]
    Singular {
        /// Joint name.
        joint: String,
    },
    /// An actuator that cannot be compiled.
    #[error("{actuator} (line {line}): {reason}")]
    Actuator {
        /// The actuator: its element and name, or its index.
        actuator: String,
        /// MJCF line.
        line: u32,
        /// What is wrong.
        reason: String,
    },
    /// A sensor that cannot be compiled.
    #[error("{sensor} (line {line}): {reason}")]
    Sensor {
        /// The sensor: its element and name, or its index.
        sensor: String,
        /// MJCF line.
        line: u32,
        /// What is wrong.
        reason: String,
    },
    /// An equality constraint that cannot be compiled.
    #[error("{equality} (line {line}): {reason}")]
    Equality {
        /// The element and its name or index.
        equality: String,
        /// MJCF line.
        line: u32,
        /// What is wrong.
        reason: String,
    },
    /// A body named for wrench inputs that cannot take one.
    #[error("--wrench-inputs: {reason}")]
    WrenchBody {
        /// What is wrong.
        reason: String,
    },
    /// A parameter that must be finite and non-negative is not.
    #[error("joint '{joint}': {what} must be finite and non-negative, found {value}")]
    BadParameter {
        /// Joint name.
        joint: String,
        /// Which parameter.
        what: &'static str,
        /// Its value.
        value: f64,
    },
}

/// What a body frame is rigidly attached to during compilation.
#[derive(Clone, Copy)]
pub(crate) struct Attachment {
    /// The link carrying the body, or `None` for the world.
    pub link: Option<usize>,
    /// ᵇᵒᵈʸX_ₗᵢₙₖ: the body frame relative to that link frame.
    pub offset: Transform,
    /// The offset's rotation as the product of the body quaternions on the
    /// way, as MuJoCo composes `xquat` (so a frame quaternion gets its sign).
    pub quat: Quat,
    /// For a body welded (no joint on the way) at a node of a flexible body
    /// that its modes move: that node, and its undeformed origin on the link.
    pub node: Option<(NodeSite, Vec3)>,
}

impl Attachment {
    /// A body frame that is the frame of `link`.
    fn at(link: Option<usize>) -> Attachment {
        Attachment { link, offset: Transform::identity(), quat: Quat::identity(), node: None }
    }

    /// A frame fixed in the body, `in_body` (ᶠX_b), on what carries the body:
    /// its link, or the node it is welded at (the frame then relative to the
    /// node's frame: the link's axes, origin at the node).
    pub(crate) fn frame(&self, in_body: &Transform) -> SiteFrame {
        let in_link = in_body.compose(&self.offset);
        match self.node {
            None => SiteFrame { link: self.link, frame: in_link, node: None },
            Some((node, origin)) => SiteFrame {
                link: self.link,
                frame: Transform { rot: in_link.rot, trans: in_link.trans - origin },
                node: Some(node),
            },
        }
    }
}

impl Model {
    /// MuJoCo's nu: the MJCF's actuators, without the wrench inputs' six per body.
    pub fn mjcf_actuator_count(&self) -> usize {
        self.actuators.len() - 6 * self.wrench_bodies.len()
    }

    /// MuJoCo's na: the actuators' activation states (one per actuator
    /// with activation dynamics, in actuator order).
    pub fn activation_count(&self) -> usize {
        self.actuators.iter().filter(|a| a.activation.is_some()).count()
    }

    /// Whether pass 3's recursion of passive forces has anything to carry:
    /// gravity, joint springs or dampers, or a flexible body's modal stiffness.
    pub fn has_passive_forces(&self) -> bool {
        !self.shortcuts.no_passive_forces() || !self.flexible.is_empty()
    }

    /// Whether forces beyond the tree's passes act: the tendons' armature
    /// or constraint rows (`Workspace::apply_constraint_forces`).
    pub fn couples_beyond_tree(&self) -> bool {
        !self.tendon_inertia.is_empty() || !self.constraints.is_empty()
    }

    /// Each tendon's wraps, as its range of the model's in the order of the
    /// paths (`Workspace::wrap_paths`; empty for a fixed tendon).
    pub fn tendon_wraps(&self) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
        self.tendons.iter().scan(0, |first, tendon| {
            let count = match &tendon.path {
                Path::Spatial { stops } => stops.iter().filter(|stop| matches!(stop, PathStop::Geom { .. })).count(),
                Path::Fixed { .. } => 0,
            };
            let wraps = *first..*first + count;
            *first = wraps.end;
            Some(wraps)
        })
    }

    /// How many geoms the spatial tendons' paths wrap round.
    pub fn wrap_count(&self) -> usize {
        self.tendon_wraps().last().map_or(0, |wraps| wraps.end)
    }

    /// The wraps' switching functions, [`WRAP_SWITCHES`] per wrap
    /// (`Workspace::wrap_switching`).
    pub fn wrap_switches(&self) -> usize {
        WRAP_SWITCHES * self.wrap_count()
    }

    /// How many switches the dynamics have, the margins of
    /// [`crate::dynamics::mode::ConstraintMode`] and a model-exchange FMU's
    /// event indicators: the constraint forces' ([`Constraints::switch_count`]),
    /// then the wraps' ([`Model::wrap_switches`]).
    pub fn switch_count(&self) -> usize {
        self.constraints.switch_count() + self.wrap_switches()
    }
}

/// The first stage of compiling a vehicle: everything that needs no
/// evaluation of the dynamics. Its `model` is what the qpos0 stage
/// (`crate::compile`) evaluates; the constants that stage finds are left
/// out of it ([`Qpos0Constants`] lists them), and [`Tree::with_constants`]
/// makes the whole model from the two.
pub(crate) struct Tree {
    /// The model without its qpos0 constants: tendons' lengths and
    /// invweights 0 (spring lengths the file's, or 0), springdamper joints
    /// without stiffness and damping, damping ratios not yet dampings, no
    /// constraints (they are `constraints`).
    pub model: Model,
    /// The joints' and tendons' friction loss and limits, without the
    /// invweights and equalities the qpos0 stage adds.
    pub constraints: Constraints,
    /// Each body's frame on the link that carries it.
    pub attachments: Vec<Attachment>,
    /// Each site's frame on the link that carries it.
    pub sites: Vec<SiteFrame>,
}

/// What MuJoCo's compiler finds at qpos0 (its `mj_setConst`), as the qpos0
/// stage computes it for a [`Tree`].
#[derive(Debug, Default)]
pub(crate) struct Qpos0Constants {
    /// The stiffness and damping of the links of `springdamper` joints.
    pub spring_dampers: Vec<LinkSpringDamper>,
    /// Each tendon's length and invweight in qpos0 and its spring length.
    pub tendons: Vec<TendonConstants>,
    /// The damping (biasprm[2]) of each actuator with a damping ratio.
    pub actuator_dampings: Vec<(usize, f64)>,
    /// MuJoCo's `dof_invweight0`, when the model has constraints.
    pub dof_invweight0: Vec<f64>,
    /// The active equality constraints.
    pub equalities: Vec<CompiledEquality>,
}

/// A link's stiffness and damping derived from its joint's `springdamper`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LinkSpringDamper {
    /// The link.
    pub link: usize,
    /// Its stiffness.
    pub stiffness: f64,
    /// Its damping.
    pub damping: f64,
}

/// A tendon's constants from qpos0 and the spring pose.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TendonConstants {
    /// Its length in qpos0.
    pub length0: f64,
    /// J M⁻¹ Jᵀ in qpos0.
    pub invweight0: f64,
    /// Its spring length: the file's, or its length in the spring pose.
    pub spring_length: [f64; 2],
}

impl Tree {
    /// Compiles the structure of `vehicle` with external wrench inputs on
    /// the named bodies (see [`Model::wrench_bodies`]).
    pub(crate) fn compile(vehicle: &Vehicle, wrench_bodies: &[String]) -> Result<Tree, ModelError> {
        let bodies = BodyTree::of(vehicle)?;
        let nv = dof_count(&bodies.links);
        let sites = site_frames(vehicle, &bodies.attachments);
        let tendons = tendon::compile_tendons(vehicle, &bodies.joints, &sites, &bodies.attachments);
        let mut actuators = compile_actuators(vehicle, &bodies.links, &bodies.joints, &sites);
        for (k, name) in wrench_bodies.iter().enumerate() {
            // Two wrenches on one body would be two sets of inputs that add up:
            // MuJoCo's xfrc_applied is one wrench per body.
            if wrench_bodies[..k].contains(name) {
                return Err(ModelError::WrenchBody {
                    reason: format!("body '{name}' is named twice: a body takes one wrench (six inputs)"),
                });
            }
            actuators.extend(wrench_actuators(vehicle, &bodies.attachments, name)?);
        }
        let sensors = sensor::compile_sensors(vehicle, &bodies.joints, &bodies.attachments, &sites)?;
        let needs_interaction = sensors.iter().any(|s| matches!(s.source, SensorSource::Interaction { .. }));
        let needs_body_masses =
            needs_interaction || sensors.iter().any(|s| matches!(s.source, SensorSource::Subtree { .. }));
        let body_masses =
            if needs_body_masses { sensor::body_masses(vehicle, &bodies.attachments) } else { Vec::new() };
        let interaction_bodies = match needs_interaction {
            true => InteractionBodies::of(vehicle, wrench_bodies),
            false => InteractionBodies::default(),
        };
        let needs_quats = sensors.iter().any(|s| s.kind == SensorKind::FrameQuat);
        let link_tree_quats = if needs_quats { bodies.tree_quats } else { Vec::new() };
        let mjcf_joints = || vehicle.bodies.iter().flat_map(|body| &body.joints).zip(&bodies.joints);
        let actuator_force_limits = mjcf_joints()
            .filter_map(|(joint, info)| {
                joint.actuator_force_range.map(|range| DofForceLimit { dof: info.dof_adr, range })
            })
            .collect();
        let constraints = Constraints::of(vehicle, &bodies.joints)?;
        let actuator_gravcomp_dofs = mjcf_joints()
            .filter(|(joint, _)| joint.actuator_gravcomp)
            .flat_map(|(joint, info)| info.dof_adr..info.dof_adr + joint.kind.nv())
            .collect();
        let mut model = Model {
            name: vehicle.name.clone(),
            nq: bodies.qpos0.len(),
            nv,
            gravity: vehicle.gravity,
            magnetic: vehicle.magnetic,
            shortcuts: Shortcuts::of(&bodies.links, &vehicle.gravity),
            links: bodies.links,
            joints: bodies.joints,
            qpos0: bodies.qpos0,
            qpos_spring: bodies.qpos_spring,
            actuators,
            actuator_force_limits,
            actuation: vehicle.actuation,
            sensors,
            body_masses,
            link_tree_quats,
            wrench_bodies: wrench_bodies.to_vec(),
            constraints: Constraints::default(),
            interaction_bodies,
            sensors_disabled: vehicle.sensors_disabled,
            gravity_compensation: bodies.compensation.applied(vehicle, actuator_gravcomp_dofs),
            tendons,
            tendon_inertia: Vec::new(),
            flexible: Vec::new(),
        };
        model.tendon_inertia = tendon::inertia_terms(&model);
        add_flexible_bodies(&mut model, vehicle, &bodies.attachments, &bodies.welded, &constraints)?;
        common_nodes(&mut model, vehicle, &bodies.attachments);
        Ok(Tree { model, constraints, attachments: bodies.attachments, sites })
    }

    /// The whole model: the tree's with the constants found at qpos0.
    pub(crate) fn with_constants(self, constants: Qpos0Constants) -> Model {
        let mut model = self.model;
        for derived in constants.spring_dampers {
            model.links[derived.link].stiffness = derived.stiffness;
            model.links[derived.link].damping = derived.damping;
        }
        model.shortcuts = Shortcuts::of(&model.links, &model.gravity);
        for (tendon, found) in model.tendons.iter_mut().zip(constants.tendons) {
            (tendon.length0, tendon.invweight0, tendon.spring_length) =
                (found.length0, found.invweight0, found.spring_length);
        }
        for (actuator, damping) in constants.actuator_dampings {
            model.actuators[actuator].bias[2] = damping;
        }
        model.constraints = Constraints {
            dof_invweight0: constants.dof_invweight0,
            equalities: constants.equalities,
            ..self.constraints
        };
        model
    }
}

/// The modal bodies with modes, in `Model::flexible`'s order.
fn with_modes(vehicle: &Vehicle) -> impl Iterator<Item = &crate::flex::ModalBody> {
    vehicle.flexible.iter().filter(|f| !f.modes.is_empty())
}

/// The flexible bodies with modes of `vehicle` on their links, their modal
/// coordinates appended to θ and ν (zero in qpos0 and the spring pose).
/// Refuses the parts of a model that do not take modes in yet.
fn add_flexible_bodies(
    model: &mut Model,
    vehicle: &Vehicle,
    attachments: &[Attachment],
    welded: &[(NodeSite, SpatialMat)],
    constraints: &Constraints,
) -> Result<(), ModelError> {
    for (f, modal) in with_modes(vehicle).enumerate() {
        let body =
            vehicle.bodies.iter().position(|b| b.name == modal.body).expect("the importer names existing bodies");
        let at = attachments[body];
        let Some(link) = at.link else { return Err(ModelError::FlexibleOnWorld { body: modal.body.clone() }) };
        if let Some((node, _)) = at.node {
            let carrier = with_modes(vehicle).nth(node.flexible).expect("a flexible body with modes");
            return Err(ModelError::FlexibleWeldedAtNode {
                body: modal.body.clone(),
                carrier: carrier.body.clone(),
                node: carrier.nodes[node.node].name.clone(),
            });
        }
        // Children with joints at a node that some mode moves ride that node
        // (their first link's parent frame is the node's), and so do those of
        // the bodies welded at such a node.
        let mut children = Vec::new();
        for (c, child) in vehicle.bodies.iter().enumerate().filter(|(_, c)| !c.joints.is_empty()) {
            let Some(parent) = child.parent else { continue };
            let node = match attachments[parent].node {
                Some((node, _)) => Some(node.node).filter(|_| node.flexible == f),
                None if parent == body => (0..modal.nodes.len())
                    .find(|&j| (modal.nodes[j].position - child.pos).norm() <= NODE_SITE_DISTANCE && moves(modal, j)),
                None => None,
            };
            let Some(j) = node else { continue };
            // The child's first link: up from its last while the parent is not the body's link.
            let mut first = attachments[c].link.expect("a child with joints has links");
            while let Some(p) = model.links[first].parent.filter(|&p| p != link) {
                first = p;
            }
            children.push((first, j));
        }
        let unsupported = [
            (!model.tendons.is_empty(), "tendons"),
            (!constraints.is_empty() || !vehicle.equalities.is_empty(), "joint limits, friction loss and equalities"),
            (
                !model.gravity_compensation.is_empty()
                    || vehicle.bodies[body].gravcomp != 0.0
                    || vehicle.bodies.iter().zip(attachments).any(|(b, at)| at.node.is_some() && b.gravcomp != 0.0),
                "gravity compensation",
            ),
            (!model.body_masses.is_empty(), "subtree, force and torque sensors"),
        ];
        if let Some((_, feature)) = unsupported.into_iter().find(|(has, _)| *has) {
            return Err(ModelError::FlexibleWith { body: modal.body.clone(), feature });
        }
        let modes = modal.modes.len();
        let on_link = flexible::on_link(modal, &at.offset);
        for &(first, j) in &children {
            // Relative to the undeformed node frame: R's axes, origin at the node.
            let node_to_link = Transform::from_pose(&Mat3::identity(), &-on_link.nodes[j].position);
            model.links[first].x_tree = model.links[first].x_tree.compose(&node_to_link);
        }
        let welded: Vec<(usize, SpatialMat)> =
            welded.iter().filter(|(node, _)| node.flexible == f).map(|(node, inertia)| (node.node, *inertia)).collect();
        model.flexible.push(FlexBody::new(link, model.nq, model.nv, on_link, &children, &welded));
        model.nq += modes;
        model.nv += modes;
        model.qpos0.extend(std::iter::repeat_n(0.0, modes));
        model.qpos_spring.extend(std::iter::repeat_n(0.0, modes));
    }
    Ok(())
}

/// The node each reference-site pair hangs from on its common link (both
/// sites on bodies welded at that node, or below children at it): its
/// modes move both, so the pair's couple is cancelled there, as MuJoCo
/// clears the dofs that move both sites. A site of the flexible body itself
/// at the node is on that body, not hanging from it.
fn common_nodes(model: &mut Model, vehicle: &Vehicle, attachments: &[Attachment]) {
    for (given, compiled) in vehicle.actuators.iter().zip(model.actuators.iter_mut()) {
        let (
            Transmission::Site { site, refsite: Some(reference) },
            ActuatorTransmission::RelativeSite { common_link: Some(common), common_node, .. },
        ) = (&given.transmission, &mut compiled.transmission)
        else {
            continue;
        };
        let hangs_from = |k: usize| -> Option<NodeSite> {
            let body = vehicle.sites[k].body?;
            let link = attachments[body].link?;
            if link == *common {
                return attachments[body].node.map(|(node, _)| node);
            }
            let mut first = link;
            while let Some(p) = model.links[first].parent.filter(|p| p != common) {
                first = p;
            }
            model.links[first].parent?;
            model.flexible.iter().enumerate().filter(|(_, f)| f.link == *common).find_map(|(f, flexible)| {
                let child = flexible.node_children.iter().find(|c| c.link == first)?;
                Some(NodeSite { flexible: f, node: flexible.rotating[child.slot] })
            })
        };
        *common_node = hangs_from(*site).filter(|node| hangs_from(*reference) == Some(*node));
    }
}

/// The links of a vehicle's bodies and joints, and where each body and
/// coordinate is on them.
struct BodyTree {
    links: Vec<Link>,
    joints: Vec<JointInfo>,
    qpos0: Vec<f64>,
    qpos_spring: Vec<f64>,
    /// Each body's frame on its link.
    attachments: Vec<Attachment>,
    /// Each link's `x_tree` rotation as MuJoCo composes `xquat`.
    tree_quats: Vec<Quat>,
    compensation: GravityCompensation,
    /// The spatial inertias of the bodies welded at nodes, about their
    /// node's origin in the link's axes.
    welded: Vec<(NodeSite, SpatialMat)>,
}

/// The node that a body without joints, child of body `parent` at `pos` in
/// its frame, is welded at: its parent's, or a node of the flexible body
/// `parent` within [`NODE_SITE_DISTANCE`] of `pos` that some mode moves
/// (a child at a node no mode moves, or at no node, is fixed to R).
fn welded_node(vehicle: &Vehicle, attachments: &[Attachment], parent: usize, pos: &Vec3) -> Option<(NodeSite, Vec3)> {
    let at = attachments[parent];
    if at.node.is_some() {
        return at.node;
    }
    let name = &vehicle.bodies[parent].name;
    let (f, modal) = with_modes(vehicle).enumerate().find(|(_, modal)| &modal.body == name)?;
    let j = (0..modal.nodes.len())
        .find(|&j| (modal.nodes[j].position - pos).norm() <= NODE_SITE_DISTANCE && moves(modal, j))?;
    let origin = at.offset.trans + at.offset.rot.transpose() * modal.nodes[j].position;
    Some((NodeSite { flexible: f, node: j }, origin))
}

/// Whether some mode of `modal` moves its node `j`.
fn moves(modal: &crate::flex::ModalBody, j: usize) -> bool {
    modal.modes.iter().any(|mode| mode.translation[j] != Vec3::zeros() || mode.rotation[j] != Vec3::zeros())
}

impl BodyTree {
    /// Links for the joints of `vehicle`'s bodies, in body order (MuJoCo's dof order).
    fn of(vehicle: &Vehicle) -> Result<BodyTree, ModelError> {
        let mut tree = BodyTree {
            links: Vec::new(),
            joints: Vec::new(),
            qpos0: Vec::new(),
            qpos_spring: Vec::new(),
            attachments: Vec::with_capacity(vehicle.bodies.len()),
            tree_quats: Vec::new(),
            compensation: GravityCompensation::default(),
            welded: Vec::new(),
        };
        for body in &vehicle.bodies {
            let parent = match body.parent {
                Some(p) => tree.attachments[p],
                None => Attachment::at(None),
            };
            let body_in_parent = Transform::from_pose(&body.quat.to_rotation_matrix().into_inner(), &body.pos);
            // The body frame before its joints move it, relative to the parent link.
            let mut inboard = Attachment {
                link: parent.link,
                offset: body_in_parent.compose(&parent.offset),
                quat: parent.quat * body.quat,
                node: None,
            };
            if body.joints.is_empty() {
                inboard.node = body.parent.and_then(|p| welded_node(vehicle, &tree.attachments, p, &body.pos));
            }
            for joint in &body.joints {
                inboard = tree.add_joint(body, joint, inboard)?;
            }
            // A flexible body's nodes carry its mass, in the passes' modal
            // block, and so does a node the mass of a body welded at it.
            let flexible = vehicle.flexible.iter().any(|f| f.body == body.name && !f.modes.is_empty());
            match (&body.inertia, inboard.link, inboard.node) {
                (Some(mass_props), Some(_), Some((node, origin))) => {
                    let inertia = rigid_inertia(mass_props.mass, &mass_props.com, &mass_props.inertia);
                    // ᵇX_ₙ = ᵇX_ₗ ˡX_ₙ, the node frame n at `origin` in link axes.
                    let in_node = inboard.offset.compose(&Transform::from_pose(&Mat3::identity(), &-origin));
                    let mut about_node = SpatialMat::zeros();
                    in_node.add_inertia_to_parent(&inertia, &mut about_node, true);
                    tree.welded.push((node, about_node));
                }
                (Some(mass_props), Some(link), None) if !flexible => {
                    tree.add_body_inertia(link, &inboard, mass_props, body.gravcomp);
                }
                _ => {}
            }
            tree.attachments.push(inboard);
        }
        if tree.links.is_empty() {
            return Err(ModelError::NoJoints);
        }
        Ok(tree)
    }

    /// Adds the link (or, for a free joint, two links) of `joint` of `body`
    /// at `inboard`; returns the frame the next joint or the body is on.
    fn add_joint(
        &mut self,
        body: &crate::vehicle::Body,
        joint: &crate::vehicle::Joint,
        inboard: Attachment,
    ) -> Result<Attachment, ModelError> {
        for (what, value) in [("armature", joint.armature), ("stiffness", joint.stiffness), ("damping", joint.damping)]
        {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ModelError::BadParameter { joint: joint.name.clone(), what, value });
            }
        }
        let qpos_adr = self.qpos0.len();
        let links = &mut self.links;
        self.joints.push(JointInfo {
            name: joint.name.clone(),
            body_name: body.name.clone(),
            kind: joint.kind,
            qpos_adr,
            dof_adr: dof_count(links),
        });
        let link = match joint.kind {
            JointKind::Hinge | JointKind::Slide => {
                let kind = if joint.kind == JointKind::Hinge { LinkJoint::Hinge } else { LinkJoint::Slide };
                let k = push_link(links, qpos_adr, joint, &body.name, kind, inboard);
                self.tree_quats.push(inboard.quat);
                links[k].reference = joint.reference;
                self.qpos0.push(joint.reference);
                self.qpos_spring.push(joint.springref);
                k
            }
            JointKind::Ball => {
                let k = push_link(links, qpos_adr, joint, &body.name, LinkJoint::Ball, inboard);
                self.tree_quats.push(inboard.quat);
                self.qpos0.extend([1.0, 0.0, 0.0, 0.0]);
                self.qpos_spring.extend([1.0, 0.0, 0.0, 0.0]);
                k
            }
            JointKind::Free => {
                if body.parent.is_some() || body.joints.len() != 1 {
                    return Err(ModelError::MisplacedFreeJoint { joint: joint.name.clone(), line: joint.line });
                }
                // qpos holds the body pose in world directly: the tree offset is absorbed.
                let world = Attachment::at(None);
                let t = push_link(links, qpos_adr, joint, &body.name, LinkJoint::Translation, world);
                let r = push_link(links, qpos_adr + 3, joint, &body.name, LinkJoint::Ball, Attachment::at(Some(t)));
                self.tree_quats.extend([Quat::identity(), Quat::identity()]);
                let q = body.quat;
                let pose = [body.pos.x, body.pos.y, body.pos.z, q.w, q.i, q.j, q.k];
                self.qpos0.extend(pose);
                self.qpos_spring.extend(pose);
                r
            }
        };
        Ok(Attachment::at(Some(link)))
    }

    /// Adds the mass properties of a body whose frame is `at` to its link.
    fn add_body_inertia(&mut self, link: usize, at: &Attachment, mass_props: &MassProperties, gravcomp: f64) {
        let inertia = rigid_inertia(mass_props.mass, &mass_props.com, &mass_props.inertia);
        let l = &mut self.links[link];
        // The body frame is ᵇX_ₗ = offset relative to the link: bring its inertia to the link frame.
        let mut in_link = SpatialMat::zeros();
        at.offset.add_inertia_to_parent(&inertia, &mut in_link, true);
        l.rotational_inertia += in_link.fixed_view::<3, 3>(0, 0);
        l.mass += mass_props.mass;
        let com = at.offset.trans + at.offset.rot.transpose() * mass_props.com;
        l.mass_moment += mass_props.mass * com;
        self.compensation.add_body(link, gravcomp, mass_props.mass, &com);
    }
}
/// How close a site must be to a node of a flexible body to ride it, and
/// a child body's frame to be taken as at the node (m).
pub const NODE_SITE_DISTANCE: f64 = 1e-6;

/// The sites' frames on the links that carry them (`attachments`, per
/// body). A site of a flexible body within [`NODE_SITE_DISTANCE`] of one of
/// its nodes rides that node (docs/flexible.md, "Sites at nodes"), and so
/// does every site of a body welded at a node.
fn site_frames(vehicle: &Vehicle, attachments: &[Attachment]) -> Vec<SiteFrame> {
    vehicle
        .sites
        .iter()
        .map(|site| {
            let in_body = Transform::from_pose(&site.quat.to_rotation_matrix().into_inner(), &site.pos);
            let Some(body) = site.body else { return SiteFrame { link: None, frame: in_body, node: None } };
            let at = attachments[body];
            let name = &vehicle.bodies[body].name;
            let node = with_modes(vehicle).enumerate().filter(|(_, f)| &f.body == name).find_map(|(f, modal)| {
                let j = modal.nodes.iter().position(|n| (n.position - site.pos).norm() <= NODE_SITE_DISTANCE)?;
                // The node's frame at rest: its origin, the link's axes.
                let origin = at.offset.trans + at.offset.rot.transpose() * modal.nodes[j].position;
                Some((NodeSite { flexible: f, node: j }, origin))
            });
            // A body welded at a node carries its sites on that node.
            let carrier = match node {
                Some(node) => Attachment { node: Some(node), ..at },
                None => at,
            };
            carrier.frame(&in_body)
        })
        .collect()
}

/// The actuators of `vehicle` with their transmissions resolved: joints into
/// dof and θ addresses, sites into their frames on links. The importer has
/// checked every name.
fn compile_actuators(vehicle: &Vehicle, links: &[Link], joints: &[JointInfo], sites: &[SiteFrame]) -> Vec<Actuator> {
    let joint_index: HashMap<&str, &JointInfo> = joints.iter().map(|j| (j.name.as_str(), j)).collect();
    let site_name = |k: usize| vehicle.sites[k].name.clone().unwrap_or_default();
    vehicle
        .actuators
        .iter()
        .map(|actuator| {
            let (target, transmission) = match &actuator.transmission {
                Transmission::Joint { joint, in_parent } => {
                    let info = joint_index[joint.as_str()];
                    let (dof, qpos, in_parent) = (info.dof_adr, info.qpos_adr, *in_parent);
                    let transmission = match info.kind {
                        JointKind::Hinge | JointKind::Slide => ActuatorTransmission::Scalar { dof, qpos },
                        JointKind::Ball => ActuatorTransmission::Ball { dof, qpos, in_parent },
                        JointKind::Free => ActuatorTransmission::Free { dof, qpos: qpos + 3, in_parent },
                    };
                    let attribute = if in_parent { "jointinparent" } else { "joint" };
                    (ActuatorTarget { attribute: attribute.into(), name: joint.clone(), refsite: None }, transmission)
                }
                Transmission::Tendon { tendon } => {
                    let name = vehicle.tendons[*tendon].name.clone().unwrap_or_default();
                    let target = ActuatorTarget { attribute: "tendon".into(), name, refsite: None };
                    (target, ActuatorTransmission::Tendon { tendon: *tendon })
                }
                Transmission::Site { site, refsite } => {
                    let transmission = match refsite {
                        None => ActuatorTransmission::Site { site: sites[*site] },
                        Some(reference) => ActuatorTransmission::RelativeSite {
                            site: sites[*site],
                            reference: sites[*reference],
                            common_link: common_link(links, sites[*site].link, sites[*reference].link),
                            common_node: None,
                        },
                    };
                    let target = ActuatorTarget {
                        attribute: "site".into(),
                        name: site_name(*site),
                        refsite: refsite.map(site_name),
                    };
                    (target, transmission)
                }
            };
            let mut compiled = Actuator {
                name: actuator.name.clone(),
                kind: actuator.kind,
                target,
                transmission,
                gear: actuator.gear,
                gain_type: actuator.gain_type,
                gain: actuator.gain,
                bias_type: actuator.bias_type,
                bias: actuator.bias,
                ctrl_range: actuator.ctrl_range,
                force_range: actuator.force_range,
                activation: actuator.activation,
                enabled: !actuator.group_disabled,
                setpoint_period: 0.0,
                line: actuator.line,
            };
            compiled.setpoint_period = setpoint_period(&compiled);
            compiled
        })
        .collect()
}

/// The six actuators of a wrench input on body `name`: unit forces along
/// the world's axes at the body's centre of mass (MuJoCo's `xipos`), then
/// unit torques about them. Each is a site transmission measured in the
/// world's frame (a reference site fixed to the world takes no reaction),
/// which is exactly MuJoCo's `xfrc_applied`.
fn wrench_actuators(vehicle: &Vehicle, attachments: &[Attachment], name: &str) -> Result<Vec<Actuator>, ModelError> {
    let Some(index) = vehicle.bodies.iter().position(|b| b.name == name) else {
        let known: Vec<&str> = vehicle.bodies.iter().map(|b| b.name.as_str()).collect();
        return Err(ModelError::WrenchBody {
            reason: format!("no body '{name}' in the vehicle (its bodies: {})", known.join(", ")),
        });
    };
    let at = attachments[index];
    if at.link.is_none() {
        return Err(ModelError::WrenchBody {
            reason: format!("body '{name}' is fixed to the world: a wrench on it moves nothing"),
        });
    }
    let centre = Transform::from_pose(&Mat3::identity(), &vehicle.bodies[index].inertial_pos);
    let site = at.frame(&centre);
    let world = SiteFrame { link: None, frame: Transform::identity(), node: None };
    const COMPONENTS: [&str; 6] = ["force x", "force y", "force z", "torque x", "torque y", "torque z"];
    Ok(COMPONENTS
        .iter()
        .enumerate()
        .map(|(k, component)| {
            let mut gear = [0.0; 6];
            gear[k] = 1.0;
            Actuator {
                name: Some(format!("{component} on '{name}'")),
                kind: ActuatorKind::General,
                target: ActuatorTarget { attribute: "xfrc_applied".into(), name: name.to_string(), refsite: None },
                transmission: ActuatorTransmission::RelativeSite {
                    site,
                    reference: world,
                    common_link: None,
                    common_node: None,
                },
                gear,
                gain_type: GainType::Fixed,
                gain: [1.0, 0.0, 0.0],
                bias_type: BiasType::None,
                bias: [0.0; 3],
                ctrl_range: None,
                force_range: None,
                activation: None,
                enabled: true,
                setpoint_period: 0.0,
                line: 0,
            }
        })
        .collect())
}

/// MuJoCo's period of a position servo's setpoint on a rotation whose
/// length wraps: 2π·|rotation gear| on a ball joint, or on a reference site
/// with a purely rotational gear; 0 otherwise.
fn setpoint_period(actuator: &Actuator) -> f64 {
    if !actuator.is_position_servo() {
        return 0.0;
    }
    let turn = 2.0 * std::f64::consts::PI;
    match actuator.transmission {
        ActuatorTransmission::Ball { .. } => turn * actuator.gear_translation().norm(),
        ActuatorTransmission::RelativeSite { .. } if actuator.gear_translation() == Vec3::zeros() => {
            turn * actuator.gear_rotation().norm()
        }
        _ => 0.0,
    }
}

/// The deepest link that is `a` or an ancestor of it and `b` or an ancestor
/// of it; `None` when either is the world or they share no link.
fn common_link(links: &[Link], a: Option<usize>, b: Option<usize>) -> Option<usize> {
    let (mut a, mut b) = (a?, b?);
    // Parents precede their children: step up from the later of the two.
    while a != b {
        if a > b {
            a = links[a].parent?;
        } else {
            b = links[b].parent?;
        }
    }
    Some(a)
}

/// Dofs taken by `links`: the next link's first dof.
fn dof_count(links: &[Link]) -> usize {
    links.last().map_or(0, |l| l.dof_adr + l.ndof)
}

/// MuJoCo's smallest denominator (mjMINVAL).
pub(crate) const MIN_VALUE: f64 = 1e-15;

/// Appends the link of `joint` (of body `body_name`) attached at `inboard`;
/// returns its index. Free-joint halves have their anchor at the body origin.
fn push_link(
    links: &mut Vec<Link>,
    qpos_adr: usize,
    joint: &crate::vehicle::Joint,
    body_name: &str,
    joint_type: LinkJoint,
    inboard: Attachment,
) -> usize {
    let anchor = if joint.kind == JointKind::Free { Vec3::zeros() } else { joint.pos };
    let axis = match joint_type {
        LinkJoint::Hinge | LinkJoint::Slide => joint.axis,
        LinkJoint::Ball | LinkJoint::Translation => Vec3::zeros(),
    };
    let dof_adr = dof_count(links);
    let (ndof, motion_subspace) = motion_subspace(joint_type, &axis, &anchor);
    links.push(Link {
        joint_name: joint.name.clone(),
        body_name: body_name.to_string(),
        parent: inboard.link,
        x_tree: inboard.offset,
        joint: joint_type,
        axis,
        anchor,
        reference: 0.0,
        ndof,
        motion_subspace,
        qpos_adr,
        dof_adr,
        armature: joint.armature,
        stiffness: joint.stiffness,
        damping: joint.damping,
        rotational_inertia: Mat3::zeros(),
        mass: 0.0,
        mass_moment: Vec3::zeros(),
    });
    links.len() - 1
}

/// S for a joint, in the link frame (docs/DYNAMICS.md §2): a hinge through `anchor`
/// moves the link origin with velocity θ̇ (anchor × axis).
fn motion_subspace(joint: LinkJoint, axis: &Vec3, anchor: &Vec3) -> (usize, MotionSubspace) {
    let mut s = MotionSubspace::zeros();
    match joint {
        LinkJoint::Hinge => {
            s.fixed_view_mut::<3, 1>(0, 0).copy_from(axis);
            s.fixed_view_mut::<3, 1>(3, 0).copy_from(&anchor.cross(axis));
            (1, s)
        }
        LinkJoint::Slide => {
            s.fixed_view_mut::<3, 1>(3, 0).copy_from(axis);
            (1, s)
        }
        LinkJoint::Ball => {
            s.fixed_view_mut::<3, 3>(0, 0).copy_from(&Mat3::identity());
            s.fixed_view_mut::<3, 3>(3, 0).copy_from(&skew(anchor));
            (3, s)
        }
        LinkJoint::Translation => {
            s.fixed_view_mut::<3, 3>(3, 0).copy_from(&Mat3::identity());
            (3, s)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hinge body carrying a welded box, offset and rotated.
    const WELDED: &str = r#"<mujoco><worldbody><body name="arm" pos="0 0 1">
        <joint name="hinge" axis="0 1 0"/>
        <inertial pos="0.1 0.2 -0.3" mass="2" diaginertia="0.3 0.2 0.1"/>
        <body name="tool" pos="0.5 -0.1 0.2" euler="30 -20 45">
          <inertial pos="0.05 0 0.1" mass="0.7" fullinertia="0.02 0.03 0.04 0.001 -0.002 0.003"/>
        </body></body></worldbody></mujoco>"#;

    #[test]
    fn spatial_inertia_is_the_sum_of_the_links_bodies_in_its_frame() {
        let vehicle = crate::mjcf::parse_mjcf(WELDED).unwrap().vehicle;
        let model = Model::compile(&vehicle).unwrap();
        let link = &model.links[0];
        // Independently: each body's rigid inertia through a dense 6×6
        // motion transform (identity for the link's own body; for the tool,
        // its pose relative to the arm).
        let mut expected = SpatialMat::zeros();
        for body in &vehicle.bodies {
            let props = body.inertia.as_ref().unwrap();
            let x = match body.parent {
                Some(_) => {
                    Transform::from_pose(&body.quat.to_rotation_matrix().into_inner(), &body.pos).motion_matrix()
                }
                None => SpatialMat::identity(),
            };
            expected += x.transpose() * rigid_inertia(props.mass, &props.com, &props.inertia) * x;
        }
        assert!((link.spatial_inertia() - expected).abs().max() < 1e-14, "{}\n{}", link.spatial_inertia(), expected);
        let v = SpatialVec::new(0.3, -1.2, 0.7, 2.0, 0.4, -0.9);
        assert!((link.inertia_times(&v) - link.spatial_inertia() * v).abs().max() < 1e-14);
    }
}
