//! Compiled sensors: what each reads, resolved into dofs, actuators, frames
//! on links or ranges of bodies, in MuJoCo's sensor order, with their
//! addresses in `sensordata`.

use serde::{Deserialize, Serialize};

use super::{Attachment, JointInfo, ModelError, SiteFrame};
use crate::math::{Mat3, Quat, Transform, Vec3};
use crate::vehicle::{FrameObject, SensorKind, SensorTarget, Vehicle};

/// Where a sensor reads its values.
// Frames are large and the rest small, but a model holds few sensors and
// reads them once per output: no indirection is worth it.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "type")]
pub enum SensorSource {
    /// A hinge or slide joint, or the three dofs of a ball joint.
    Joint {
        /// The joint's first dof.
        dof: usize,
        /// The joint's first θ entry.
        qpos: usize,
    },
    /// An actuator, by index.
    Actuator {
        /// The actuator's index (in ctrl).
        actuator: usize,
    },
    /// A frame fixed to a link, measured in the world or in a reference frame.
    Frame {
        /// The frame measured.
        object: SiteFrame,
        /// The frame it is measured in.
        reference: Option<SiteFrame>,
        /// The rotations of `object` and `reference` relative to their links
        /// as quaternions composed as MuJoCo composes them (framequat's sign).
        quats: [Quat; 2],
    },
    /// A subtree: the bodies `first..end` of [`Model::body_masses`](super::Model::body_masses).
    Subtree {
        /// The subtree's root body.
        first: usize,
        /// One past its last body.
        end: usize,
    },
    /// The interaction force of a site's body with its parent (force and
    /// torque sensors): the sum over the body's subtree, the bodies
    /// `first..end` of [`Model::body_masses`](super::Model::body_masses)
    /// (every body for a site on the world).
    Interaction {
        /// The site, whose frame the force and torque are expressed in.
        site: SiteFrame,
        /// The subtree's root body.
        first: usize,
        /// One past its last body.
        end: usize,
    },
    /// A tendon.
    Tendon {
        /// The tendon (index into [`Model::tendons`](super::Model::tendons)).
        tendon: usize,
    },
    /// The simulation time.
    Clock,
}

/// One compiled sensor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sensor {
    /// The sensor's name, if it has one.
    pub name: Option<String>,
    /// Its type.
    pub kind: SensorKind,
    /// Where it reads.
    pub source: SensorSource,
    /// What it measures, as the MJCF names it (for descriptions): e.g.
    /// "site 'tool'", "joint 'elbow'", "subtree of body 'arm'".
    pub target: String,
    /// MuJoCo's `cutoff` (0: none).
    pub cutoff: f64,
    /// First entry in sensordata.
    pub adr: usize,
    /// Line of the sensor element in the MJCF file (1-based).
    pub line: u32,
}

impl Sensor {
    /// The sensor as messages and descriptions name it: its element and
    /// name, or its index.
    pub fn label(&self, index: usize) -> String {
        match &self.name {
            Some(name) => format!("{} '{name}'", self.kind.name()),
            None => format!("{} {index}", self.kind.name()),
        }
    }

    /// Number of sensordata entries.
    pub fn dim(&self) -> usize {
        self.kind.dim()
    }
}

/// A body's mass as the subtree sensors sum it, on the link that carries it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BodyMass {
    /// The link carrying the body; `None` for a body welded to the world.
    pub link: Option<usize>,
    /// Mass.
    pub mass: f64,
    /// Centre of mass in link coordinates (world coordinates without a link).
    pub com: Vec3,
    /// Rotational inertia about the centre of mass, in link axes.
    pub inertia: Mat3,
}

/// The masses of `vehicle`'s bodies on their links, in body order.
pub(super) fn body_masses(vehicle: &Vehicle, attachments: &[Attachment]) -> Vec<BodyMass> {
    vehicle
        .bodies
        .iter()
        .zip(attachments)
        .map(|(body, at)| match &body.inertia {
            Some(props) => {
                // ᵇX_ₗ: the rotation takes link axes to body axes.
                let to_body = at.offset.rot;
                BodyMass {
                    link: at.link,
                    mass: props.mass,
                    com: at.offset.trans + to_body.transpose() * props.com,
                    inertia: to_body.transpose() * props.inertia * to_body,
                }
            }
            None => BodyMass { link: at.link, mass: 0.0, com: at.offset.trans, inertia: Mat3::zeros() },
        })
        .collect()
}

