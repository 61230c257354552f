//! MJCF importer: reads a MuJoCo XML file into a [`Vehicle`], resolving
//! defaults, orientations, angle units and geom-derived mass properties
//! exactly as MuJoCo 4.0's compiler does.
//!
//! Elements without effect on the dynamics (cameras, lights, visual
//! settings…) are ignored with a warning each; elements that would change
//! the dynamics in ways nudyn does not model (MuJoCo's flexes and
//! composites, fluid forces, muscles…) are rejected with an [`MjcfError`]
//! naming the element and its line (and its file, when it is in an included
//! one). Sites, actuators and sensors are read: actuators act through
//! `ctrl`. `<keyframe>`s are kept ([`keyframe`]), and `<custom>` texts
//! naming modal data files make bodies flexible (`crate::flex`).
//! `<include>`d files are merged in, `<frame>`s composed into what they
//! place, mocap bodies fixed to the world, and `<compiler fusestatic>`
//! applied, as MuJoCo 4.0 does.

mod actuator;
mod attributes;
mod bodies;
mod contacts;
mod defaults;
mod element;
mod equality;
mod error;
mod include;
mod inertia;
pub mod keyframe;
mod mesh;
mod orientation;
mod reader;
mod sensor;
mod support;
mod tendon;

use std::fmt;
use std::path::{Path, PathBuf};

pub use error::MjcfError;
pub use support::support_table;

use crate::vehicle::Vehicle;

/// The result of a successful import.
#[derive(Clone, Debug, PartialEq)]
pub struct Imported {
    /// The vehicle the file describes.
    pub vehicle: Vehicle,
    /// What the importer ignored, in document order.
    pub warnings: Vec<MjcfWarning>,
    /// The `<key>`s of the file's `<keyframe>` sections, in document order.
    pub keyframes: Vec<keyframe::Keyframe>,
}

/// Something in the file that the importer ignored.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MjcfWarning {
    /// The included file the element is in (`<include>`); `None` for the
    /// main file.
    pub file: Option<PathBuf>,
    /// 1-based line of the element in its file.
    pub line: u32,
    /// The element: its tag, with its `name` attribute when it has one
    /// (e.g. `camera name="top"`).
    pub element: String,
    /// What was ignored and why.
    pub message: String,
}

impl fmt::Display for MjcfWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(file) = &self.file {
            write!(f, "{}: ", file.display())?;
        }
        write!(f, "line {}: <{}>: {}", self.line, self.element, self.message)
    }
}

/// Reads an MJCF document; the files it includes (`<include file>`) and its
/// mesh files are looked for relative to the current directory.
pub fn parse_mjcf(xml: &str) -> Result<Imported, MjcfError> {
    reader::read(xml, None)
}

/// Reads an MJCF file and the files it includes, which are looked for
/// relative to its directory as MuJoCo looks for them.
pub fn load_mjcf(path: &Path) -> Result<Imported, MjcfError> {
    let bytes = read_regular_file(path).map_err(|source| MjcfError::Io { path: path.to_path_buf(), source })?;
    let xml = String::from_utf8(bytes).map_err(|e| MjcfError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidData, e),
    })?;
    reader::read(&xml, Some(path))
}

/// Reads a file the model names, refusing anything but a regular file: a
/// named pipe would block the import forever, a device never end.
pub(crate) fn read_regular_file(path: &Path) -> std::io::Result<Vec<u8>> {
    let file_type = std::fs::metadata(path)?.file_type();
    if !file_type.is_file() {
        let kind = if file_type.is_dir() { "a directory" } else { "a named pipe, device or socket" };
        return Err(std::io::Error::new(std::io::ErrorKind::InvalidInput, format!("not a regular file ({kind})")));
    }
    std::fs::read(path)
}
