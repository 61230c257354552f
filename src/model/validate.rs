//! [`Model::validate`]: the shape every pass relies on. A model that passes
//! has parent-first links with consecutive coordinates and dofs, vectors of
//! the declared sizes, finite numbers, and no shortcut past a term it has.
//!
//! [`Model::compile`] checks what it builds with it (a number that
//! overflowed while compiling is caught here), and the FMU checks the model
//! it reads from its resources, which may be corrupted or hand-edited: such
//! a file must be refused at instantiation with a message, not crash, hang
//! or allocate without bound later.

use super::{ActuatorTransmission, EqualityRows, FlexBody, LinkJoint, Model, SensorSource, SiteFrame};
use crate::math::Transform;
use crate::vehicle::{JointKind, SensorKind};

/// What is wrong with a compiled model.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum InvalidModel {
    /// No links at all.
    #[error("the model has no links")]
    NoLinks,
    /// A parent that does not come before its child.
    #[error("link {link} has parent {parent}: parents must come first")]
    Parent {
        /// The link.
        link: usize,
        /// Its parent.
        parent: usize,
    },
    /// A dof count that does not fit the joint.
    #[error("link {link} is a {joint:?} joint with {ndof} dofs, expected {expected}")]
    Dofs {
        /// The link.
        link: usize,
        /// Its joint.
        joint: LinkJoint,
        /// Its dof count.
        ndof: usize,
        /// The joint's dof count.
        expected: usize,
    },
    /// Coordinates or dofs that are not consecutive in link order.
    #[error("link {link} starts at {what} {found}, expected {expected}")]
    Address {
        /// The link.
        link: usize,
        /// "qpos" or "dof".
        what: &'static str,
        /// Its address.
        found: usize,
        /// The end of the previous link's.
        expected: usize,
    },
    /// A flexible body that is not laid out as the compiler lays it out.
    #[error("flexible body {body}: {what}")]
    Flexible {
        /// Its index in the model's flexible bodies.
        body: usize,
        /// What is wrong.
        what: String,
    },
    /// A size that does not match the links.
    #[error("{what} is {found}, the links give {expected}")]
    Size {
        /// Which size.
        what: &'static str,
        /// The value in the file.
        found: usize,
        /// The value the links imply.
        expected: usize,
    },
    /// A joint whose coordinates or dofs lie outside the vectors.
    #[error("joint '{joint}' lies outside the coordinates or dofs")]
    JointAddress {
        /// The joint name.
        joint: String,
    },
    /// A number that is not finite, or negative where it must not be.
    #[error("{what} of link {link} is {value}: must be finite{}", if *.non_negative { " and non-negative" } else { "" })]
    Number {
        /// The link (or 0 for model-wide values).
        link: usize,
        /// Which quantity.
        what: &'static str,
        /// The offending value.
        value: f64,
        /// Whether the quantity must also be non-negative.
        non_negative: bool,
    },
    /// A shortcut that would skip a term the model has.
    #[error("the model takes the shortcut {0}, but it has that term")]
    Shortcut(&'static str),
    /// A hinge or slide axis that is not a unit vector.
    #[error("the axis of link {link} has length {length}: it must be a unit vector")]
    Axis {
        /// The link.
        link: usize,
        /// |axis|.
        length: f64,
    },
    /// A placement whose rotation part is not a proper rotation.
    #[error("x_tree of link {link} is not a rotation: |EᵀE − 1| = {deviation:e}, det E = {determinant}")]
    Rotation {
        /// The link.
        link: usize,
        /// The largest entry of |EᵀE − 1|.
        deviation: f64,
        /// det E.
        determinant: f64,
    },
    /// A motion subspace that the link's joint, axis and anchor do not give.
    #[error("the motion subspace of link {link} is not the one its joint, axis and anchor give")]
    MotionSubspace {
        /// The link.
        link: usize,
    },
    /// An inertia no body can have.
    #[error("the inertia of link {link} is {what}")]
    Inertia {
        /// The link.
        link: usize,
        /// What is wrong, with the numbers.
        what: String,
    },
    /// A joint's actuator force limit off a hinge or slide dof, or not a range.
    #[error("the actuator force limit at dof {dof} is not on a hinge or slide joint, or not an increasing range")]
    ActuatorForceLimit {
        /// The dof.
        dof: usize,
    },
    /// An actuator whose transmission or force law the links do not support.
    #[error("actuator {actuator}: {what}")]
    Actuator {
        /// The actuator's index.
        actuator: usize,
        /// What is wrong.
        what: String,
    },
    /// Tendon armature terms that are not those of the tendons and links.
    #[error("the tendons' armature terms do not match the tendons and links")]
    TendonInertia,
    /// A tendon whose path lies outside the model or whose numbers are not finite.
    #[error("tendon {tendon}: {what}")]
    Tendon {
        /// The tendon's index.
        tendon: usize,
        /// What is wrong.
        what: String,
    },
    /// More wrench bodies than actuators to carry their inputs.
    #[error("{bodies} wrench bodies need {needed} actuators, the model has {found}")]
    WrenchInputs {
        /// Number of wrench bodies.
        bodies: usize,
        /// Actuators they need (six each).
        needed: usize,
        /// Actuators in the model.
        found: usize,
    },
    /// A constraint row that lies outside the model or has numbers MuJoCo
    /// could not use.
    #[error("constraint: {0}")]
    Constraint(String),
    /// Gravity compensation on links or dofs the model does not have, or
    /// with numbers that are not finite.
    #[error("gravity compensation: {0}")]
    GravityCompensation(String),
    /// An evaluation in qpos0 failed while compiling.
    #[error("evaluation in qpos0 failed: {0}")]
    Evaluation(String),
    /// A sensor that reads outside the model.
    #[error("sensor {sensor}: {what}")]
    Sensor {
        /// The sensor's index.
        sensor: usize,
        /// What is wrong.
        what: &'static str,
    },
}

