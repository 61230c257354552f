//! A vehicle as described by its MJCF file, with MuJoCo's semantics resolved:
//! defaults applied, angles in radians, orientations as unit quaternions,
//! inertia computed from geoms where the body has no `<inertial>`.
//!
//! This is what the importer produces and what [`crate::model::Model::compile`]
//! turns into the compiled model; it still mirrors the MJCF body tree
//! (bodies without joints are kept, several joints per body are allowed).
//! Actuators are kept as MuJoCo's general actuator they stand for, with their
//! transmission target named; the compiler resolves targets into dofs and links.

use crate::math::{Mat3, Quat, Real, Vec3};

/// A vehicle: the tree of moving and welded bodies below `<worldbody>`.
#[derive(Clone, Debug, PartialEq)]
pub struct Vehicle {
    /// The `model` attribute of `<mujoco>` (or "vehicle").
    pub name: String,
    /// Gravity in world coordinates (zero when `<flag gravity="disable"/>`).
    pub gravity: Vec3,
    /// The magnetic field in world coordinates (`<option magnetic>`), which magnetometers read.
    pub magnetic: Vec3,
    /// Bodies in MJCF document order (depth-first, parent before child),
    /// not including the world body.
    pub bodies: Vec<Body>,
    /// Sites in MJCF document order (MuJoCo's site order).
    pub sites: Vec<Site>,
    /// Actuators in MJCF document order (MuJoCo's actuator order, that of `ctrl`).
    pub actuators: Vec<Actuator>,
    /// Sensors in MJCF document order (MuJoCo's sensor order, that of `sensordata`).
    pub sensors: Vec<Sensor>,
    /// `<option>` settings for all actuators.
    pub actuation: Actuation,
    /// `<option>` settings of MuJoCo's constraint model.
    pub constraint_options: ConstraintOptions,
    /// Equality constraints in document order (MuJoCo's equality order).
    pub equalities: Vec<Equality>,
    /// `<flag sensor="disable"/>`: MuJoCo computes no sensor, and sensordata stays 0.
    pub sensors_disabled: bool,
    /// Tendons in document order (MuJoCo's tendon order).
    pub tendons: Vec<Tendon>,
    /// The bodies a modal data file makes flexible (docs/flexible.md), in body order.
    pub flexible: Vec<crate::flex::ModalBody>,
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
    /// The origin of the body's inertial frame in the body frame (MuJoCo's
    /// `body_ipos`), which sensors of objtype "body" measure.
    pub inertial_pos: Vec3,
    /// The inertial frame's orientation (MuJoCo's `body_iquat`). The importer
    /// always gives it (as written, or as MuJoCo's eigen-decomposition finds
    /// it for a full inertia tensor, several geoms or a mesh); `None` leaves
    /// it unknown, and sensors that measure its axes are then refused.
    pub inertial_quat: Option<Quat>,
    /// Whether the body's mass is left out because it is fixed to the
    /// world and its geoms' mass would come from sdf or height-field assets
    /// (which nudyn does not compute).
    pub mass_unknown: bool,
    /// The body's joints, in document order (MuJoCo applies them in this order).
    pub joints: Vec<Joint>,
    /// MuJoCo's `gravcomp`: a force of −gravcomp · mass · gravity at the
    /// centre of mass (its `qfrc_gravcomp`); 0 when MuJoCo computes no
    /// passive force (`<flag spring="disable" damper="disable"/>`).
    pub gravcomp: f64,
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
    /// MuJoCo's `springdamper`: when given, the compiled model's stiffness
    /// and damping come from the joint's inertia in qpos0 instead.
    pub springdamper: Option<SpringDamper>,
    /// Armature (rotor inertia) added to every dof of the joint.
    pub armature: f64,
    /// Limits of the total actuator force on the joint (MuJoCo's
    /// `actuatorfrcrange` when `actuatorfrclimited`; hinge and slide only).
    pub actuator_force_range: Option<[f64; 2]>,
    /// MuJoCo's `actuatorgravcomp`: the gravity compensation on the joint's
    /// dofs is an actuator force (inside `qfrc_actuator` and its limits),
    /// not a passive one.
    pub actuator_gravcomp: bool,
    /// Friction loss and limits: constraint forces.
    pub constraints: JointConstraints,
    /// Line of the joint element in the MJCF file (1-based).
    pub line: u32,
}

