//! The modal data file that makes an MJCF body flexible (docs/flexible.md):
//! its JSON form, read strictly (unknown fields refused), then checked and
//! converted to SI units with mass-normalized modes.

use std::collections::HashSet;
use std::path::Path;

use serde::Deserialize;

use super::{ModalBody, ModalError, Mode, Node};
use crate::math::{Mat3, Vec3};

/// The value of the file's `format` field.
pub const FORMAT: &str = "nudyn-modal";
/// The file format version this reader understands.
pub const VERSION: u32 = 1;

/// Two modes count as orthogonal in the nodes' mass when Φᵢᵀ M Φⱼ is at
/// most this fraction of √(mᵢ mⱼ); unit modal masses are held to the same.
pub const ORTHOGONALITY_TOLERANCE: f64 = 1e-6;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    format: String,
    version: u32,
    #[serde(default)]
    units: Units,
    mass_normalized: bool,
    nodes: Vec<FileNode>,
    modes: Vec<FileMode>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Units {
    #[serde(default = "metre")]
    length: String,
    #[serde(default = "kilogram")]
    mass: String,
    #[serde(default = "hertz")]
    frequency: String,
}

fn metre() -> String {
    "m".into()
}
fn kilogram() -> String {
    "kg".into()
}
fn hertz() -> String {
    "Hz".into()
}