/// Relative round-off allowed in the physical checks: far above what
/// compilation and a JSON round trip leave, far below any real error.
const PHYSICS_TOLERANCE: f64 = 1e-9;

/// Checks that a link is physically possible: a unit axis, a proper
/// rotation, the motion subspace of its joint, and a symmetric, positive
/// semi-definite spatial inertia.
fn check_physics(k: usize, link: &super::Link) -> Result<(), InvalidModel> {
    if matches!(link.joint, LinkJoint::Hinge | LinkJoint::Slide) {
        let length = link.axis.norm();
        if (length - 1.0).abs() > PHYSICS_TOLERANCE {
            return Err(InvalidModel::Axis { link: k, length });
        }
    }
    let rot = &link.x_tree.rot;
    let deviation = (rot.transpose() * rot - super::Mat3::identity()).amax();
    let determinant = rot.determinant();
    if deviation > PHYSICS_TOLERANCE || determinant <= 0.0 {
        return Err(InvalidModel::Rotation { link: k, deviation, determinant });
    }
    let (_, expected) = super::motion_subspace(link.joint, &link.axis, &link.anchor);
    let scale = 1.0 + link.anchor.amax();
    if (link.motion_subspace - expected).amax() > PHYSICS_TOLERANCE * scale {
        return Err(InvalidModel::MotionSubspace { link: k });
    }
    let inertia = &link.rotational_inertia;
    let asymmetry = (inertia - inertia.transpose()).amax();
    if asymmetry > PHYSICS_TOLERANCE * inertia.amax() {
        return Err(InvalidModel::Inertia { link: k, what: format!("not symmetric (|I − Iᵀ| = {asymmetry:e})") });
    }
    let eigenvalues = link.spatial_inertia().symmetric_eigenvalues();
    let (smallest, largest) = (eigenvalues.min(), eigenvalues.amax());
    if smallest < -PHYSICS_TOLERANCE * largest {
        let what = format!("not positive semi-definite (spatial inertia eigenvalue {smallest:e}, largest {largest:e})");
        return Err(InvalidModel::Inertia { link: k, what });
    }
    Ok(())
}

/// Whether a range is finite and increasing.
fn is_range(range: [f64; 2]) -> bool {
    range.iter().all(|x| x.is_finite()) && range[0] < range[1]
}