/// A joint's `springdamper`: a spring and damper that make the joint, with
/// its inertia in qpos0, a mass-spring-damper of this time constant and
/// damping ratio (MuJoCo's `AutoSpringDamper`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpringDamper {
    /// Time constant (s).
    pub time_constant: f64,
    /// Damping ratio.
    pub damping_ratio: f64,
    /// Whether the spring acts (not with `<flag spring="disable"/>`).
    pub spring: bool,
    /// Whether the damper acts (not with `<flag damper="disable"/>`).
    pub damper: bool,
}

/// One `<site>`: a frame fixed to a body, where actuators apply forces.
#[derive(Clone, Debug, PartialEq)]
pub struct Site {
    /// The site's name; sites without one cannot be referred to.
    pub name: Option<String>,
    /// Index of its body in [`Vehicle::bodies`]; `None` for a site of `<worldbody>`.
    pub body: Option<usize>,
    /// Position of the site frame in the body frame.
    pub pos: Vec3,
    /// Orientation of the site frame in the body frame.
    pub quat: Quat,
    /// Line of the `<site>` element in the MJCF file (1-based).
    pub line: u32,
}

/// The actuator element an actuator was written with (MuJoCo's `mjtActuator`,
/// the kinds nudyn models).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ActuatorKind {
    /// `<general>`.
    General,
    /// `<motor>`: force = ctrl.
    Motor,
    /// `<position>`: force = kp (ctrl − length) − kv velocity.
    Position,
    /// `<velocity>`: force = kv (ctrl − velocity).
    Velocity,
    /// `<damper>`: force = −kv velocity ctrl.
    Damper,
    /// `<intvelocity>`: act integrates ctrl (a velocity command);
    /// force = kp (act − length) − kv velocity.
    IntVelocity,
    /// `<cylinder>`: act follows ctrl (a pressure) with a time constant;
    /// force = area act + bias₀ + bias₁ length + bias₂ velocity.
    Cylinder,
}

impl ActuatorKind {
    /// The MJCF element name, also its JSON name.
    pub fn name(self) -> &'static str {
        match self {
            ActuatorKind::General => "general",
            ActuatorKind::Motor => "motor",
            ActuatorKind::Position => "position",
            ActuatorKind::Velocity => "velocity",
            ActuatorKind::Damper => "damper",
            ActuatorKind::IntVelocity => "intvelocity",
            ActuatorKind::Cylinder => "cylinder",
        }
    }
}

/// Where an actuator's force goes (MuJoCo's transmission).
#[derive(Clone, Debug, PartialEq)]
pub enum Transmission {
    /// `joint` or `jointinparent`: a generalized force on the joint's dofs.
    Joint {
        /// The joint's name.
        joint: String,
        /// `jointinparent`: the rotation axes of a ball or free joint's gear
        /// are in the parent frame (the world, for a free joint).
        in_parent: bool,
    },
    /// `site`: a force and torque at the site, along axes of the site frame,
    /// or with `refsite` of the reference site's frame, with the opposite
    /// force and torque on the reference site's body.
    Site {
        /// Index of the site in [`Vehicle::sites`].
        site: usize,
        /// Index of the reference site in [`Vehicle::sites`].
        refsite: Option<usize>,
    },
    /// `tendon`: the tendon's length times gear\[0\], its moment arms times gear\[0\].
    Tendon {
        /// Index of the tendon in [`Vehicle::tendons`].
        tendon: usize,
    },
}

