//! The binary of a nudyn FMI 2.0 co-simulation FMU. `nudyn export` copies
//! this cdylib to `binaries/linux64/<modelIdentifier>.so` beside the
//! compiled model in `resources/model.json`; the exported symbols are the
//! standard, unprefixed `fmi2*` names.
//!
//! - [`fmi2`]: the generic FMI layer, the only `unsafe` code;
//! - [`state`]: the state machine's table of allowed calls;
//! - [`component`]: the plant or the controller, chosen by the resource;
//! - [`slave`]: the safe slave that integrates the vehicle;
//! - [`controller`]: the safe slave of a controller FMU (the control law);
//! - [`snapshot`]: FMU states and their serialized form;
//! - [`resource`]: the consistency check of the loaded model;
//! - [`uri`]: the resource location.

mod component;
mod controller;
pub mod fmi2;
mod resource;
mod slave;
mod snapshot;
mod state;
mod uri;