/// Checks actuator `k` against the links: its dofs and θ entries belong to
/// a joint of its transmission's kind, its links exist, its site frames are
/// proper placements, and its numbers are finite with increasing ranges.
fn validate_actuator(model: &Model, k: usize) -> Result<(), String> {
    let actuator = &model.actuators[k];
    let link_at = |dof: usize| model.links.binary_search_by_key(&dof, |l| l.dof_adr).ok().map(|i| &model.links[i]);
    let joint_at = |dof: usize, qpos: usize, joint: LinkJoint| {
        link_at(dof).is_some_and(|l| l.joint == joint && l.qpos_adr == qpos)
    };
    let site_ok =
        |site: &SiteFrame| site.link.is_none_or(|l| l < model.links.len()) && placement_is_proper(&site.frame);
    let fits = match &actuator.transmission {
        ActuatorTransmission::Scalar { dof, qpos } => {
            joint_at(*dof, *qpos, LinkJoint::Hinge) || joint_at(*dof, *qpos, LinkJoint::Slide)
        }
        ActuatorTransmission::Ball { dof, qpos, .. } => joint_at(*dof, *qpos, LinkJoint::Ball),
        ActuatorTransmission::Free { dof, qpos, .. } => {
            joint_at(*dof, *qpos - 3, LinkJoint::Translation) && joint_at(*dof + 3, *qpos, LinkJoint::Ball)
        }
        ActuatorTransmission::Site { site } => site_ok(site),
        ActuatorTransmission::RelativeSite { site, reference, common_link, common_node } => {
            site_ok(site)
                && site_ok(reference)
                && common_link.is_none_or(|l| l < model.links.len())
                && common_node.is_none_or(|at| {
                    model.flexible.get(at.flexible).is_some_and(|f| {
                        Some(f.link) == *common_link && at.node < f.modal.nodes.len() && f.rotating.contains(&at.node)
                    })
                })
        }
        ActuatorTransmission::Tendon { tendon } => *tendon < model.tendons.len(),
    };
    if !fits {
        return Err("its transmission does not match the links".to_string());
    }
    let numbers = actuator.gear.iter().chain(&actuator.gain).chain(&actuator.bias);
    if !numbers.chain([&actuator.setpoint_period]).all(|x| x.is_finite()) || actuator.setpoint_period < 0.0 {
        return Err("gear, gain, bias and setpoint period must be finite".to_string());
    }
    let act_range = actuator.activation.and_then(|a| a.range);
    if actuator.activation.is_some_and(|a| !a.time_constant.is_finite()) {
        return Err("its activation's time constant must be finite".to_string());
    }
    for (what, range) in
        [("ctrl range", actuator.ctrl_range), ("force range", actuator.force_range), ("act range", act_range)]
    {
        if range.is_some_and(|range| !is_range(range)) {
            return Err(format!("its {what} must be finite and increasing"));
        }
    }
    Ok(())
}

/// A placement with finite numbers and a proper rotation.
pub(super) fn placement_is_proper(placement: &Transform) -> bool {
    let rot = &placement.rot;
    placement.rot.iter().chain(placement.trans.iter()).all(|x| x.is_finite())
        && (rot.transpose() * rot - super::Mat3::identity()).amax() <= PHYSICS_TOLERANCE
        && rot.determinant() > 0.0
}

/// (qpos count, dof count) of a link's joint.
fn joint_size(joint: LinkJoint) -> (usize, usize) {
    match joint {
        LinkJoint::Hinge | LinkJoint::Slide => (1, 1),
        LinkJoint::Ball => (4, 3),
        LinkJoint::Translation => (3, 3),
    }
}

/// The first non-finite value of `values`, as an error about `what` of `link`.
/// A flexible body's link, addresses (after the rigid coordinates and the
/// flexible bodies before it) and modal data.
fn validate_flexible(model: &Model, flexible: &FlexBody, nq: usize, nv: usize) -> Result<(), String> {
    if flexible.link >= model.links.len() {
        return Err(format!("link {} does not exist", flexible.link));
    }
    if (flexible.qpos_adr, flexible.dof_adr) != (nq, nv) {
        return Err(format!(
            "its coordinates start at qpos {} and dof {}, expected {nq} and {nv}",
            flexible.qpos_adr, flexible.dof_adr
        ));
    }
    let modal = &flexible.modal;
    for node in &modal.nodes {
        let numbers = node.position.iter().chain(node.rotary_inertia.iter()).chain([&node.mass]);
        if numbers.into_iter().any(|x| !x.is_finite()) || node.mass < 0.0 {
            return Err(format!("node '{}' has a number that is not finite, or a negative mass", node.name));
        }
    }
    for (k, mode) in modal.modes.iter().enumerate() {
        let sized = mode.translation.len() == modal.nodes.len() && mode.rotation.len() == modal.nodes.len();
        let shape_finite = mode.translation.iter().chain(&mode.rotation).flat_map(|v| v.iter()).all(|x| x.is_finite());
        let rates =
            mode.angular_frequency.is_finite() && mode.angular_frequency > 0.0 && mode.damping_ratio.is_finite();
        if !(sized && shape_finite && rates && mode.damping_ratio >= 0.0) {
            return Err(format!(
                "mode {} is not one finite shape per node with a positive frequency and a non-negative damping ratio",
                k + 1
            ));
        }
    }
    Ok(())
}

fn finite<'a>(link: usize, what: &'static str, values: impl IntoIterator<Item = &'a f64>) -> Result<(), InvalidModel> {
    match values.into_iter().find(|x| !x.is_finite()) {
        Some(&value) => Err(InvalidModel::Number { link, what, value, non_negative: false }),
        None => Ok(()),
    }
}

/// A value that must be finite and non-negative.
fn non_negative(link: usize, what: &'static str, value: f64) -> Result<(), InvalidModel> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(InvalidModel::Number { link, what, value, non_negative: true })
    }
}

impl Model {
    /// Checks that the model has the structure [`Model::compile`] gives; O(links).
    pub fn validate(&self) -> Result<(), InvalidModel> {
        validate(self)
    }
}