/// How the gain of an actuator depends on its state (MuJoCo's `gaintype`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GainType {
    /// gain = gainprm\[0\].
    Fixed,
    /// gain = gainprm\[0\] + gainprm\[1\] length + gainprm\[2\] velocity.
    Affine,
}

/// How the bias of an actuator depends on its state (MuJoCo's `biastype`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BiasType {
    /// bias = 0.
    None,
    /// bias = biasprm\[0\] + biasprm\[1\] length + biasprm\[2\] velocity.
    Affine,
}

/// An actuator's activation dynamics (MuJoCo's `dyntype` of an actuator
/// with one activation state, act): its force then takes act for ctrl.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ActivationKind {
    /// act_dot = ctrl.
    Integrator,
    /// act_dot = (ctrl − act)/τ.
    Filter,
    /// The same filter; MuJoCo's Euler step integrates it exactly, which
    /// matters here only for `actearly`.
    FilterExact,
}

/// An actuator's activation state: its dynamics and how its force reads it.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Activation {
    /// `dyntype`.
    pub kind: ActivationKind,
    /// dynprm\[0\]: a filter's time constant τ (s).
    pub time_constant: f64,
    /// `actrange` when `actlimited`: act is kept within it.
    pub range: Option<[f64; 2]>,
    /// `actearly`: the force takes the activation one `timestep` ahead
    /// (MuJoCo's `mj_nextActivation`), so that ctrl acts without a step's delay.
    pub early: bool,
}

impl Activation {
    /// `act` within the range, if limited (MuJoCo's `mju_clip`, which a
    /// reversed range cannot make panic).
    pub fn clamp<S: Real>(&self, act: S) -> S {
        match self.range {
            Some([low, _]) if act.value() < low => S::from(low),
            Some([_, high]) if act.value() > high => S::from(high),
            _ => act,
        }
    }
}

/// One actuator as MuJoCo's general actuator: force = gain · ctrl + bias,
/// applied through its transmission scaled by `gear`.
#[derive(Clone, Debug, PartialEq)]
pub struct Actuator {
    /// The actuator's name, if it has one.
    pub name: Option<String>,
    /// The element it was written with.
    pub kind: ActuatorKind,
    /// Where the force goes.
    pub transmission: Transmission,
    /// `gear`: for a hinge or slide only the first entry; for a ball joint
    /// the first three (a rotation axis); for free joints and sites a
    /// translation axis then a rotation axis.
    pub gear: [f64; 6],
    /// `gaintype`.
    pub gain_type: GainType,
    /// The first three of `gainprm` (the only ones fixed and affine gains use).
    pub gain: [f64; 3],
    /// `biastype`.
    pub bias_type: BiasType,
    /// The first three of `biasprm`. As in MuJoCo, a positive `biasprm[2]`
    /// of a position-like actuator (gainprm\[0\] = −biasprm\[1\]) is a damping
    /// ratio, turned into a damping by [`crate::model::Model::compile`].
    pub bias: [f64; 3],
    /// `ctrlrange` when `ctrllimited` (resolved as MuJoCo does, including `autolimits`).
    pub ctrl_range: Option<[f64; 2]>,
    /// `forcerange` when `forcelimited`.
    pub force_range: Option<[f64; 2]>,
    /// The activation state, for `dyntype` integrator, filter and filterexact.
    pub activation: Option<Activation>,
    /// Whether `<option actuatorgroupdisable>` disables the actuator's group
    /// (its force is then 0, clamped to `forcerange`).
    pub group_disabled: bool,
    /// Line of the actuator element in the MJCF file (1-based).
    pub line: u32,
}

