//! `nudyn describe`: the vehicle's structure as data, so that scripts find
//! joints, kinds and coordinate addresses without reading description prose.
//! The field names are a contract with users' scripts.

use serde::Serialize;

use crate::math::Quat;
use crate::model::Model;
use crate::vehicle::{Activation, ActuatorKind, BiasType, GainType, JointKind, PathPoint, TendonPath, Vehicle};

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
    /// The actuators in MuJoCo's order (that of ctrl).
    pub actuators: Vec<ActuatorDescription>,
    /// The bodies in MuJoCo's order, without the world body.
    pub bodies: Vec<BodyDescription>,
    /// The tendons in MuJoCo's order.
    pub tendons: Vec<TendonDescription>,
    /// The flexible bodies' modes, in θ and ν order after the joints
    /// (docs/flexible.md); absent from the JSON of a rigid vehicle.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub modes: Vec<ModeDescription>,
}

/// One mode of a flexible body: its entries of θ and ν.
#[derive(Clone, Debug, Serialize)]
pub struct ModeDescription {
    /// `BODY:modeK`, K from 1 by rising frequency.
    pub name: String,
    /// The flexible body.
    pub body: String,
    /// Its frequency (Hz) with the body clamped at its frame.
    pub frequency: f64,
    /// Its damping ratio ζ.
    pub damping_ratio: f64,
    /// Its θ entry, 0-based.
    pub qpos_adr: usize,
    /// Its ν (and ε) entry, 0-based.
    pub dof_adr: usize,
}

/// One tendon: its path and the forces it carries, as MuJoCo's compiled
/// model holds them.
#[derive(Clone, Debug, Serialize)]
pub struct TendonDescription {
    /// The tendon's name; `None` (JSON null) when it has none.
    pub name: Option<String>,
    /// The element it was written with: fixed or spatial.
    pub kind: &'static str,
    /// A fixed tendon's joints and coefficients (empty for a spatial one).
    pub joints: Vec<TendonJoint>,
    /// A spatial tendon's sites, wrapping geoms and pulleys in order (empty for a fixed one).
    pub path: Vec<TendonPathPoint>,
    /// Length in qpos0 (tendon_length0).
    pub length0: f64,
    /// The lengths between which the spring is at rest (tendon_lengthspring).
    pub springlength: [f64; 2],
    /// Stiffness.
    pub stiffness: f64,
    /// Damping.
    pub damping: f64,
    /// Friction loss (0: none).
    pub frictionloss: f64,
    /// The length range when the tendon is limited (`null` otherwise).
    pub range: Option<[f64; 2]>,
}

/// One joint of a fixed tendon.
#[derive(Clone, Debug, Serialize)]
pub struct TendonJoint {
    /// The joint's name.
    pub joint: String,
    /// Its coefficient.
    pub coef: f64,
}

/// One element of a spatial tendon's path.
#[derive(Clone, Debug, Serialize)]
#[serde(rename_all = "snake_case", tag = "type")]
pub enum TendonPathPoint {
    /// A site.
    Site {
        /// The site's name.
        name: Option<String>,
        /// The body carrying it ("world" for the world body).
        body: String,
    },
    /// A sphere or cylinder the tendon wraps around.
    Geom {
        /// The body carrying it ("world" for the world body).
        body: String,
        /// sphere or cylinder.
        shape: &'static str,
        /// Its radius.
        radius: f64,
        /// The name of its side site, when it has one.
        #[serde(skip_serializing_if = "Option::is_none")]
        sidesite: Option<String>,
    },
    /// A pulley: the path after it counts 1/divisor.
    Pulley {
        /// Its divisor.
        divisor: f64,
    },
}

/// One body's mass properties, as MuJoCo's compiled model holds them.
#[derive(Clone, Debug, Serialize)]
pub struct BodyDescription {
    /// The body's name (MuJoCo's, or the one nudyn gives an unnamed body).
    pub name: String,
    /// The body frame's position in its parent's (body_pos).
    pub pos: [f64; 3],
    /// The body frame's orientation in its parent's, w x y z (body_quat).
    pub quat: [f64; 4],
    /// Mass (MuJoCo's body_mass).
    pub mass: f64,
    /// Principal moments of inertia (body_inertia).
    pub inertia: [f64; 3],
    /// Centre of mass in the body frame (body_ipos).
    pub ipos: [f64; 3],
    /// Orientation of the principal axes in the body frame, w x y z
    /// (body_iquat); `null` when not known.
    pub iquat: Option<[f64; 4]>,
    /// Whether the mass of some of its geoms is left out (sdf and
    /// height-field geoms of a body fixed to the world, which moves nothing).
    pub mass_unknown: bool,
}