impl Default for Units {
    fn default() -> Self {
        Units { length: metre(), mass: kilogram(), frequency: hertz() }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileNode {
    name: String,
    position: [f64; 3],
    mass: f64,
    /// Ixx, Iyy, Izz, Ixy, Ixz, Iyz about the node, body axes (MJCF's
    /// `fullinertia` order).
    #[serde(default)]
    rotary_inertia: [f64; 6],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileMode {
    frequency: f64,
    damping_ratio: f64,
    /// Per node, in node order: three translations, then three rotations (rad).
    shape: Vec<[f64; 6]>,
}

/// Scale factors to SI of the file's units.
struct Scale {
    length: f64,
    mass: f64,
    /// To rad/s.
    angular_frequency: f64,
}

impl Scale {
    fn of(units: &Units) -> Result<Self, String> {
        let length = match units.length.as_str() {
            "m" => 1.0,
            "cm" => 1e-2,
            "mm" => 1e-3,
            other => return Err(format!("units.length is \"{other}\"; expected \"m\", \"cm\" or \"mm\"")),
        };
        let mass = match units.mass.as_str() {
            "kg" => 1.0,
            "g" => 1e-3,
            "t" => 1e3,
            other => return Err(format!("units.mass is \"{other}\"; expected \"kg\", \"g\" or \"t\"")),
        };
        let angular_frequency = match units.frequency.as_str() {
            "Hz" => std::f64::consts::TAU,
            "rad/s" => 1.0,
            other => return Err(format!("units.frequency is \"{other}\"; expected \"Hz\" or \"rad/s\"")),
        };
        Ok(Scale { length, mass, angular_frequency })
    }
}

/// Reads and checks the modal file at `path`, for the body `body`.
pub fn read(path: &Path, body: &str) -> Result<ModalBody, ModalError> {
    let text = std::fs::read_to_string(path).map_err(|source| ModalError::Read {
        body: body.to_string(),
        path: path.to_path_buf(),
        source,
    })?;
    parse(&text, body).map_err(|problem| ModalError::Invalid {
        body: body.to_string(),
        path: path.to_path_buf(),
        problem,
    })
}

/// Parses and checks a modal file's text; the error says which field is
/// wrong and how. Every number is finite: JSON has no NaN or infinity, and
/// serde_json refuses a number out of f64's range, with its line and column.
pub fn parse(text: &str, body: &str) -> Result<ModalBody, String> {
    let file: File = serde_json::from_str(text).map_err(|e| e.to_string())?;
    if file.format != FORMAT {
        return Err(format!("format is \"{}\"; expected \"{FORMAT}\"", file.format));
    }
    if file.version != VERSION {
        return Err(format!("version {} is not one this nudyn reads (it reads version {VERSION})", file.version));
    }
    let scale = Scale::of(&file.units)?;
    let nodes = convert_nodes(&file.nodes, &scale)?;
    let mut modes = convert_modes(&file.modes, &nodes, &scale)?;
    normalize_modes(&mut modes, &nodes, file.mass_normalized.then_some(&scale))?;
    Ok(ModalBody { body: body.to_string(), nodes, modes })
}

fn convert_nodes(nodes: &[FileNode], scale: &Scale) -> Result<Vec<Node>, String> {
    if nodes.is_empty() {
        return Err("nodes is empty; a flexible body needs at least one node".into());
    }
    let mut names = HashSet::new();
    let mut out = Vec::with_capacity(nodes.len());
    for (k, node) in nodes.iter().enumerate() {
        let field = format!("nodes[{k}] (\"{}\")", node.name);
        if node.name.is_empty() {
            return Err(format!("nodes[{k}].name is empty"));
        }
        if !names.insert(node.name.as_str()) {
            return Err(format!("{field}: the name is used by an earlier node"));
        }
        if node.mass < 0.0 {
            return Err(format!("{field}.mass is {}; masses cannot be negative", node.mass));
        }
        let [ixx, iyy, izz, ixy, ixz, iyz] = node.rotary_inertia;
        let rotary =
            Mat3::new(ixx, ixy, ixz, ixy, iyy, iyz, ixz, iyz, izz) * (scale.mass * scale.length * scale.length);
        let eigenvalues = rotary.symmetric_eigenvalues();
        if eigenvalues.iter().any(|&e| e < -1e-12 * rotary.norm()) {
            return Err(format!(
                "{field}.rotary_inertia has principal moments {:?}; an inertia cannot have a negative one",
                eigenvalues.as_slice()
            ));
        }
        out.push(Node {
            name: node.name.clone(),
            position: Vec3::from(node.position) * scale.length,
            mass: node.mass * scale.mass,
            rotary_inertia: rotary,
        });
    }
    Ok(out)
}

fn convert_modes(modes: &[FileMode], nodes: &[Node], scale: &Scale) -> Result<Vec<Mode>, String> {
    let mut out = Vec::with_capacity(modes.len());
    for (k, mode) in modes.iter().enumerate() {
        let field = format!("modes[{k}]");
        if mode.frequency <= 0.0 {
            return Err(format!(
                "{field}.frequency is {}; constrained modes have positive frequencies (rigid-body motion is the MJCF body's)",
                mode.frequency
            ));
        }
        if mode.damping_ratio < 0.0 {
            return Err(format!("{field}.damping_ratio is {}; it cannot be negative", mode.damping_ratio));
        }
        if mode.shape.len() != nodes.len() {
            return Err(format!(
                "{field}.shape has {} entries; expected one per node ({}), each three translations and three rotations",
                mode.shape.len(),
                nodes.len()
            ));
        }
        let mut translation = Vec::with_capacity(nodes.len());
        let mut rotation = Vec::with_capacity(nodes.len());
        for values in &mode.shape {
            translation.push(Vec3::new(values[0], values[1], values[2]) * scale.length);
            rotation.push(Vec3::new(values[3], values[4], values[5]));
        }
        out.push(Mode {
            angular_frequency: mode.frequency * scale.angular_frequency,
            damping_ratio: mode.damping_ratio,
            translation,
            rotation,
        });
    }
    if let Some(k) = out.windows(2).position(|pair| pair[1].angular_frequency < pair[0].angular_frequency) {
        return Err(format!(
            "modes[{}] has a lower frequency than modes[{k}]; list the modes by rising frequency",
            k + 1
        ));
    }
    Ok(out)
}

/// Φᵢᵀ M Φⱼ over the nodes' masses and rotary inertias.
pub(super) fn modal_mass(nodes: &[Node], a: &Mode, b: &Mode) -> f64 {
    nodes
        .iter()
        .enumerate()
        .map(|(j, node)| {
            node.mass * a.translation[j].dot(&b.translation[j])
                + a.rotation[j].dot(&(node.rotary_inertia * b.rotation[j]))
        })
        .sum()
}

/// Checks the modes' orthogonality (and, given the file's units when it
/// says its modes are mass-normalized, their unit modal masses in those
/// units), then scales them to unit modal mass in SI.
fn normalize_modes(modes: &mut [Mode], nodes: &[Node], mass_normalized: Option<&Scale>) -> Result<(), String> {
    let masses: Vec<f64> = modes.iter().map(|mode| modal_mass(nodes, mode, mode)).collect();
    for (k, &mass) in masses.iter().enumerate() {
        if mass <= 0.0 {
            return Err(format!("modes[{k}] moves no mass (its modal mass is {mass})"));
        }
    }
    for i in 0..modes.len() {
        for j in 0..i {
            let coupling = modal_mass(nodes, &modes[i], &modes[j]) / (masses[i] * masses[j]).sqrt();
            if coupling.abs() > ORTHOGONALITY_TOLERANCE {
                return Err(format!(
                    "modes[{j}] and modes[{i}] are not orthogonal in the nodes' mass (Φᵀ M Φ over their modal \
                     masses is {coupling:.3e}, at most {ORTHOGONALITY_TOLERANCE:e} allowed); a finite-element model \
                     with a consistent mass matrix needs lumped masses at these nodes"
                ));
            }
        }
    }
    if let Some(scale) = mass_normalized {
        // Translations scale by length, rotary inertias by mass·length²:
        // every modal mass in SI is its value in the file's units times mass·length².
        let unit = scale.mass * scale.length * scale.length;
        for (k, &mass) in masses.iter().enumerate() {
            let in_file_units = mass / unit;
            if (in_file_units - 1.0).abs() > ORTHOGONALITY_TOLERANCE {
                return Err(format!(
                    "mass_normalized is true, but modes[{k}]'s modal mass is {in_file_units} in the file's units, not 1"
                ));
            }
        }
    }
    for (mode, mass) in modes.iter_mut().zip(masses) {
        let factor = 1.0 / mass.sqrt();
        mode.translation.iter_mut().for_each(|t| *t *= factor);
        mode.rotation.iter_mut().for_each(|r| *r *= factor);
    }
    Ok(())
}