/// The sensor types nudyn models (MuJoCo's `mjtSensor`, by MJCF element).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SensorKind {
    /// A hinge or slide joint's position.
    JointPos,
    /// A hinge or slide joint's velocity.
    JointVel,
    /// A ball joint's unit quaternion.
    BallQuat,
    /// A ball joint's angular velocity (its three dofs).
    BallAngVel,
    /// An object's position (in the world, or in the reference frame).
    FramePos,
    /// An object's orientation quaternion.
    FrameQuat,
    /// An object's x axis.
    FrameXAxis,
    /// An object's y axis.
    FrameYAxis,
    /// An object's z axis.
    FrameZAxis,
    /// An object's linear velocity.
    FrameLinVel,
    /// An object's angular velocity.
    FrameAngVel,
    /// An object's linear acceleration, gravity included as an accelerometer feels it.
    FrameLinAcc,
    /// An object's angular acceleration.
    FrameAngAcc,
    /// A subtree's centre of mass.
    SubtreeCom,
    /// The velocity of a subtree's centre of mass.
    SubtreeLinVel,
    /// A subtree's angular momentum about its centre of mass.
    SubtreeAngMom,
    /// A site's angular velocity in the site frame.
    Gyro,
    /// A site's linear velocity in the site frame.
    Velocimeter,
    /// A site's linear acceleration in the site frame, gravity included.
    Accelerometer,
    /// The force the site's body takes from its parent (MuJoCo's
    /// `cfrc_int`), in the site frame.
    Force,
    /// The torque the site's body takes from its parent, about the site,
    /// in the site frame.
    Torque,
    /// The magnetic field (`<option magnetic>`) in the site frame.
    Magnetometer,
    /// An actuator's force.
    ActuatorFrc,
    /// The actuators' total force on a hinge or slide joint.
    JointActuatorFrc,
    /// A joint's distance to its active limit less the margin (0 with no active limit row).
    JointLimitPos,
    /// The velocity of a joint's active limit row.
    JointLimitVel,
    /// The force of a joint's active limit row.
    JointLimitFrc,
    /// A tendon's length.
    TendonPos,
    /// A tendon's velocity.
    TendonVel,
    /// The total force of the actuators on a tendon (their scalar forces).
    TendonActuatorFrc,
    /// A tendon's distance to its active limit less the margin (0 with no active limit row).
    TendonLimitPos,
    /// The velocity of a tendon's active limit row.
    TendonLimitVel,
    /// The force of a tendon's active limit row.
    TendonLimitFrc,
    /// An actuator's length.
    ActuatorPos,
    /// An actuator's velocity.
    ActuatorVel,
    /// The simulation time.
    Clock,
}

impl SensorKind {
    /// Every kind, in MuJoCo's `mjtSensor` order.
    pub const ALL: [SensorKind; 36] = {
        use SensorKind::*;
        [
            Accelerometer,
            Velocimeter,
            Gyro,
            Force,
            Torque,
            Magnetometer,
            JointPos,
            JointVel,
            ActuatorPos,
            ActuatorVel,
            ActuatorFrc,
            JointActuatorFrc,
            JointLimitPos,
            JointLimitVel,
            JointLimitFrc,
            TendonPos,
            TendonVel,
            TendonActuatorFrc,
            TendonLimitPos,
            TendonLimitVel,
            TendonLimitFrc,
            BallQuat,
            BallAngVel,
            FramePos,
            FrameQuat,
            FrameXAxis,
            FrameYAxis,
            FrameZAxis,
            FrameLinVel,
            FrameAngVel,
            FrameLinAcc,
            FrameAngAcc,
            SubtreeCom,
            SubtreeLinVel,
            SubtreeAngMom,
            Clock,
        ]
    };