/// One actuator: what it is, what it acts on, and its limits.
#[derive(Clone, Debug, Serialize)]
pub struct ActuatorDescription {
    /// The actuator's name; `None` (JSON null) when it has none.
    pub name: Option<String>,
    /// The element it was written with: general, motor, position, velocity or damper.
    pub kind: ActuatorKind,
    /// Its transmission: "joint", "jointinparent" or "site".
    pub transmission: String,
    /// The joint's or site's name.
    pub target: String,
    /// The reference site of a site transmission.
    pub refsite: Option<String>,
    /// MuJoCo's gear.
    pub gear: [f64; 6],
    /// The ctrl range when ctrl is clamped to one (`null` when unlimited).
    pub ctrlrange: Option<[f64; 2]>,
    /// The force range when the force is clamped to one.
    pub forcerange: Option<[f64; 2]>,
    /// MuJoCo's gaintype: fixed or affine.
    pub gaintype: GainType,
    /// gainprm[0..3] (gain = gainprm\[0\], or affine in length and velocity).
    pub gainprm: [f64; 3],
    /// MuJoCo's biastype: none or affine.
    pub biastype: BiasType,
    /// biasprm[0..3], a damping ratio resolved into −kv.
    pub biasprm: [f64; 3],
    /// Its activation dynamics (dyntype, dynprm\[0\], actrange, actearly),
    /// when it has an activation state `act` (absent otherwise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub activation: Option<Activation>,
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
    /// The description of `model`, compiled from `vehicle`.
    pub fn of(vehicle: &Vehicle, model: &Model) -> Self {
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
        let actuators = model
            .actuators
            .iter()
            .map(|actuator| ActuatorDescription {
                name: actuator.name.clone(),
                kind: actuator.kind,
                transmission: actuator.target.attribute.clone(),
                target: actuator.target.name.clone(),
                refsite: actuator.target.refsite.clone(),
                gear: actuator.gear,
                ctrlrange: actuator.ctrl_range,
                forcerange: actuator.force_range,
                gaintype: actuator.gain_type,
                gainprm: actuator.gain,
                biastype: actuator.bias_type,
                biasprm: actuator.bias,
                activation: actuator.activation,
            })
            .collect();
        Description {
            name: model.name.clone(),
            nq: model.nq,
            nv: model.nv,
            gravity: [model.gravity.x, model.gravity.y, model.gravity.z],
            qpos0: model.qpos0.clone(),
            joints,
            actuators,
            bodies: vehicle.bodies.iter().map(describe_body).collect(),
            tendons: vehicle.tendons.iter().zip(&model.tendons).map(|(t, c)| describe_tendon(vehicle, t, c)).collect(),
            modes: model
                .flexible
                .iter()
                .flat_map(|flexible| {
                    flexible.modal.modes.iter().enumerate().map(|(k, mode)| ModeDescription {
                        name: format!("{}:mode{}", flexible.modal.body, k + 1),
                        body: flexible.modal.body.clone(),
                        frequency: mode.angular_frequency / std::f64::consts::TAU,
                        damping_ratio: mode.damping_ratio,
                        qpos_adr: flexible.qpos_adr + k,
                        dof_adr: flexible.dof_adr + k,
                    })
                })
                .collect(),
        }
    }
}

/// A tendon as written (`tendon`) and compiled (`compiled`: its qpos0
/// length and resolved spring lengths).
fn describe_tendon(
    vehicle: &Vehicle,
    tendon: &crate::vehicle::Tendon,
    compiled: &crate::model::Tendon,
) -> TendonDescription {
    let body_name = |body: Option<usize>| body.map_or("world".to_string(), |b| vehicle.bodies[b].name.clone());
    let (kind, joints, path) = match &tendon.path {
        TendonPath::Fixed(terms) => {
            let joints = terms.iter().map(|(joint, coef)| TendonJoint { joint: joint.clone(), coef: *coef }).collect();
            ("fixed", joints, Vec::new())
        }
        TendonPath::Spatial(points) => {
            let path = points
                .iter()
                .map(|point| match *point {
                    PathPoint::Site(site) => {
                        let site = &vehicle.sites[site];
                        TendonPathPoint::Site { name: site.name.clone(), body: body_name(site.body) }
                    }
                    PathPoint::Geom(geom) => TendonPathPoint::Geom {
                        body: body_name(geom.body),
                        shape: if geom.cylinder { "cylinder" } else { "sphere" },
                        radius: geom.radius,
                        sidesite: geom.side.and_then(|site| vehicle.sites[site].name.clone()),
                    },
                    PathPoint::Pulley(divisor) => TendonPathPoint::Pulley { divisor },
                })
                .collect();
            ("spatial", Vec::new(), path)
        }
    };
    TendonDescription {
        name: tendon.name.clone(),
        kind,
        joints,
        path,
        length0: compiled.length0,
        springlength: compiled.spring_length,
        stiffness: tendon.stiffness,
        damping: tendon.damping,
        frictionloss: tendon.frictionloss,
        range: tendon.limit.as_ref().map(|limit| limit.range),
    }
}

/// A body's mass properties; the principal moments are the tensor's
/// diagonal in the principal axes.
fn describe_body(body: &crate::vehicle::Body) -> BodyDescription {
    let quat = body.inertial_quat.unwrap_or_else(Quat::identity);
    let (mass, inertia) = match &body.inertia {
        Some(props) => {
            let axes = quat.to_rotation_matrix().into_inner();
            let principal = (axes.transpose() * props.inertia * axes).diagonal();
            (props.mass, [principal.x, principal.y, principal.z])
        }
        None => (0.0, [0.0; 3]),
    };
    let pos = body.inertial_pos;
    let (at, turn) = (body.pos, body.quat);
    BodyDescription {
        name: body.name.clone(),
        pos: [at.x, at.y, at.z],
        quat: [turn.w, turn.i, turn.j, turn.k],
        mass,
        inertia,
        ipos: [pos.x, pos.y, pos.z],
        iquat: body.inertial_quat.map(|q| [q.w, q.i, q.j, q.k]),
        mass_unknown: body.mass_unknown,
    }
}
