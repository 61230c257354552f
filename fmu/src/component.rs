//! What an instance runs: the plant (the vehicle's dynamics, [`Slave`]) or
//! its controller ([`Controller`]), told apart at fmi2Instantiate by the
//! resource the FMU ships. The FMI layer calls only this type, so its
//! checks (state machine, pointers, value references, statuses, logging)
//! are the same for both.

use crate::controller::{CONTROLLER_RESOURCE_FILE, Controller};
use crate::slave::{Slave, SlaveError, StepReport};
use crate::snapshot::Snapshot;
use crate::state::Phase;
use crate::uri::resource_directory;

/// The slave behind one FMU instance.
pub enum Component {
    /// The vehicle's dynamics: ε in, θ and ν out.
    Plant(Box<Slave>),
    /// The control law: θ and ν in, ε out.
    Controller(Box<Controller>),
}

impl Component {
    /// Loads the FMU's resources: a controller if `controller.json` is
    /// there, else the plant (whose loader reports a missing `model.json`).
    pub fn load(resource_location: &str, guid: &str) -> Result<Component, SlaveError> {
        let directory = resource_directory(resource_location)?;
        if directory.join(CONTROLLER_RESOURCE_FILE).is_file() {
            return Ok(Component::Controller(Box::new(Controller::load(&directory, guid)?)));
        }
        Ok(Component::Plant(Box::new(Slave::load(resource_location, guid)?)))
    }

    /// fmi2Reset.
    pub fn reset(&mut self) {
        match self {
            Component::Plant(s) => s.reset(),
            Component::Controller(c) => c.reset(),
        }
    }

    /// fmi2SetupExperiment.
    pub fn setup_experiment(&mut self, tolerance: Option<f64>, start_time: f64, stop_time: Option<f64>) -> Result<(), SlaveError> {
        match self {
            Component::Plant(s) => s.setup_experiment(tolerance, start_time, stop_time),
            Component::Controller(c) => c.setup_experiment(tolerance, start_time, stop_time),
        }
    }

    /// fmi2ExitInitializationMode.
    pub fn initialize(&mut self) -> Result<(), SlaveError> {
        match self {
            Component::Plant(s) => s.initialize(),
            Component::Controller(c) => c.initialize(),
        }
    }

    /// fmi2GetReal.
    pub fn get_real(&mut self, vrs: &[u32], values: &mut [f64]) -> Result<(), SlaveError> {
        match self {
            Component::Plant(s) => s.get_real(vrs, values),
            Component::Controller(c) => c.get_real(vrs, values),
        }
    }

    /// fmi2SetReal; `initialized`: after fmi2ExitInitializationMode.
    pub fn set_real(&mut self, vrs: &[u32], values: &[f64], initialized: bool) -> Result<(), SlaveError> {
        match self {
            Component::Plant(s) => s.set_real(vrs, values, initialized),
            Component::Controller(c) => c.set_real(vrs, values),
        }
    }

    /// fmi2GetInteger (the controller has no Integer variables).
    pub fn get_integer(&self, vrs: &[u32], values: &mut [i32]) -> Result<(), SlaveError> {
        match self {
            Component::Plant(s) => s.get_integer(vrs, values),
            Component::Controller(_) => none_of("Integer", vrs),
        }
    }

    /// fmi2SetInteger.
    pub fn set_integer(&mut self, vrs: &[u32], values: &[i32], initialized: bool) -> Result<(), SlaveError> {
        match self {
            Component::Plant(s) => s.set_integer(vrs, values, initialized),
            Component::Controller(_) => none_of("Integer", vrs),
        }
    }

    /// fmi2GetBoolean: the value of the variables `vrs` (all the same one).
    pub fn get_boolean(&self, vrs: &[u32]) -> Result<bool, SlaveError> {
        match self {
            Component::Plant(s) => s.get_boolean(vrs),
            Component::Controller(_) => none_of("Boolean", vrs).map(|()| false),
        }
    }

    /// fmi2SetBoolean.
    pub fn set_boolean(&mut self, vrs: &[u32], values: &[bool], initialized: bool) -> Result<(), SlaveError> {
        match self {
            Component::Plant(s) => s.set_boolean(vrs, values, initialized),
            Component::Controller(_) => none_of("Boolean", vrs),
        }
    }

    /// fmi2SetRealInputDerivatives.
    pub fn set_input_derivatives(&mut self, vrs: &[u32], orders: &[i32], values: &[f64]) -> Result<(), SlaveError> {
        match self {
            Component::Plant(s) => s.set_input_derivatives(vrs, orders, values),
            Component::Controller(c) => c.set_input_derivatives(vrs),
        }
    }

    /// fmi2GetRealOutputDerivatives.
    pub fn get_output_derivatives(&mut self, vrs: &[u32], orders: &[i32], values: &mut [f64]) -> Result<(), SlaveError> {
        match self {
            Component::Plant(s) => s.get_output_derivatives(vrs, orders, values),
            Component::Controller(c) => c.get_output_derivatives(vrs),
        }
    }

    /// The checks fmi2DoStep makes before stepping.
    pub fn check_step_arguments(&self, time: f64, step: f64) -> Result<(), SlaveError> {
        match self {
            Component::Plant(s) => s.check_step_arguments(time, step),
            Component::Controller(c) => c.check_step_arguments(time),
        }
    }

    /// fmi2DoStep; the plant reports what its integration did.
    pub fn do_step(&mut self, time: f64, step: f64) -> Result<Option<StepReport>, SlaveError> {
        match self {
            Component::Plant(s) => s.do_step(time, step).map(Some),
            Component::Controller(c) => c.do_step(time, step).map(|()| None),
        }
    }

    /// fmi2LastSuccessfulTime.
    pub fn time(&self) -> f64 {
        match self {
            Component::Plant(s) => s.time(),
            Component::Controller(c) => c.time(),
        }
    }

    /// fmi2Terminated status: whether the slave cannot go on.
    pub fn failed_for_good(&self) -> bool {
        match self {
            Component::Plant(s) => s.failed_for_good(),
            Component::Controller(_) => false,
        }
    }

    /// Saves the state into an existing FMU state.
    pub fn save(&self, phase: Phase, snapshot: &mut Snapshot) -> Result<(), SlaveError> {
        match self {
            Component::Plant(s) => {
                s.save(phase, snapshot);
                Ok(())
            }
            Component::Controller(_) => Err(SlaveError::NoFmuState),
        }
    }

    /// A new FMU state.
    pub fn snapshot(&self, phase: Phase) -> Result<Snapshot, SlaveError> {
        match self {
            Component::Plant(s) => Ok(s.snapshot(phase)),
            Component::Controller(_) => Err(SlaveError::NoFmuState),
        }
    }

    /// Restores an FMU state.
    pub fn restore(&mut self, snapshot: &Snapshot) -> Result<(), SlaveError> {
        match self {
            Component::Plant(s) => s.restore(snapshot),
            Component::Controller(_) => Err(SlaveError::NoFmuState),
        }
    }

    /// Reads a serialized FMU state.
    pub fn deserialize(&self, bytes: &[u8]) -> Result<Snapshot, SlaveError> {
        match self {
            Component::Plant(s) => s.deserialize(bytes),
            Component::Controller(_) => Err(SlaveError::NoFmuState),
        }
    }
}

/// A type of which the FMU has no variables: any value reference is unknown.
fn none_of(kind: &'static str, vrs: &[u32]) -> Result<(), SlaveError> {
    match vrs.first() {
        Some(&vr) => Err(SlaveError::UnknownValueReference { vr, kind }),
        None => Ok(()),
    }
}