    /// The MJCF element name, also its JSON name.
    pub fn name(self) -> &'static str {
        use SensorKind::*;
        match self {
            JointPos => "jointpos",
            JointVel => "jointvel",
            BallQuat => "ballquat",
            BallAngVel => "ballangvel",
            FramePos => "framepos",
            FrameQuat => "framequat",
            FrameXAxis => "framexaxis",
            FrameYAxis => "frameyaxis",
            FrameZAxis => "framezaxis",
            FrameLinVel => "framelinvel",
            FrameAngVel => "frameangvel",
            FrameLinAcc => "framelinacc",
            FrameAngAcc => "frameangacc",
            SubtreeCom => "subtreecom",
            SubtreeLinVel => "subtreelinvel",
            SubtreeAngMom => "subtreeangmom",
            Gyro => "gyro",
            Velocimeter => "velocimeter",
            Accelerometer => "accelerometer",
            Force => "force",
            Torque => "torque",
            Magnetometer => "magnetometer",
            ActuatorFrc => "actuatorfrc",
            JointActuatorFrc => "jointactuatorfrc",
            JointLimitPos => "jointlimitpos",
            JointLimitVel => "jointlimitvel",
            JointLimitFrc => "jointlimitfrc",
            TendonPos => "tendonpos",
            TendonVel => "tendonvel",
            TendonActuatorFrc => "tendonactuatorfrc",
            TendonLimitPos => "tendonlimitpos",
            TendonLimitVel => "tendonlimitvel",
            TendonLimitFrc => "tendonlimitfrc",
            ActuatorPos => "actuatorpos",
            ActuatorVel => "actuatorvel",
            Clock => "clock",
        }
    }

    /// The kind an MJCF element stands for.
    pub fn from_name(tag: &str) -> Option<SensorKind> {
        SensorKind::ALL.into_iter().find(|kind| kind.name() == tag)
    }

    /// Number of sensordata entries.
    pub fn dim(self) -> usize {
        use SensorKind::*;
        match self {
            JointPos | JointVel | ActuatorFrc | JointActuatorFrc | ActuatorPos | ActuatorVel | Clock => 1,
            JointLimitPos | JointLimitVel | JointLimitFrc => 1,
            TendonPos | TendonVel | TendonActuatorFrc | TendonLimitPos | TendonLimitVel | TendonLimitFrc => 1,
            BallQuat | FrameQuat => 4,
            _ => 3,
        }
    }

    /// Whether the values are unit vectors or quaternions (MuJoCo's axis and
    /// quaternion data types), to which MuJoCo applies no cutoff.
    pub fn is_direction(self) -> bool {
        use SensorKind::*;
        matches!(self, BallQuat | FrameQuat | FrameXAxis | FrameYAxis | FrameZAxis)
    }
}

/// Which frame of an object a frame sensor measures (MuJoCo's `objtype`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameObject {
    /// A body's inertial frame (objtype "body"); `None`: the world body.
    Body(Option<usize>),
    /// A body's own frame (objtype "xbody"); `None`: the world body.
    XBody(Option<usize>),
    /// A site (objtype "site").
    Site(usize),
}

/// What a sensor measures.
#[derive(Clone, Debug, PartialEq)]
pub enum SensorTarget {
    /// A joint, by name.
    Joint(String),
    /// An actuator, by index in [`Vehicle::actuators`].
    Actuator(usize),
    /// A frame, with the frame it is measured in (`reftype`/`refname`), if any.
    Frame {
        /// The frame measured.
        object: FrameObject,
        /// The reference frame.
        reference: Option<FrameObject>,
    },
    /// The subtree of a body (`None`: the world body, the whole vehicle).
    Subtree(Option<usize>),
    /// A tendon, by index in [`Vehicle::tendons`].
    Tendon(usize),
    /// Nothing (the clock).
    None,
}

/// One sensor.
#[derive(Clone, Debug, PartialEq)]
pub struct Sensor {
    /// The sensor's name, if it has one.
    pub name: Option<String>,
    /// Its type.
    pub kind: SensorKind,
    /// What it measures.
    pub target: SensorTarget,
    /// MuJoCo's `cutoff`: when positive, each value is clamped to ±cutoff.
    pub cutoff: f64,
    /// Line of the sensor element in the MJCF file (1-based).
    pub line: u32,
}

/// `<option>` settings that apply to all actuators.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Actuation {
    /// `<flag actuation="disable"/>` turns every actuator force off.
    pub enabled: bool,
    /// `<flag clampctrl="disable"/>` turns the clamping of ctrl to `ctrlrange` off.
    pub clamp_ctrl: bool,
}

