//! The controller FMU (`nudyn export --controller`): the control law of
//! `nudyn::control` with the plant's variable names, so that a master
//! connects them name to name: plant `theta[i]` → controller `theta[i]`,
//! plant `nu[i]` → controller `nu[i]`, controller `eps[i]` → plant `eps[i]`.
//!
//! The controller is a direct-feedthrough map (θ, ν) ↦ ε with no state: its
//! outputs are calculated from its inputs and its tunable parameters (gains
//! and targets), and fmi2DoStep only advances time.

use serde::{Deserialize, Serialize};

use nudyn::control::{ControlLaw, ControlParameters, Objective};
use nudyn::model::Model;

use crate::blocks::{Block, RealBlock, every_variable, real_blocks, variable_at};
use crate::capabilities::Capabilities;
use crate::resource::Resource;
use crate::variable::Kind;

mod describe;
mod table;

pub use table::{CONTROLLER_TABLE, ControllerEntry};

/// What the controller FMU can do: nothing to save (its outputs are a
/// function of inputs and parameters), no input or output derivatives.
pub const CAPABILITIES: Capabilities = Capabilities {
    can_interpolate_inputs: false,
    max_output_derivative_order: 0,
    can_get_and_set_fmu_state: false,
    can_serialize_fmu_state: false,
    provides_directional_derivative: false,
    can_handle_variable_communication_step_size: true,
    model_exchange: false,
};

/// `resources/controller.json`: what the controller FMU loads.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ControllerResource {
    /// [`Resource::FORMAT`] of the writer.
    pub format: u32,
    /// The control law.
    pub law: ControlLaw,
    /// Whether the FMI 3.0 FMU declares every element as a scalar
    /// (`--fmi3-scalars`): absent (false) in files of FMUs with arrays.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub fmi3_scalars: bool,
    /// The compiled vehicle.
    pub model: Model,
}

impl ControllerResource {
    /// The resource of the controller of `model` with `law`.
    pub fn new(model: Model, law: ControlLaw) -> Self {
        ControllerResource { format: Self::FORMAT, law, fmi3_scalars: false, model }
    }

    /// The layout of its variables.
    pub fn layout(&self) -> ControllerLayout {
        ControllerLayout::new(&self.model, &self.law)
    }
}

impl Resource for ControllerResource {
    const FILE: &'static str = "controller.json";
    const FORMAT: u32 = 4;

    fn format(&self) -> u32 {
        self.format
    }

    fn model(&self) -> &Model {
        &self.model
    }

    fn real_blocks(&self) -> Vec<RealBlock> {
        self.layout().real_blocks()
    }

    fn fmi3_scalars(&self) -> bool {
        self.fmi3_scalars
    }

    fn dependencies(&self, vr: u32) -> Option<Vec<u32>> {
        self.layout().dependency_vrs(vr)
    }
}

/// One Real variable of the controller FMU; indices 0-based (1-based in names).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ControllerVariable {
    /// Parameter `c1[k+1]`: rate gain of dof k.
    RateGain(usize),
    /// Parameter `c2[k+1]`: gain of controlled quantity k.
    TargetGain(usize),
    /// Parameter `target[k+1]` (joint targets) or `target_position[1..3]`,
    /// `target_quaternion[1..4]` (pose target: k = 0..7).
    Target(usize),
    /// Input `theta[k+1]`.
    Theta(usize),
    /// Input `nu[k+1]`.
    Nu(usize),
    /// Output `eps[k+1]`.
    Eps(usize),
    /// Output `potential`: U = ½ ΔYᵀ c₂ ΔY.
    Potential,
    /// Output `target_error[k+1]`: ΔY = Ŷ − Y.
    TargetError(usize),
}

/// The controller's Real variables and value references: the entries of
/// [`CONTROLLER_TABLE`] numbered from 1 (c1, c2, target, theta, nu, eps,
/// potential, target_error).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ControllerLayout {
    /// Number of position coordinates.
    pub nq: usize,
    /// Number of dofs.
    pub nv: usize,
    /// Number of controlled quantities.
    pub ny: usize,
    /// Number of target values.
    pub target_len: usize,
    /// Whether the target is a pose (names target_position, target_quaternion).
    pub pose: bool,
}

impl ControllerLayout {
    /// The layout of the controller of `model` with `law`.
    pub fn new(model: &Model, law: &ControlLaw) -> Self {
        ControllerLayout {
            nq: model.nq,
            nv: model.nv,
            ny: law.ny(),
            target_len: law.target_len(),
            pose: matches!(law.objective, Objective::Pose(_)),
        }
    }

    /// The table's entries in value-reference order, each with the value
    /// reference of its first element and its length in this layout.
    fn entries(&self) -> impl Iterator<Item = (u32, &'static ControllerEntry, usize)> + '_ {
        let mut next = 1;
        CONTROLLER_TABLE.iter().map(move |entry| {
            let (first, len) = (next, (entry.len)(self));
            next += len as u32;
            (first, entry, len)
        })
    }

    fn blocks(&self) -> impl Iterator<Item = (u32, Block<ControllerVariable>)> + '_ {
        self.entries().map(|(first, entry, len)| {
            (first, Block { name: entry.name, shape: entry.shape, len, variable: entry.slot })
        })
    }

