//! Why an MJCF file was rejected.

use std::path::PathBuf;

/// An MJCF file the importer cannot turn into a [`crate::vehicle::Vehicle`].
///
/// Every variant found in the document names the element (its tag, with its
/// `name` attribute when it has one, e.g. `joint name="j2"`) and the 1-based
/// line of the element's start tag; `Display` starts with
/// `line N: <element>: `, preceded by the file's path when the element is in
/// an included file ([`MjcfError::Included`]).
#[derive(Debug, thiserror::Error)]
pub enum MjcfError {
    /// The file could not be read.
    // The io error is the source, so error chains (anyhow's {:#}) print it once.
    #[error("cannot read {}", path.display())]
    Io {
        /// The file's path.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },

    /// The text is not well-formed XML (there is no element to name).
    #[error("line {line}, column {column}: not well-formed XML: {message}")]
    Xml {
        /// Line of the syntax error.
        line: u32,
        /// Column of the syntax error.
        column: u32,
        /// The XML parser's description.
        message: String,
    },

    /// The root element is not `<mujoco>`.
    #[error("line {line}: <{element}>: expected the root element <mujoco>")]
    WrongRoot {
        /// Line of the root element.
        line: u32,
        /// The root element found.
        element: String,
    },

    /// `<mujoco>` has no `<worldbody>`, so the file describes no vehicle.
    #[error("line {line}: <{element}>: missing <worldbody>")]
    MissingWorldbody {
        /// Line of the `<mujoco>` element.
        line: u32,
        /// The root element.
        element: String,
    },

    /// An attribute this element does not have (typos must not pass silently).
    #[error("line {line}: <{element}>: unknown attribute '{attribute}'")]
    UnknownAttribute {
        /// Line of the element.
        line: u32,
        /// The element.
        element: String,
        /// The attribute's name.
        attribute: String,
    },

    /// A required attribute is missing.
    #[error("line {line}: <{element}>: missing attribute '{attribute}'")]
    MissingAttribute {
        /// Line of the element.
        line: u32,
        /// The element.
        element: String,
        /// The attribute's name.
        attribute: String,
    },

    /// An attribute's value is malformed or out of range.
    #[error("line {line}: <{element}>: attribute '{attribute}' expects {expected}, found \"{found}\"")]
    BadValue {
        /// Line of the element.
        line: u32,
        /// The element.
        element: String,
        /// The attribute's name.
        attribute: String,
        /// What a valid value looks like.
        expected: String,
        /// The value found.
        found: String,
    },

    /// Two attributes that exclude each other.
    #[error("line {line}: <{element}>: attributes '{first}' and '{second}' cannot both be given")]
    ConflictingAttributes {
        /// Line of the element.
        line: u32,
        /// The element.
        element: String,
        /// The first attribute.
        first: String,
        /// The second attribute.
        second: String,
    },

    /// An element that has no meaning where it is.
    #[error("line {line}: <{element}>: unknown element inside <{parent}>")]
    UnknownElement {
        /// Line of the element.
        line: u32,
        /// The element.
        element: String,
        /// Its parent's tag.
        parent: String,
    },

    /// An element that may appear only once in its parent appears again.
    #[error("line {line}: <{element}>: may appear only once in <{parent}> (first at line {first_line})")]
    Repeated {
        /// Line of the repetition.
        line: u32,
        /// The element.
        element: String,
        /// Its parent's tag.
        parent: String,
        /// Line of the first occurrence.
        first_line: u32,
    },

    /// A valid MuJoCo construct whose effect on the dynamics nudyn does not model.
    #[error("line {line}: <{element}>: not supported: {reason}")]
    Unsupported {
        /// Line of the element.
        line: u32,
        /// The element.
        element: String,
        /// What is unsupported and why.
        reason: String,
    },

    /// A `class` or `childclass` that names no `<default>` class.
    #[error("line {line}: <{element}>: unknown default class \"{class}\"")]
    UnknownClass {
        /// Line of the element.
        line: u32,
        /// The element.
        element: String,
        /// The class name.
        class: String,
    },

    /// Two bodies, two joints or two default classes with the same name.
    #[error("line {line}: <{element}>: {kind} name \"{name}\" is already used at line {first_line}")]
    DuplicateName {
        /// Line of the second element.
        line: u32,
        /// The second element.
        element: String,
        /// "body", "joint" or "default class".
        kind: &'static str,
        /// The repeated name.
        name: String,
        /// Line of the first element with that name.
        first_line: u32,
    },

    /// An error in a file the model includes (`<include file>`): the
    /// error's line is a line of that file.
    #[error("{}: {error}", path.display())]
    Included {
        /// The included file.
        path: PathBuf,
        /// The error found in it.
        error: Box<MjcfError>,
    },

    /// A model MuJoCo's compiler itself rejects (the reason says which rule).
    #[error("line {line}: <{element}>: {reason}")]
    Invalid {
        /// Line of the element.
        line: u32,
        /// The element.
        element: String,
        /// The rule broken.
        reason: String,
    },
}

impl MjcfError {
    /// The line the error names, if it names one (not for an error in an
    /// included file, whose line is already that file's).
    pub(crate) fn line_mut(&mut self) -> Option<&mut u32> {
        match self {
            MjcfError::Io { .. } | MjcfError::Included { .. } => None,
            MjcfError::Xml { line, .. }
            | MjcfError::WrongRoot { line, .. }
            | MjcfError::MissingWorldbody { line, .. }
            | MjcfError::UnknownAttribute { line, .. }
            | MjcfError::MissingAttribute { line, .. }
            | MjcfError::BadValue { line, .. }
            | MjcfError::ConflictingAttributes { line, .. }
            | MjcfError::UnknownElement { line, .. }
            | MjcfError::Repeated { line, .. }
            | MjcfError::Unsupported { line, .. }
            | MjcfError::UnknownClass { line, .. }
            | MjcfError::DuplicateName { line, .. }
            | MjcfError::Invalid { line, .. } => Some(line),
        }
    }
}