impl Default for Actuation {
    /// MuJoCo's defaults: actuation on, ctrl clamped.
    fn default() -> Self {
        Actuation { enabled: true, clamp_ctrl: true }
    }
}

/// MuJoCo's soft-constraint parameters of one constraint: `solref`
/// (time constant and damping ratio, or stiffness and damping when
/// negative) and `solimp` (the impedance's dmin, dmax, width, midpoint,
/// power).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SoftConstraint {
    /// `solref`.
    pub solref: [f64; 2],
    /// `solimp`.
    pub solimp: [f64; 5],
}

impl Default for SoftConstraint {
    /// MuJoCo's defaults: solref (0.02, 1), solimp (0.9, 0.95, 0.001, 0.5, 2).
    fn default() -> Self {
        SoftConstraint { solref: [0.02, 1.0], solimp: [0.9, 0.95, 0.001, 0.5, 2.0] }
    }
}

/// A joint's constraint forces, as MuJoCo builds them from its attributes
/// and the `<flag>`s that leave them on.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct JointConstraints {
    /// `frictionloss` on each of the joint's dofs (N m or N); 0 for none.
    pub frictionloss: f64,
    /// `solreffriction`, `solimpfriction`.
    pub friction: SoftConstraint,
    /// The joint's limits, when it is limited (hinge, slide and ball).
    pub limit: Option<JointLimit>,
}

/// A joint's `range` as a constraint: one-sided, active within `margin`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointLimit {
    /// `range` in rad or m (a ball joint limits its rotation angle by the larger value).
    pub range: [f64; 2],
    /// `margin`: the distance to the limit at which the constraint becomes active.
    pub margin: f64,
    /// `solreflimit`, `solimplimit`.
    pub soft: SoftConstraint,
}

/// One `<equality>` constraint.
#[derive(Clone, Debug, PartialEq)]
pub struct Equality {
    /// Its name, if it has one.
    pub name: Option<String>,
    /// What it holds together.
    pub kind: EqualityKind,
    /// `active`: whether it acts from the start (nudyn cannot switch it later).
    pub active: bool,
    /// `solref`, `solimp`.
    pub soft: SoftConstraint,
    /// Line of the element in the MJCF file (1-based).
    pub line: u32,
}

/// The two frames a connect or weld constraint holds together.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EqualityObjects {
    /// Two bodies (indices into [`Vehicle::bodies`]; `None` for the world).
    Bodies(Option<usize>, Option<usize>),
    /// Two sites (indices into [`Vehicle::sites`]).
    Sites(usize, usize),
}

/// The kinds of equality constraint nudyn models.
#[derive(Clone, Debug, PartialEq)]
pub enum EqualityKind {
    /// `<connect>`: a point of each frame held together (a ball joint closing a loop).
    Connect {
        /// The frames.
        objects: EqualityObjects,
        /// `anchor`: the point in body1's frame (body semantics only).
        anchor: Vec3,
    },
    /// `<weld>`: the frames held at a fixed relative pose.
    Weld {
        /// The frames.
        objects: EqualityObjects,
        /// `anchor`: the point in body2's frame (body semantics only).
        anchor: Vec3,
        /// `relpose`: body2's pose in body1's frame; `None` (a zero
        /// quaternion) takes the pose of qpos0.
        relpose: Option<(Vec3, Quat)>,
        /// `torquescale`: the weight of the rotation rows.
        torquescale: f64,
    },
    /// `<joint>`: joint1's value a quartic of joint2's, both from qpos0.
    Joint {
        /// `joint1`.
        joint1: String,
        /// `joint2`, if given.
        joint2: Option<String>,
        /// `polycoef`.
        polycoef: [f64; 5],
    },
    /// `<tendon>`: tendon1's length a quartic of tendon2's, both from their
    /// lengths in qpos0.
    Tendon {
        /// `tendon1`, by index in [`Vehicle::tendons`].
        tendon1: usize,
        /// `tendon2`, if given.
        tendon2: Option<usize>,
        /// `polycoef`.
        polycoef: [f64; 5],
    },
}