/// The sensors of `vehicle`, resolved against the compiled joints, the
/// bodies' attachments to links and the sites' frames.
pub(super) fn compile_sensors(
    vehicle: &Vehicle,
    joints: &[JointInfo],
    attachments: &[Attachment],
    sites: &[SiteFrame],
) -> Result<Vec<Sensor>, ModelError> {
    let mut adr = 0;
    let mut compiled = Vec::with_capacity(vehicle.sensors.len());
    for (index, sensor) in vehicle.sensors.iter().enumerate() {
        let refused = |reason: String| ModelError::Sensor {
            sensor: match &sensor.name {
                Some(name) => format!("{} '{name}'", sensor.kind.name()),
                None => format!("{} {index}", sensor.kind.name()),
            },
            line: sensor.line,
            reason,
        };
        let (source, target) = match &sensor.target {
            SensorTarget::Joint(name) => {
                let joint = joints.iter().find(|j| &j.name == name).expect("the importer checked the joint");
                (SensorSource::Joint { dof: joint.dof_adr, qpos: joint.qpos_adr }, format!("joint '{name}'"))
            }
            SensorTarget::Actuator(k) => {
                let actuator = &vehicle.actuators[*k];
                let name = actuator.name.clone().unwrap_or_default();
                (SensorSource::Actuator { actuator: *k }, format!("actuator '{name}'"))
            }
            SensorTarget::Frame { object: FrameObject::Site(index), .. }
                if matches!(sensor.kind, SensorKind::Force | SensorKind::Torque) =>
            {
                let site = &vehicle.sites[*index];
                let (first, end, body) = match site.body {
                    Some(body) => (body, subtree_end(vehicle, body), format!("body '{}'", vehicle.bodies[body].name)),
                    None => (0, vehicle.bodies.len(), "the world body".to_string()),
                };
                // A body fixed to the world bears its weight: MuJoCo counts it.
                let weighed = vehicle.gravity != Vec3::zeros();
                if let Some(unknown) = vehicle.bodies[first..end].iter().find(|b| b.mass_unknown && weighed) {
                    return Err(refused(format!(
                        "the subtree of {body} holds body '{}', fixed to the world with mesh, sdf or height-field \
                         geoms whose mass nudyn does not compute, and its weight would count",
                        unknown.name
                    )));
                }
                let name = site.name.clone().unwrap_or_default();
                (SensorSource::Interaction { site: sites[*index], first, end }, format!("{body} at site '{name}'"))
            }
            SensorTarget::Frame { object, reference } => {
                let uses_object_axes = matches!(
                    sensor.kind,
                    SensorKind::FrameQuat | SensorKind::FrameXAxis | SensorKind::FrameYAxis | SensorKind::FrameZAxis
                );
                let (object_frame, object_quat) =
                    frame_of(vehicle, attachments, sites, object, uses_object_axes).map_err(&refused)?;
                let (reference_frame, reference_quat) = match reference {
                    Some(reference) => {
                        let (frame, quat) = frame_of(vehicle, attachments, sites, reference, true).map_err(&refused)?;
                        (Some(frame), quat)
                    }
                    None => (None, Quat::identity()),
                };
                let mut target = object_name(vehicle, object);
                if let Some(reference) = reference {
                    target = format!("{target} in the frame of {}", object_name(vehicle, reference));
                }
                let quats = [object_quat, reference_quat];
                (SensorSource::Frame { object: object_frame, reference: reference_frame, quats }, target)
            }
            SensorTarget::Subtree(body) => {
                let (first, end, name) = match body {
                    Some(root) => (*root, subtree_end(vehicle, *root), vehicle.bodies[*root].name.clone()),
                    None => (0, vehicle.bodies.len(), "world".to_string()),
                };
                if let Some(unknown) = vehicle.bodies[first..end].iter().find(|b| b.mass_unknown) {
                    return Err(refused(format!(
                        "the subtree of body '{name}' holds body '{}', fixed to the world with mesh, sdf or \
                         height-field geoms whose mass nudyn does not compute",
                        unknown.name
                    )));
                }
                (SensorSource::Subtree { first, end }, format!("subtree of body '{name}'"))
            }
            SensorTarget::Tendon(k) => {
                let name = vehicle.tendons[*k].name.clone().unwrap_or_default();
                (SensorSource::Tendon { tendon: *k }, format!("tendon '{name}'"))
            }
            SensorTarget::None => (SensorSource::Clock, "time".to_string()),
        };
        compiled.push(Sensor {
            name: sensor.name.clone(),
            kind: sensor.kind,
            source,
            target,
            cutoff: sensor.cutoff,
            adr,
            line: sensor.line,
        });
        adr += sensor.kind.dim();
    }
    Ok(compiled)
}

