//! Compiling a vehicle into a [`Model`]: first its structure (links,
//! inertias, transmissions, sensors, constraint lists: `model::Tree`),
//! then one stage at qpos0 that evaluates the dynamics once for every
//! constant MuJoCo's compiler finds there (its `mj_setConst`, [`qpos0`]),
//! then the whole model, checked.
//!
//! It sits outside [`crate::model`] so that the model does not depend on
//! the passes that evaluate it.

mod equality;
mod invweight;
mod qpos0;

use crate::model::{Model, ModelError, Tree};
use crate::vehicle::Vehicle;

impl Model {
    /// Compiles a vehicle description into the link array.
    pub fn compile(vehicle: &Vehicle) -> Result<Model, ModelError> {
        Model::compile_with_wrench_inputs(vehicle, &[])
    }

    /// Compiles a vehicle with external wrench inputs on the named bodies
    /// (see [`Model::wrench_bodies`]).
    pub fn compile_with_wrench_inputs(vehicle: &Vehicle, wrench_bodies: &[String]) -> Result<Model, ModelError> {
        let tree = Tree::compile(vehicle, wrench_bodies)?;
        // The passes index by the model's addresses: check them before evaluating.
        tree.model.validate()?;
        let constants = qpos0::evaluate(&tree, vehicle)?;
        let model = tree.with_constants(constants);
        model.validate()?;
        Ok(model)
    }
}