/// One `<tendon>` element: `<fixed>` or `<spatial>`.
#[derive(Clone, Debug, PartialEq)]
pub struct Tendon {
    /// Its name, if it has one.
    pub name: Option<String>,
    /// Its path.
    pub path: TendonPath,
    /// `stiffness` (N/m, or N m per unit of a fixed tendon's length).
    pub stiffness: f64,
    /// `damping`.
    pub damping: f64,
    /// `armature`: the inertia a·L̇² / 2 of the tendon itself (MuJoCo adds
    /// a·JᵀJ to the mass matrix).
    pub armature: f64,
    /// `actuatorfrcrange` when limited: MuJoCo scales the forces of the
    /// tendon's actuators alike to bring their sum into it.
    pub actuator_force_range: Option<[f64; 2]>,
    /// `springlength`: the deadband of lengths at which the spring is at
    /// rest (one value: a point); `None` (MuJoCo's −1) takes the tendon's
    /// length in the spring pose (qpos_spring).
    pub spring_length: Option<[f64; 2]>,
    /// `frictionloss`: a friction-loss constraint row when positive.
    pub frictionloss: f64,
    /// `solreffriction`, `solimpfriction`.
    pub friction: SoftConstraint,
    /// The tendon's length limits, when it is limited.
    pub limit: Option<JointLimit>,
    /// `range` as written (an actuator's `inheritrange` reads it).
    pub range: [f64; 2],
    /// Line of the element in the MJCF file (1-based).
    pub line: u32,
}

/// The path a tendon's length is measured along.
#[derive(Clone, Debug, PartialEq)]
pub enum TendonPath {
    /// `<fixed>`: Σ coef · qpos over hinge and slide joints, by name.
    Fixed(Vec<(String, f64)>),
    /// `<spatial>`: straight segments between consecutive sites, pulleys
    /// splitting the path into branches.
    Spatial(Vec<PathPoint>),
}

/// One element of a spatial tendon's path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PathPoint {
    /// A site, by index in [`Vehicle::sites`].
    Site(usize),
    /// `<geom geom>`: the segment between the sites around it wraps
    /// around this sphere or cylinder.
    Geom(WrapGeom),
    /// `<pulley divisor>`: a new branch; the lengths after it count 1/divisor.
    Pulley(f64),
}

/// A sphere or cylinder geom a tendon wraps around.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WrapGeom {
    /// Index of its body in [`Vehicle::bodies`]; `None` for the world body.
    pub body: Option<usize>,
    /// Position in the body frame.
    pub pos: Vec3,
    /// Orientation in the body frame (a cylinder's axis is its z).
    pub quat: Quat,
    /// `size[0]`: the radius.
    pub radius: f64,
    /// A cylinder (else a sphere).
    pub cylinder: bool,
    /// In a tendon's path, its `sidesite` (index in [`Vehicle::sites`]), on
    /// the geom's body and outside it: the tendon goes round the geom as
    /// the polyline from the first site through it to the second does.
    pub side: Option<usize>,
}

/// The kinds of constraint a user can leave out of a model, as MuJoCo's
/// `<flag equality|frictionloss|limit="disable">` leave them out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConstraintKind {
    /// Equality constraints.
    Equality,
    /// Joint friction loss.
    FrictionLoss,
    /// Joint limits.
    Limit,
}

impl ConstraintKind {
    /// Every kind, by its flag's name.
    pub const ALL: [(&str, ConstraintKind); 3] = [
        ("equality", ConstraintKind::Equality),
        ("frictionloss", ConstraintKind::FrictionLoss),
        ("limit", ConstraintKind::Limit),
    ];
}

impl std::str::FromStr for ConstraintKind {
    type Err = String;

