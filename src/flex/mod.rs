//! Flexible bodies: an MJCF body made flexible by a modal data file
//! (constrained modes of its structure, docs/flexible.md).
//!
//! The file names its nodes (position, mass, rotary inertia in the body
//! frame) and its modes (frequency, damping ratio, a shape at every node).
//! [`modal_file::read`] checks it and gives a [`ModalBody`] in SI units with
//! mass-normalized modes; [`ModalBody::check_mass_properties`] holds its
//! nodes to the body's `<inertial>`, so that the same MJCF file is the
//! rigid vehicle in MuJoCo and the undeformed one here.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::math::{Mat3, Vec3};
use crate::vehicle::MassProperties;

pub mod modal_file;
pub mod nodes;
pub mod point_masses;
pub mod rotation;

/// How closely the nodes must reproduce the body's mass, centre of mass and
/// inertia (relative).
pub const MASS_PROPERTIES_TOLERANCE: f64 = 1e-6;

/// One node of a flexible body: a lumped mass at a point of the undeformed body.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Node {
    /// The node's name in the modal file.
    pub name: String,
    /// Position in the body frame (m).
    pub position: Vec3,
    /// Mass (kg).
    pub mass: f64,
    /// Rotary inertia about the node, body axes (kg m²).
    pub rotary_inertia: Mat3,
}

/// One constrained mode, mass-normalized in SI (Φᵀ M Φ = 1 kg m² … so that
/// the modal coordinate has units √kg·m).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Mode {
    /// ω (rad/s).
    pub angular_frequency: f64,
    /// ζ: the modal damping force is 2ζω times the modal rate.
    pub damping_ratio: f64,
    /// Displacement of each node per unit modal coordinate (body axes).
    pub translation: Vec<Vec3>,
    /// Rotation of each node per unit modal coordinate (body axes).
    pub rotation: Vec<Vec3>,
}

/// A body's modal data, checked, in SI, with mass-normalized modes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModalBody {
    /// The MJCF body the file makes flexible.
    pub body: String,
    /// The nodes, in file order.
    pub nodes: Vec<Node>,
    /// The modes, by rising frequency.
    pub modes: Vec<Mode>,
}

/// Why a modal file cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ModalError {
    /// The file cannot be read.
    #[error("cannot read the modal file {} of body '{body}': {source}", path.display())]
    Read {
        /// The flexible body.
        body: String,
        /// The file.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// The file is not a valid modal file.
    #[error("modal file {} of body '{body}': {problem}", path.display())]
    Invalid {
        /// The flexible body.
        body: String,
        /// The file.
        path: PathBuf,
        /// Which field is wrong, and how.
        problem: String,
    },
    /// The nodes do not reproduce the body's `<inertial>`.
    #[error(
        "body '{body}': its modal file's nodes give {nodes}, but its inertial gives {inertial} \
         (they must agree within {MASS_PROPERTIES_TOLERANCE:e} relative: {what} differs by {difference:.3e})"
    )]
    MassProperties {
        /// The flexible body.
        body: String,
        /// The nodes' mass properties, written out.
        nodes: String,
        /// The `<inertial>`'s, written out.
        inertial: String,
        /// The first quantity that differs: mass, centre of mass or inertia.
        what: &'static str,
        /// By how much, relative.
        difference: f64,
    },
}

impl ModalBody {
    /// Mass, centre of mass and inertia about it of the undeformed nodes.
    pub fn mass_properties(&self) -> MassProperties {
        let mass: f64 = self.nodes.iter().map(|n| n.mass).sum();
        let com = if mass > 0.0 {
            self.nodes.iter().map(|n| n.position * n.mass).sum::<Vec3>() / mass
        } else {
            Vec3::zeros()
        };
        let inertia = self
            .nodes
            .iter()
            .map(|n| {
                let d = n.position - com;
                n.rotary_inertia + (Mat3::identity() * d.norm_squared() - d * d.transpose()) * n.mass
            })
            .sum();
        MassProperties { mass, com, inertia }
    }

    /// Fails unless the nodes give the body's mass, centre of mass and
    /// inertia (`inertial`, None for a massless body) within
    /// [`MASS_PROPERTIES_TOLERANCE`].
    pub fn check_mass_properties(&self, inertial: Option<&MassProperties>) -> Result<(), ModalError> {
        let nodes = self.mass_properties();
        let zero = MassProperties { mass: 0.0, com: Vec3::zeros(), inertia: Mat3::zeros() };
        let inertial = inertial.unwrap_or(&zero);
        let mass_scale = nodes.mass.max(inertial.mass).max(f64::MIN_POSITIVE);
        // The centre of mass relative to the body's size (its radius of gyration).
        let length_scale =
            (nodes.inertia.trace().max(inertial.inertia.trace()) / mass_scale).sqrt().max(f64::MIN_POSITIVE);
        let inertia_scale = nodes.inertia.norm().max(inertial.inertia.norm()).max(f64::MIN_POSITIVE);
        let differences = [
            ("mass", (nodes.mass - inertial.mass).abs() / mass_scale),
            ("centre of mass", (nodes.com - inertial.com).norm() / length_scale),
            ("inertia", (nodes.inertia - inertial.inertia).norm() / inertia_scale),
        ];
        match differences.into_iter().find(|(_, d)| *d > MASS_PROPERTIES_TOLERANCE) {
            None => Ok(()),
            Some((what, difference)) => Err(ModalError::MassProperties {
                body: self.body.clone(),
                nodes: describe(&nodes),
                inertial: describe(inertial),
                what,
                difference,
            }),
        }
    }

    /// The node named `name`.
    pub fn node(&self, name: &str) -> Option<usize> {
        self.nodes.iter().position(|n| n.name == name)
    }
}

fn describe(p: &MassProperties) -> String {
    let i = &p.inertia;
    format!(
        "mass {} kg, centre of mass ({}, {}, {}) m, inertia about it (Ixx Iyy Izz Ixy Ixz Iyz) ({} {} {} {} {} {}) kg m²",
        p.mass,
        p.com.x,
        p.com.y,
        p.com.z,
        i[(0, 0)],
        i[(1, 1)],
        i[(2, 2)],
        i[(0, 1)],
        i[(0, 2)],
        i[(1, 2)]
    )
}
