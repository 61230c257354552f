//! The FMI contract of a nudyn FMU: everything the exporter writes into
//! `modelDescription.xml` that the FMU binary must then honour, kept in one
//! place so that the two cannot drift.
//!
//! - [`blocks`]: value references numbered block by block, and the blocks'
//!   names and shapes, for both sides;
//! - [`variable`]: what a variable is (causality, variability, range) and
//!   when it may be set: the exporter writes it, the FMU enforces it;
//! - [`plant`]: the vehicle FMU's variables, value references, parameter
//!   defaults and resource file;
//! - [`controller`]: the controller FMU's likewise;
//! - [`fmi3`]: the same variables as FMI 3.0 arrays, for both sides;
//! - [`capabilities`]: the capability flags of each kind of FMU;
//! - [`log`]: the log categories;
//! - [`resource`]: the resource files and the content-derived GUID.
#![warn(missing_docs)]

pub mod blocks;
pub mod capabilities;
pub mod controller;
pub mod fmi3;
pub mod log;
pub mod plant;
pub mod resource;
pub mod variable;

#[cfg(test)]
mod agreement_tests;

/// The default communication step of the DefaultExperiment (s).
pub const DEFAULT_STEP_SIZE: f64 = 0.01;

/// The stop time of the DefaultExperiment (s).
pub const DEFAULT_STOP_TIME: f64 = 10.0;