    fn from_str(name: &str) -> Result<Self, String> {
        let found = ConstraintKind::ALL.iter().find(|(flag, _)| *flag == name.trim());
        found.map(|&(_, kind)| kind).ok_or_else(|| {
            let names: Vec<&str> = ConstraintKind::ALL.iter().map(|(flag, _)| *flag).collect();
            format!("unknown constraint kind '{name}': expected one of {}", names.join(", "))
        })
    }
}

impl Vehicle {
    /// Leaves out the constraints of `kind`, as the MJCF's
    /// `<flag {kind}="disable"/>` would.
    pub fn disable_constraints(&mut self, kind: ConstraintKind) {
        match kind {
            ConstraintKind::Equality => self.equalities.clear(),
            ConstraintKind::FrictionLoss | ConstraintKind::Limit => {
                for joint in self.bodies.iter_mut().flat_map(|b| &mut b.joints) {
                    match kind {
                        ConstraintKind::FrictionLoss => joint.constraints.frictionloss = 0.0,
                        _ => joint.constraints.limit = None,
                    }
                }
                for tendon in &mut self.tendons {
                    match kind {
                        ConstraintKind::FrictionLoss => tendon.frictionloss = 0.0,
                        _ => tendon.limit = None,
                    }
                }
            }
        }
    }
}

impl EqualityKind {
    /// The frames a connect or weld holds (`None` for a joint coupling).
    pub fn objects(&self) -> Option<EqualityObjects> {
        match self {
            EqualityKind::Connect { objects, .. } | EqualityKind::Weld { objects, .. } => Some(*objects),
            EqualityKind::Joint { .. } | EqualityKind::Tendon { .. } => None,
        }
    }

    /// The same, to renumber bodies.
    pub(crate) fn objects_mut(&mut self) -> Option<&mut EqualityObjects> {
        match self {
            EqualityKind::Connect { objects, .. } | EqualityKind::Weld { objects, .. } => Some(objects),
            EqualityKind::Joint { .. } | EqualityKind::Tendon { .. } => None,
        }
    }
}

/// `<option>` settings of MuJoCo's constraint model that change its forces.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ConstraintOptions {
    /// `timestep` (s): with `refsafe` on, a constraint's time constant is at least twice it.
    pub timestep: f64,
    /// `<flag refsafe>`.
    pub refsafe: bool,
    /// `noslip_iterations`: the most sweeps of MuJoCo's no-slip pass over
    /// the friction-loss rows after its solver (0: no pass).
    pub noslip_iterations: u32,
    /// `noslip_tolerance`: the pass stops once a sweep's scaled cost
    /// improvement falls below it.
    #[serde(default = "default_noslip_tolerance")]
    pub noslip_tolerance: f64,
    /// `<flag island>`: whether MuJoCo runs the no-slip pass island by
    /// island (each with its own stopping rule) or over all rows at once.
    #[serde(default = "default_islands")]
    pub islands: bool,
}

/// MuJoCo's default `noslip_tolerance`.
fn default_noslip_tolerance() -> f64 {
    1e-6
}

/// Islands are on unless `<flag island="disable">`.
fn default_islands() -> bool {
    true
}

impl Default for ConstraintOptions {
    /// MuJoCo's defaults: timestep 0.002 s, refsafe on, no no-slip pass
    /// (tolerance 1e-6), islands on.
    fn default() -> Self {
        ConstraintOptions {
            timestep: 0.002,
            refsafe: true,
            noslip_iterations: 0,
            noslip_tolerance: default_noslip_tolerance(),
            islands: default_islands(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_names_are_the_mjcf_names() {
        for kind in JointKind::ALL {
            assert_eq!(serde_json::to_value(kind).unwrap(), kind.name());
        }
        use ActuatorKind::*;
        for kind in [General, Motor, Position, Velocity, Damper, IntVelocity, Cylinder] {
            assert_eq!(serde_json::to_value(kind).unwrap(), kind.name());
        }
    }
}