    /// Every element of the table present in this layout, in value-reference order.
    pub fn elements(&self) -> impl Iterator<Item = ControllerElement> + '_ {
        self.entries().flat_map(|(first, entry, len)| {
            (0..len).map(move |k| ControllerElement { value_reference: first + k as u32, entry, index: k, len })
        })
    }

    /// The element with value reference `vr`, if any.
    pub fn element(&self, vr: u32) -> Option<ControllerElement> {
        self.entries().find(|&(first, _, len)| vr >= first && ((vr - first) as usize) < len).map(
            |(first, entry, len)| ControllerElement { value_reference: vr, entry, index: (vr - first) as usize, len },
        )
    }

    /// The value reference of `variable`, if this layout has it.
    fn value_reference(&self, variable: ControllerVariable) -> Option<u32> {
        self.elements().find(|element| element.variable() == variable).map(|element| element.value_reference)
    }

    /// The Real variables' blocks, numbered.
    pub fn real_blocks(&self) -> Vec<RealBlock> {
        real_blocks(self.blocks())
    }

    /// The value references of the inputs the output `vr` depends on,
    /// ascending: ε on θ and ν, the potential and the target error on θ;
    /// `None` for a variable that is not an output.
    pub fn dependency_vrs(&self, vr: u32) -> Option<Vec<u32>> {
        let element = self.element(vr)?;
        let inputs = (element.entry.dependencies)(self, element.index)?;
        let mut vrs: Vec<u32> = inputs.into_iter().filter_map(|input| self.value_reference(input)).collect();
        vrs.sort_unstable();
        Some(vrs)
    }

    /// The variable with value reference `vr`, if any.
    pub fn variable(&self, vr: u32) -> Option<ControllerVariable> {
        variable_at(self.blocks(), vr)
    }

    /// All Real variables with their value references, in order.
    pub fn variables(&self) -> impl Iterator<Item = (u32, ControllerVariable)> {
        every_variable(self.blocks())
    }

    /// The structured, 1-based name of `variable`, a variable of this
    /// layout (as [`ControllerLayout::variables`] lists them), from its block.
    pub fn name(&self, variable: ControllerVariable) -> String {
        self.blocks()
            .find_map(|(first, block)| {
                let k = (0..block.len).position(|k| (block.variable)(k) == variable)?;
                Some(RealBlock { name: block.name, shape: block.shape, first, len: block.len }.element_name(k))
            })
            .expect("a variable of this layout")
    }
}

/// One element of the controller's table in a layout.
#[derive(Clone, Copy)]
pub struct ControllerElement {
    /// Its value reference.
    pub value_reference: u32,
    /// Its entry of the table.
    pub entry: &'static ControllerEntry,
    /// Its index within the entry (0-based; 0 for a scalar).
    pub index: usize,
    /// The number of elements of its entry in the layout.
    pub len: usize,
}

impl ControllerElement {
    /// Its name: `name` or `name[k+1]`.
    pub fn name(&self) -> String {
        let block = RealBlock { name: self.entry.name, shape: self.entry.shape, first: 0, len: self.len };
        block.element_name(self.index)
    }

    /// Its slot: what the FMU reads and writes.
    pub fn variable(&self) -> ControllerVariable {
        (self.entry.slot)(self.index)
    }

    /// Its kind.
    pub fn kind(&self) -> Kind {
        self.entry.kind
    }

    /// Its start value in the FMU of `model` with the law's `defaults`, if it has one.
    pub fn start(&self, model: &Model, defaults: &ControlParameters) -> Option<f64> {
        (self.entry.start)(model, defaults, self.index)
    }

    /// Its description in the FMU of `model` with `law`.
    pub fn description(&self, model: &Model, law: &ControlLaw) -> String {
        (self.entry.description)(model, law, self.index)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_references_are_consecutive_and_decode() {
        let layout = ControllerLayout { nq: 14, nv: 13, ny: 6, target_len: 7, pose: true };
        let all: Vec<(u32, ControllerVariable)> = layout.variables().collect();
        assert_eq!(all.len(), 13 + 6 + 7 + 14 + 13 + 13 + 1 + 6);
        for (k, &(vr, variable)) in all.iter().enumerate() {
            assert_eq!(vr, k as u32 + 1);
            assert_eq!(layout.variable(vr), Some(variable));
        }
        assert_eq!(layout.variable(0), None);
        assert_eq!(layout.variable(all.len() as u32 + 1), None);
        let names: Vec<String> = all.iter().map(|&(_, v)| layout.name(v)).collect();
        for name in [
            "c1[13]",
            "c2[6]",
            "target_position[3]",
            "target_quaternion[1]",
            "target_quaternion[4]",
            "theta[14]",
            "nu[1]",
            "eps[13]",
            "potential",
            "target_error[6]",
        ] {
            assert!(names.iter().any(|n| n == name), "{name} missing from {names:?}");
        }
        let joints = ControllerLayout { nq: 4, nv: 4, ny: 3, target_len: 3, pose: false };
        assert_eq!(joints.name(ControllerVariable::Target(2)), "target[3]");
    }
}
