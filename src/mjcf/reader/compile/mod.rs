//! The compile stage: the spec tree the reader gives (`ReadTree`: every
//! element's defaults resolved and its values checked, the objects it
//! names by name, its line and label kept for messages) turned into the
//! vehicle's types, as MuJoCo's compiler turns its spec into a model: the
//! body tree first (`bodies.rs`), then the tendons, equalities, actuators
//! and sensors, whose names resolve into it (`sections.rs`), then what
//! needs them all: `fusestatic`, `settotalmass` (`fuse.rs`), and the
//! keyframes' sizes.

mod bodies;
mod fuse;
mod sections;

use super::{JointSpec, Pose, Reader};
use crate::mjcf::actuator::ActuatorSpec;
use crate::mjcf::defaults::GeomSettings;
use crate::mjcf::element::Origin;
use crate::mjcf::equality::EqualitySpec;
use crate::mjcf::error::MjcfError;
use crate::mjcf::inertia::BodyInertia;
use crate::mjcf::keyframe::KeySpec;
use crate::mjcf::sensor::SensorSpec;
use crate::mjcf::tendon::TendonSpec;
use crate::vehicle::Site;

/// The spec tree: the document as parsed, for the compile stage.
#[derive(Default)]
pub(super) struct ReadTree {
    /// Each body, in the vehicle's order.
    pub bodies: Vec<BodySpec>,
    /// Every geom, the world body's too, in document order.
    pub geoms: Vec<GeomSpec>,
    /// Every site, the world body's too, in document order.
    pub sites: Vec<SiteSpec>,
    /// The tendons of every `<tendon>` section, in document order.
    pub tendons: Vec<TendonSpec>,
    /// The elements of every `<equality>` section, in document order.
    pub equalities: Vec<EqualitySpec>,
    /// Each `<actuator>` section's elements (a section's `<replicate>`
    /// copies come at its end).
    pub actuator_sections: Vec<Vec<ActuatorSpec>>,
    /// Each `<sensor>` section's elements, likewise.
    pub sensor_sections: Vec<Vec<SensorSpec>>,
    /// The `<key>`s of every `<keyframe>` section, in document order.
    pub keyframes: Vec<KeySpec>,
}

/// A `<site>` as read.
pub(super) struct SiteSpec {
    /// The site, its pose in the `<frame>`s around it.
    pub site: Site,
    /// The pose of those `<frame>`s in its body.
    pub frame: Option<Pose>,
    /// Whether it is fitted to a mesh (which moves its frame).
    pub fitted_to_mesh: bool,
}

/// A `<body>` as read.
pub(super) struct BodySpec {
    /// Its name (one made up when the file gives none).
    pub name: String,
    /// Its parent; `None` for the world body.
    pub parent: Option<usize>,
    /// The pose of the `<frame>`s around it, in its parent.
    pub frame: Option<Pose>,
    /// Its joints, with their settings resolved.
    pub joints: Vec<JointSpec>,
    /// `gravcomp`.
    pub gravcomp: f64,
    /// What its mass properties and frame come from.
    pub mass: MassSource,
}

/// What a body's mass properties and frame come from.
pub(super) struct MassSource {
    /// The `<body>` element, for messages.
    pub at: Origin,
    /// Its `<inertial>`, in the `<frame>`s around it (their pose in the body).
    pub explicit: Option<(BodyInertia, Option<Pose>)>,
    /// Whether a joint lies between it and the world.
    pub moving: bool,
    /// Whether its frame moves to its inertial frame (a free body without
    /// children, as `align` or `<compiler alignfree>` says).
    pub aligned: bool,
    /// Its pose in its parent before any `<frame>` around it.
    pub own_pose: Pose,
}

/// A `<geom>` as read.
pub(super) struct GeomSpec {
    /// The element, for messages.
    pub at: Origin,
    /// Its class's settings with its own attributes applied.
    pub settings: GeomSettings,
    /// The pose of the `<frame>`s around it, in its body.
    pub frame: Option<Pose>,
    /// Its name, with its `<replicate>` suffix.
    pub name: Option<String>,
    /// Its body; `None` for the world body.
    pub body: Option<usize>,
}

impl Reader {
    /// Compiles `tree`: the bodies, then what names them.
    pub(super) fn compile(&mut self, tree: ReadTree) -> Result<(), MjcfError> {
        let ReadTree { bodies, geoms, sites, tendons, equalities, actuator_sections, sensor_sections, keyframes } =
            tree;
        self.note_wrap_obstacles(&tendons);
        self.compile_bodies(bodies, geoms, sites)?;
        // Before the equalities, actuators and sensors, which may name tendons.
        self.compile_tendons(&tendons)?;
        self.compile_equalities(&equalities)?;
        for section in &actuator_sections {
            self.compile_actuators(section)?;
        }
        // After the actuators, which sensors may name.
        for section in &sensor_sections {
            self.compile_sensors(section)?;
        }
        // Before fusestatic renumbers the bodies.
        self.warn_of_contacts();
        self.compile_masses()?;
        self.compile_keyframes(keyframes)
    }
}