fn validate(model: &Model) -> Result<(), InvalidModel> {
    if model.links.is_empty() {
        return Err(InvalidModel::NoLinks);
    }
    let (mut nq, mut nv) = (0, 0);
    for (k, link) in model.links.iter().enumerate() {
        if let Some(parent) = link.parent.filter(|&p| p >= k) {
            return Err(InvalidModel::Parent { link: k, parent });
        }
        let (link_nq, link_nv) = joint_size(link.joint);
        if link.ndof != link_nv {
            return Err(InvalidModel::Dofs { link: k, joint: link.joint, ndof: link.ndof, expected: link_nv });
        }
        if link.qpos_adr != nq {
            return Err(InvalidModel::Address { link: k, what: "qpos", found: link.qpos_adr, expected: nq });
        }
        if link.dof_adr != nv {
            return Err(InvalidModel::Address { link: k, what: "dof", found: link.dof_adr, expected: nv });
        }
        nq += link_nq;
        nv += link_nv;
        finite(k, "x_tree", link.x_tree.rot.iter().chain(link.x_tree.trans.iter()))?;
        finite(k, "axis", link.axis.iter())?;
        finite(k, "anchor", link.anchor.iter())?;
        finite(k, "reference", [link.reference].iter())?;
        finite(k, "motion_subspace", link.motion_subspace.iter())?;
        finite(k, "rotational_inertia", link.rotational_inertia.iter())?;
        finite(k, "mass_moment", link.mass_moment.iter())?;
        non_negative(k, "armature", link.armature)?;
        non_negative(k, "stiffness", link.stiffness)?;
        non_negative(k, "damping", link.damping)?;
        non_negative(k, "mass", link.mass)?;
        check_physics(k, link)?;
    }
    for (k, flexible) in model.flexible.iter().enumerate() {
        validate_flexible(model, flexible, nq, nv).map_err(|what| InvalidModel::Flexible { body: k, what })?;
        nq += flexible.mode_count();
        nv += flexible.mode_count();
    }
    for (what, found, expected) in [
        ("nq", model.nq, nq),
        ("nv", model.nv, nv),
        ("the length of qpos0", model.qpos0.len(), nq),
        ("the length of qpos_spring", model.qpos_spring.len(), nq),
    ] {
        if found != expected {
            return Err(InvalidModel::Size { what, found, expected });
        }
    }
    if let Some(joint) = model.joints.iter().find(|j| j.qpos_adr >= nq || j.dof_adr >= nv) {
        return Err(InvalidModel::JointAddress { joint: joint.name.clone() });
    }
    finite(0, "gravity", model.gravity.iter())?;
    finite(0, "qpos0", &model.qpos0)?;
    finite(0, "qpos_spring", &model.qpos_spring)?;
    for k in 0..model.tendons.len() {
        super::tendon::validate_tendon(model, k).map_err(|what| InvalidModel::Tendon { tendon: k, what })?;
    }
    if model.tendon_inertia != super::tendon::inertia_terms(model) {
        return Err(InvalidModel::TendonInertia);
    }
    for k in 0..model.actuators.len() {
        validate_actuator(model, k).map_err(|what| InvalidModel::Actuator { actuator: k, what })?;
    }
    let (bodies, found) = (model.wrench_bodies.len(), model.actuators.len());
    if bodies.checked_mul(6).is_none_or(|needed| needed > found) {
        return Err(InvalidModel::WrenchInputs { bodies, needed: bodies.saturating_mul(6), found });
    }
    validate_sensors(model)?;
    validate_constraints(model).map_err(InvalidModel::Constraint)?;
    validate_gravity_compensation(model).map_err(InvalidModel::GravityCompensation)?;
    for limit in &model.actuator_force_limits {
        let joint = model.links.iter().find(|l| l.dof_adr == limit.dof).map(|l| l.joint);
        if !matches!(joint, Some(LinkJoint::Hinge | LinkJoint::Slide)) || !is_range(limit.range) {
            return Err(InvalidModel::ActuatorForceLimit { dof: limit.dof });
        }
    }
    match model.shortcuts.not_allowed_for(model) {
        Some(shortcut) => Err(InvalidModel::Shortcut(shortcut)),
        None => Ok(()),
    }
}

