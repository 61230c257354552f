//! Typed model of the FMI 2.0 `modelDescription.xml` of a co-simulation FMU.
//!
//! [`to_xml`] writes a [`FmiModelDescription`] as a document that validates
//! against the official FMI 2.0 XML schema, [`from_xml`] reads one back, and
//! [`validate()`] checks the semantic rules of the standard that the schema
//! cannot express (unique names, the `<ModelStructure>` lists, legal
//! causality/variability/initial combinations, references to types and
//! units).
//!
//! Section numbers (§) refer to the FMI 2.0.x specification, "Functional
//! Mock-up Interface for Model Exchange and Co-Simulation".

#![warn(missing_docs)]

pub mod fmi3;
mod model;
mod validation;
mod xsd;

pub use model::*;
pub use validation::{BaseType, Problem, StructureList, validate};

use serde::Serialize;

/// Failure to write or read a `modelDescription.xml`.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The model could not be serialized (e.g. a string that XML cannot hold).
    #[error("cannot write modelDescription.xml: {0}")]
    Write(#[from] quick_xml::SeError),
    /// The document is not well-formed, misses a required attribute or
    /// element, or holds a value of the wrong type or spelling.
    #[error("cannot read modelDescription.xml: {0}")]
    Read(#[from] quick_xml::DeError),
}

const XML_DECLARATION: &str = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";

/// Writes `model` as a complete, indented `modelDescription.xml` document,
/// starting with the XML declaration.
///
/// This does not call [`validate()`]: a model that breaks the standard's
/// semantic rules is written as it is.
pub fn to_xml(model: &FmiModelDescription) -> Result<String, Error> {
    write_document(model)
}

/// `model` as an indented `<fmiModelDescription>` document after the XML declaration.
fn write_document(model: &impl Serialize) -> Result<String, Error> {
    let mut document = String::from(XML_DECLARATION);
    let mut serializer = quick_xml::se::Serializer::with_root(&mut document, Some("fmiModelDescription"))?;
    serializer.indent(' ', 2);
    model.serialize(serializer)?;
    document.push('\n');
    Ok(document)
}

/// Reads a `modelDescription.xml` document.
///
/// Elements this crate does not model (`<VendorAnnotations>`) are ignored. `<Annotations>` inside a
/// `<ScalarVariable>` are not supported and make reading fail.
pub fn from_xml(document: &str) -> Result<FmiModelDescription, Error> {
    Ok(quick_xml::de::from_str(document)?)
}
