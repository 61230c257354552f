//! The binary of every nudyn FMU: FMI 2.0 and FMI 3.0, co-simulation and
//! model exchange, plant and controller. `nudyn export` copies this cdylib
//! into the FMU's `binaries/` folder (`linux64/<modelIdentifier>.so` for
//! FMI 2.0, `x86_64-linux/<modelIdentifier>.so` for FMI 3.0; the win64 DLL
//! likewise) beside the resource file (`resources/model.json` or
//! `resources/controller.json`); the exported symbols are the standard,
//! unprefixed `fmi2*` and `fmi3*` names.
//!
//! - [`layer`]: the generic FMI layer both versions share (instances,
//!   the entry path, statuses, logging, FMU states); with [`fmi2`] and
//!   [`fmi3`], the functions of each version, the only `unsafe` code;
//! - [`state`]: the state machine's table of allowed calls;
//! - [`calls`]: the argument checks every component shares;
//! - [`component`]: the one interface of what an instance runs, and the
//!   errors of its calls and steps;
//! - [`load`]: the resources read and checked at instantiation, and the
//!   component made from them;
//! - [`plant`]: the vehicle's dynamics, integrated;
//! - [`partials`]: the plant's exact partial derivatives;
//! - [`controller`]: the control law;
//! - [`snapshot`]: FMU states and their serialized form;
//! - [`uri`]: the resource location.

#[cfg(test)]
mod agreement_tests;
mod calls;
mod component;
mod controller;
pub mod fmi2;
pub mod fmi3;
mod layer;
mod load;
mod partials;
mod plant;
mod snapshot;
mod state;
#[cfg(test)]
mod step_loop_allocations;
#[cfg(test)]
mod test_resources;
mod uri;