/// Every constraint row lies on a joint of its kind, with finite numbers
/// and MuJoCo's invweights when there are rows.
pub(super) fn validate_constraints(model: &Model) -> Result<(), String> {
    let constraints = &model.constraints;
    let soft_ok = |soft: &crate::vehicle::SoftConstraint| soft.solref.iter().chain(&soft.solimp).all(|x| x.is_finite());
    let reads_interaction = model.sensors.iter().any(|s| matches!(s.source, SensorSource::Interaction { .. }));
    if reads_interaction
        && !constraints.equalities.is_empty()
        && model.interaction_bodies.equalities.len() != constraints.equalities.len()
    {
        return Err("the force and torque sensors do not know the bodies of every equality".to_string());
    }
    for friction in &constraints.friction {
        if friction.dof >= model.nv || !(friction.frictionloss.is_finite() && friction.frictionloss > 0.0) {
            return Err(format!("friction loss at dof {} is {}", friction.dof, friction.frictionloss));
        }
        if !soft_ok(&friction.soft) {
            return Err(format!("friction loss at dof {}: solref or solimp not finite", friction.dof));
        }
    }
    for limit in &constraints.limits {
        let joint =
            model.joints.get(limit.joint).ok_or(format!("limit on joint {}, which does not exist", limit.joint))?;
        let fits = joint.kind == limit.kind
            && joint.qpos_adr == limit.qpos
            && joint.dof_adr == limit.dof
            && matches!(limit.kind, JointKind::Hinge | JointKind::Slide | JointKind::Ball);
        let ranged = limit.range.iter().all(|x| x.is_finite())
            && (limit.kind == JointKind::Ball || limit.range[0] < limit.range[1]);
        if !fits || !ranged || !limit.margin.is_finite() || !soft_ok(&limit.soft) {
            return Err(format!(
                "the limit of joint '{}' does not fit it or has numbers that are not finite",
                joint.name
            ));
        }
    }
    for equality in &constraints.equalities {
        let bad = || format!("equality {} lies outside the model or has numbers that are not finite", equality.label);
        let finite = |values: &[f64]| values.iter().all(|x| x.is_finite());
        let frame_ok = |frame: &super::SiteFrame| {
            frame.link.is_none_or(|l| l < model.links.len())
                && finite(frame.frame.rot.as_slice())
                && finite(frame.frame.trans.as_slice())
        };
        let ok = match &equality.rows {
            EqualityRows::Connect { frames, anchors, invweight } => {
                frames.iter().all(frame_ok) && anchors.iter().all(|a| finite(a.as_slice())) && invweight.is_finite()
            }
            EqualityRows::Weld { frames, anchors, relative, torquescale, invweight } => {
                frames.iter().all(frame_ok)
                    && anchors.iter().all(|a| finite(a.as_slice()))
                    && finite(relative.coords.as_slice())
                    && torquescale.is_finite()
                    && finite(invweight)
            }
            EqualityRows::Joint { first, second, polycoef, invweight } => {
                let inside = |[dof, qpos]: [usize; 2]| dof < model.nv && qpos < model.nq;
                inside(*first) && second.is_none_or(inside) && finite(polycoef) && invweight.is_finite()
            }
            EqualityRows::Tendon { first, second, polycoef, invweight } => {
                let inside = |k: usize| k < model.tendons.len();
                inside(*first) && second.is_none_or(inside) && finite(polycoef) && invweight.is_finite()
            }
        };
        if !ok || !soft_ok(&equality.soft) {
            return Err(bad());
        }
    }
    for friction in &constraints.tendon_friction {
        let ok = friction.tendon < model.tendons.len()
            && friction.frictionloss.is_finite()
            && friction.frictionloss > 0.0
            && soft_ok(&friction.soft);
        if !ok {
            return Err(format!("friction loss of tendon {} is outside the model or not finite", friction.tendon));
        }
    }
    for limit in &constraints.tendon_limits {
        let ok = limit.tendon < model.tendons.len()
            && limit.range.iter().all(|x| x.is_finite())
            && limit.range[0] < limit.range[1]
            && limit.margin.is_finite()
            && soft_ok(&limit.soft);
        if !ok {
            return Err(format!("the limit of tendon {} is outside the model or not a finite range", limit.tendon));
        }
    }
    let weights = &constraints.dof_invweight0;
    let expected = if constraints.is_empty() { 0 } else { model.nv };
    if weights.len() != expected || weights.iter().any(|w| !(w.is_finite() && *w >= 0.0)) {
        return Err(format!(
            "dof_invweight0 has {} entries (expected {expected}), or one not finite and non-negative",
            weights.len()
        ));
    }
    let timestep = constraints.options.timestep;
    if !(timestep.is_finite() && timestep > 0.0) {
        return Err(format!("timestep {timestep} is not positive"));
    }
    Ok(())
}