/// One past the last body of the subtree of `root` (bodies are in
/// depth-first order, so a subtree is a contiguous range).
fn subtree_end(vehicle: &Vehicle, root: usize) -> usize {
    let in_subtree = |mut body: usize| loop {
        if body == root {
            return true;
        }
        match vehicle.bodies[body].parent {
            Some(parent) => body = parent,
            None => return false,
        }
    };
    (root + 1..vehicle.bodies.len()).find(|&b| !in_subtree(b)).unwrap_or(vehicle.bodies.len())
}

/// The MJCF name of a frame object, for descriptions.
fn object_name(vehicle: &Vehicle, object: &FrameObject) -> String {
    let body = |index: &Option<usize>| index.map_or("world".to_string(), |b| vehicle.bodies[b].name.clone());
    match object {
        FrameObject::Body(index) => format!("body '{}' (inertial frame)", body(index)),
        FrameObject::XBody(index) => format!("body '{}'", body(index)),
        FrameObject::Site(index) => format!("site '{}'", vehicle.sites[*index].name.clone().unwrap_or_default()),
    }
}

/// A frame object's frame on its link, and its rotation relative to the
/// link as a quaternion. `axes_needed`: its orientation matters, which nudyn
/// knows for a body's inertial frame only when the file gives it.
fn frame_of(
    vehicle: &Vehicle,
    attachments: &[Attachment],
    sites: &[SiteFrame],
    object: &FrameObject,
    axes_needed: bool,
) -> Result<(SiteFrame, Quat), String> {
    let body_frame = |index: &Option<usize>| match index {
        Some(b) => (attachments[*b].frame(&Transform::identity()), attachments[*b].quat),
        None => (SiteFrame { link: None, frame: Transform::identity(), node: None }, Quat::identity()),
    };
    Ok(match object {
        FrameObject::Site(index) => {
            let site = &vehicle.sites[*index];
            let body_quat = site.body.map_or(Quat::identity(), |b| attachments[b].quat);
            (sites[*index], body_quat * site.quat)
        }
        FrameObject::XBody(index) => body_frame(index),
        FrameObject::Body(None) => body_frame(&None),
        FrameObject::Body(Some(b)) => {
            let body = &vehicle.bodies[*b];
            let quat = match (body.inertial_quat, axes_needed) {
                (Some(quat), _) => quat,
                (None, false) => Quat::identity(),
                (None, true) => {
                    return Err(format!(
                        "the axes of body '{}''s inertial frame are not known (the vehicle was not imported \
                         from MJCF); measure objtype \"xbody\" or a site instead",
                        body.name
                    ));
                }
            };
            let (at, body_quat) = body_frame(&Some(*b));
            let in_body = Transform::from_pose(&quat.to_rotation_matrix().into_inner(), &body.inertial_pos);
            (SiteFrame { link: at.link, frame: in_body.compose(&at.frame), node: at.node }, body_quat * quat)
        }
    })
}