/// The compensated links and the dofs routed to the actuators lie inside
/// the model, ascending and each once, with finite numbers, and only under gravity.
fn validate_gravity_compensation(model: &Model) -> Result<(), String> {
    let compensation = &model.gravity_compensation;
    if compensation.is_empty() {
        return match compensation.actuator_dofs.is_empty() {
            true => Ok(()),
            false => Err("dofs are routed to the actuators, but no link is compensated".to_string()),
        };
    }
    if model.gravity == crate::math::Vec3::zeros() {
        return Err("compensated links without gravity".to_string());
    }
    let ascending = |values: &[usize], end: usize| {
        values.windows(2).all(|pair| pair[0] < pair[1]) && values.last().is_none_or(|&last| last < end)
    };
    let links: Vec<usize> = compensation.links.iter().map(|c| c.link).collect();
    if !ascending(&links, model.links.len()) {
        return Err("the compensated links are not ascending links of the model".to_string());
    }
    if !ascending(&compensation.actuator_dofs, model.nv) {
        return Err("the dofs routed to the actuators are not ascending dofs of the model".to_string());
    }
    match compensation.links.iter().find(|c| !(c.mass.is_finite() && c.mass_moment.iter().all(|x| x.is_finite()))) {
        Some(c) => Err(format!("the compensated mass or mass moment of link {} is not finite", c.link)),
        None => Ok(()),
    }
}

/// Every sensor reads inside the model, at its place in sensordata.
fn validate_sensors(model: &Model) -> Result<(), InvalidModel> {
    let links = model.links.len();
    let frame_ok = |frame: &SiteFrame| frame.link.is_none_or(|l| l < links) && frame_is_finite(&frame.frame);
    if !(model.link_tree_quats.is_empty() || model.link_tree_quats.len() == links)
        || model.link_tree_quats.iter().any(|q| !q.coords.iter().all(|x| x.is_finite()))
    {
        return Err(InvalidModel::Sensor { sensor: 0, what: "link_tree_quats do not match the links" });
    }
    if model.body_masses.iter().any(|b| {
        b.link.is_some_and(|l| l >= links)
            || !(b.mass.is_finite() && b.mass >= 0.0)
            || !b.com.iter().chain(b.inertia.iter()).all(|x| x.is_finite())
    }) {
        return Err(InvalidModel::Sensor { sensor: 0, what: "a body mass is not valid" });
    }
    let mut adr = 0;
    for (k, sensor) in model.sensors.iter().enumerate() {
        let fail = |what| Err(InvalidModel::Sensor { sensor: k, what });
        if sensor.adr != adr {
            return fail("its address does not follow the previous sensor's");
        }
        adr += sensor.dim();
        if !(sensor.cutoff.is_finite() && sensor.cutoff >= 0.0) {
            return fail("cutoff must be finite and non-negative");
        }
        use SensorKind::*;
        let reads_a_joint = matches!(
            sensor.kind,
            JointPos
                | JointVel
                | BallQuat
                | BallAngVel
                | JointActuatorFrc
                | JointLimitPos
                | JointLimitVel
                | JointLimitFrc
        );
        let reads_a_tendon = matches!(
            sensor.kind,
            TendonPos | TendonVel | TendonActuatorFrc | TendonLimitPos | TendonLimitVel | TendonLimitFrc
        );
        let kind_matches = match &sensor.source {
            SensorSource::Joint { .. } => reads_a_joint,
            SensorSource::Tendon { .. } => reads_a_tendon,
            SensorSource::Actuator { .. } => matches!(sensor.kind, ActuatorFrc | ActuatorPos | ActuatorVel),
            SensorSource::Subtree { .. } => matches!(sensor.kind, SubtreeCom | SubtreeLinVel | SubtreeAngMom),
            SensorSource::Interaction { .. } => matches!(sensor.kind, Force | Torque),
            SensorSource::Clock => sensor.kind == Clock,
            SensorSource::Frame { .. } => {
                !reads_a_joint
                    && !reads_a_tendon
                    && !matches!(
                        sensor.kind,
                        ActuatorFrc
                            | ActuatorPos
                            | ActuatorVel
                            | SubtreeCom
                            | SubtreeLinVel
                            | SubtreeAngMom
                            | Force
                            | Torque
                            | Clock
                    )
            }
        };
        if !kind_matches {
            return fail("its type does not read what its source gives");
        }
        let (nq, nv) = (model.nq, model.nv);
        let fits = match &sensor.source {
            SensorSource::Joint { dof, qpos } => {
                let (coordinates, dofs) = match sensor.kind {
                    BallQuat | BallAngVel => (4, 3),
                    _ => (1, 1),
                };
                qpos.checked_add(coordinates).is_some_and(|end| end <= nq)
                    && dof.checked_add(dofs).is_some_and(|end| end <= nv)
            }
            SensorSource::Actuator { actuator } => *actuator < model.mjcf_actuator_count(),
            SensorSource::Frame { object, reference, quats } => {
                frame_ok(object)
                    && reference.as_ref().is_none_or(frame_ok)
                    && quats.iter().all(|q| q.coords.iter().all(|x| x.is_finite()))
                    && (sensor.kind != FrameQuat || model.link_tree_quats.len() == links)
            }
            SensorSource::Subtree { first, end } => first <= end && *end <= model.body_masses.len(),
            SensorSource::Interaction { site, first, end } => {
                frame_ok(site) && first <= end && *end <= model.body_masses.len() && interaction_bodies_ok(model)
            }
            SensorSource::Tendon { tendon } => *tendon < model.tendons.len(),
            SensorSource::Clock => true,
        };
        if !fits {
            return fail("it reads outside the model");
        }
    }
    Ok(())
}

/// Whether the bodies of the wrench inputs and equalities are the model's,
/// one per wrench body (that each equality has its pair is
/// [`validate_constraints`]' to check, once the equalities are compiled).
fn interaction_bodies_ok(model: &Model) -> bool {
    let bodies = &model.interaction_bodies;
    let inside = |b: &usize| *b < model.body_masses.len();
    bodies.wrench_inputs.len() == model.wrench_bodies.len()
        && bodies.wrench_inputs.iter().all(inside)
        && bodies.equalities.iter().flatten().flatten().all(inside)
}

/// Whether a fixed frame's numbers are all finite.
fn frame_is_finite(frame: &Transform) -> bool {
    frame.rot.iter().chain(frame.trans.iter()).all(|x| x.is_finite())
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use super::*;

    fn example(name: &str) -> Model {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples").join(name);
        let vehicle = crate::mjcf::load_mjcf(&path).expect("example imports").vehicle;
        Model::compile(&vehicle).expect("example compiles")
    }

    #[test]
    fn compiled_examples_pass() {
        for name in ["bus_arm7.xml", "flexible_boom.xml", "fixed_rig.xml", "chain60.xml", "servicer.xml"] {
            assert_eq!(validate(&example(name)), Ok(()), "{name}");
        }
    }

    #[test]
    fn sizes_that_do_not_match_the_links_are_refused() {
        let mut model = example("bus_arm7.xml");
        // A flipped digit in "nv" would otherwise size every vector (and the GUID's variable list) by it.
        model.nv = 1_000_000_000_000;
        assert!(matches!(validate(&model), Err(InvalidModel::Size { what: "nv", .. })));
        let mut model = example("bus_arm7.xml");
        model.qpos0.pop();
        assert!(matches!(validate(&model), Err(InvalidModel::Size { .. })));
    }

    #[test]
    fn broken_structure_is_refused() {
        let mut model = example("bus_arm7.xml");
        model.links[3].parent = Some(5);
        assert_eq!(validate(&model), Err(InvalidModel::Parent { link: 3, parent: 5 }));
        let mut model = example("bus_arm7.xml");
        model.links[2].ndof = 3;
        assert!(matches!(validate(&model), Err(InvalidModel::Dofs { link: 2, .. })));
        let mut model = example("bus_arm7.xml");
        model.links[4].qpos_adr += 1;
        assert!(matches!(validate(&model), Err(InvalidModel::Address { link: 4, what: "qpos", .. })));
        let mut model = example("bus_arm7.xml");
        model.links.clear();
        assert_eq!(validate(&model), Err(InvalidModel::NoLinks));
        let mut model = example("bus_arm7.xml");
        model.joints[1].dof_adr = model.nv;
        assert!(matches!(validate(&model), Err(InvalidModel::JointAddress { .. })));
    }

    #[test]
    fn bad_numbers_are_refused() {
        let mut model = example("flexible_boom.xml");
        model.links[1].rotational_inertia[(2, 2)] = f64::NAN;
        assert!(matches!(validate(&model), Err(InvalidModel::Number { link: 1, what: "rotational_inertia", .. })));
        let mut model = example("flexible_boom.xml");
        model.links[0].mass = -1.0;
        assert!(matches!(validate(&model), Err(InvalidModel::Number { what: "mass", non_negative: true, .. })));
        let mut model = example("flexible_boom.xml");
        model.gravity[2] = f64::INFINITY;
        assert!(matches!(validate(&model), Err(InvalidModel::Number { what: "gravity", .. })));
    }

    #[test]
    fn physically_impossible_links_are_refused() {
        let model = example("bus_arm7.xml");
        let mut bent = model.clone();
        bent.links[3].axis *= 1.5;
        assert!(matches!(validate(&bent), Err(InvalidModel::Axis { link: 3, .. })));
        let mut zero_axis = model.clone();
        zero_axis.links[3].axis.fill(0.0);
        assert!(matches!(validate(&zero_axis), Err(InvalidModel::Axis { link: 3, .. })));
        let mut skewed = model.clone();
        skewed.links[4].x_tree.rot[(0, 1)] += 0.01;
        assert!(matches!(validate(&skewed), Err(InvalidModel::Rotation { link: 4, .. })));
        let mut mirrored = model.clone();
        mirrored.links[4].x_tree.rot.column_mut(0).neg_mut();
        assert!(matches!(validate(&mirrored), Err(InvalidModel::Rotation { link: 4, .. })), "det E = -1");
        let mut elsewhere = model.clone();
        elsewhere.links[5].motion_subspace[(3, 0)] += 0.1;
        assert_eq!(validate(&elsewhere), Err(InvalidModel::MotionSubspace { link: 5 }));
        let mut asymmetric = model.clone();
        asymmetric.links[2].rotational_inertia[(0, 1)] += 0.5;
        assert!(matches!(validate(&asymmetric), Err(InvalidModel::Inertia { link: 2, .. })));
        let mut indefinite = model.clone();
        indefinite.links[2].rotational_inertia[(2, 2)] = -1.0;
        let error = validate(&indefinite).unwrap_err();
        assert!(error.to_string().contains("not positive semi-definite"), "{error}");
        let mut negative_mass_moment = model;
        // A centre of mass far outside a light body: no rotational inertia about it can hold.
        negative_mass_moment.links[2].mass_moment *= 1e3;
        assert!(matches!(validate(&negative_mass_moment), Err(InvalidModel::Inertia { link: 2, .. })));
    }

    #[test]
    fn every_importer_fixture_that_compiles_is_valid() {
        let fixtures = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
        let files = std::fs::read_dir(fixtures.join("mjcf")).unwrap().map(|e| e.unwrap().path());
        for path in files.chain([fixtures.join("thin_rods.xml")]) {
            let Ok(imported) = crate::mjcf::load_mjcf(&path) else { continue };
            if let Ok(model) = Model::compile(&imported.vehicle) {
                assert_eq!(validate(&model), Ok(()), "{}", path.display());
            }
        }
    }

    #[test]
    fn actuators_that_do_not_fit_the_links_are_refused() {
        let model = example("servicer.xml");
        assert_eq!(validate(&model), Ok(()));
        // Actuator 8 is the x wheel's motor, on a hinge's dof.
        let mut moved = model.clone();
        if let ActuatorTransmission::Scalar { dof, .. } = &mut moved.actuators[8].transmission {
            *dof = 0;
        }
        assert!(matches!(validate(&moved), Err(InvalidModel::Actuator { actuator: 8, .. })));
        let mut no_link = model.clone();
        if let ActuatorTransmission::Site { site } = &mut no_link.actuators[0].transmission {
            site.link = Some(99);
        }
        assert!(matches!(validate(&no_link), Err(InvalidModel::Actuator { actuator: 0, .. })));
        let mut reversed = model.clone();
        reversed.actuators[12].ctrl_range = Some([1.0, -1.0]);
        assert!(matches!(validate(&reversed), Err(InvalidModel::Actuator { actuator: 12, .. })));
        let mut nan = model.clone();
        nan.actuators[3].gear[2] = f64::NAN;
        assert!(matches!(validate(&nan), Err(InvalidModel::Actuator { actuator: 3, .. })));
        let mut limit = model;
        limit.actuator_force_limits.push(crate::model::DofForceLimit { dof: 2, range: [-1.0, 1.0] });
        assert_eq!(validate(&limit), Err(InvalidModel::ActuatorForceLimit { dof: 2 }));
    }

    #[test]
    fn gravity_compensation_outside_the_model_is_refused() {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/gravcomp/arm_on_bus.xml");
        let model = Model::compile(&crate::mjcf::load_mjcf(&path).unwrap().vehicle).unwrap();
        assert_eq!(validate(&model), Ok(()));
        assert!(!model.gravity_compensation.is_empty() && !model.gravity_compensation.actuator_dofs.is_empty());
        let refused = |edit: &dyn Fn(&mut Model)| {
            let mut edited = model.clone();
            edit(&mut edited);
            matches!(validate(&edited), Err(InvalidModel::GravityCompensation(_)))
        };
        assert!(refused(&|m| m.gravity_compensation.links[0].link = 99));
        assert!(refused(&|m| m.gravity_compensation.links.swap(0, 1)));
        assert!(refused(&|m| m.gravity_compensation.links[1].mass_moment.y = f64::NAN));
        assert!(refused(&|m| m.gravity_compensation.actuator_dofs.push(m.nv)));
        assert!(refused(&|m| m.gravity_compensation.actuator_dofs.insert(0, 8)));
        assert!(refused(&|m| m.gravity_compensation.links.clear()));
        assert!(refused(&|m| {
            m.gravity = crate::math::Vec3::zeros();
            m.shortcuts.no_gravity = true;
        }));
    }

    #[test]
    fn a_shortcut_past_a_term_the_model_has_is_refused() {
        // bus_arm7 has no gravity but has armature: an edited file must not skip it.
        let mut model = example("bus_arm7.xml");
        assert!(model.shortcuts.no_gravity && !model.shortcuts.no_armature);
        model.shortcuts.no_armature = true;
        assert_eq!(validate(&model), Err(InvalidModel::Shortcut("no_armature")));
        model.shortcuts = crate::model::Shortcuts::none();
        assert_eq!(validate(&model), Ok(()));
    }
}
