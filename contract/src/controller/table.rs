//! The controller's variable table: one entry per kind of Real variable,
//! in value-reference order, as the plant's (`crate::plant::TABLE`): name,
//! shape, length, kind, start and description per element, dependencies,
//! and the slot the FMU reads and writes. The value references, both
//! modelDescriptions, the documentation page and the SSP's `--set` checks
//! are rendered from it.

use nudyn::control::{ControlLaw, ControlParameters};
use nudyn::model::Model;

use super::describe;
use super::{ControllerLayout, ControllerVariable};
use crate::blocks::Shape;
use crate::variable::{Kind, Range};

/// One entry of the controller's variable table.
pub struct ControllerEntry {
    /// The name of the scalar or array.
    pub name: &'static str,
    /// Its shape.
    pub shape: Shape,
    /// How many elements it has in a layout.
    pub len: fn(&ControllerLayout) -> usize,
    /// What kind of variable every element is: gains and targets are tunable.
    pub kind: Kind,
    /// The start value of element k, from the law's default parameters.
    pub start: fn(&Model, &ControlParameters, usize) -> Option<f64>,
    /// The description of element k.
    pub description: fn(&Model, &ControlLaw, usize) -> String,
    /// The inputs element k depends on; `None` for a variable that is not an output.
    pub dependencies: fn(&ControllerLayout, usize) -> Option<Vec<ControllerVariable>>,
    /// The slot of element k.
    pub slot: fn(usize) -> ControllerVariable,
}

fn no_start(_: &Model, _: &ControlParameters, _: usize) -> Option<f64> {
    None
}

fn not_an_output(_: &ControllerLayout, _: usize) -> Option<Vec<ControllerVariable>> {
    None
}

/// The configuration θ.
fn theta(layout: &ControllerLayout) -> impl Iterator<Item = ControllerVariable> + use<> {
    (0..layout.nq).map(ControllerVariable::Theta)
}

/// The table, in value-reference order from 1. A pose target is two
/// arrays, the position and the quaternion; a joint target one.
pub const CONTROLLER_TABLE: [ControllerEntry; 10] = [
    ControllerEntry {
        name: "c1",
        shape: Shape::Array,
        len: |l| l.nv,
        kind: Kind::tunable_parameter(Range::NonNegative),
        start: |_, defaults, k| Some(defaults.c1[k]),
        description: |_, _, k| format!("rate gain c1 of dof {} (1/s): eps[{0}] = -c1[{0}] nu[{0}] + ...", k + 1),
        dependencies: not_an_output,
        slot: ControllerVariable::RateGain,
    },
    ControllerEntry {
        name: "c2",
        shape: Shape::Array,
        len: |l| l.ny,
        kind: Kind::tunable_parameter(Range::NonNegative),
        start: |_, defaults, k| Some(defaults.c2[k]),
        description: describe::target_gain,
        dependencies: not_an_output,
        slot: ControllerVariable::TargetGain,
    },
    ControllerEntry {
        name: "target_position",
        shape: Shape::Array,
        len: |l| if l.pose { 3 } else { 0 },
        kind: Kind::tunable_parameter(Range::Any),
        start: |_, defaults, k| Some(defaults.target[k]),
        description: describe::target,
        dependencies: not_an_output,
        slot: ControllerVariable::Target,
    },
    ControllerEntry {
        name: "target_quaternion",
        shape: Shape::Array,
        len: |l| if l.pose { 4 } else { 0 },
        kind: Kind::tunable_parameter(Range::Any),
        start: |_, defaults, k| Some(defaults.target[3 + k]),
        description: |model, law, k| describe::target(model, law, 3 + k),
        dependencies: not_an_output,
        slot: |k| ControllerVariable::Target(3 + k),
    },
    ControllerEntry {
        name: "target",
        shape: Shape::Array,
        len: |l| if l.pose { 0 } else { l.target_len },
        kind: Kind::tunable_parameter(Range::Any),
        start: |_, defaults, k| Some(defaults.target[k]),
        description: describe::target,
        dependencies: not_an_output,
        slot: ControllerVariable::Target,
    },
    ControllerEntry {
        name: "theta",
        shape: Shape::Array,
        len: |l| l.nq,
        kind: Kind::INPUT,
        start: |model, _, k| Some(model.qpos0[k]),
        description: |model, _, k| {
            format!("input: {}", crate::plant::description(model, crate::plant::RealVariable::Theta(k)))
        },
        dependencies: not_an_output,
        slot: ControllerVariable::Theta,
    },
    ControllerEntry {
        name: "nu",
        shape: Shape::Array,
        len: |l| l.nv,
        kind: Kind::INPUT,
        start: |_, _, _| Some(0.0),
        description: |model, _, k| {
            format!("input: {}", crate::plant::description(model, crate::plant::RealVariable::Nu(k)))
        },
        dependencies: not_an_output,
        slot: ControllerVariable::Nu,
    },
    ControllerEntry {
        name: "eps",
        shape: Shape::Array,
        len: |l| l.nv,
        kind: Kind::CALCULATED_OUTPUT,
        start: no_start,
        description: |model, _, k| {
            let eps = crate::plant::description(model, crate::plant::RealVariable::Eps(k));
            format!("output: {eps} = -c1 nu + l J^T c2 (Yhat - Y)")
        },
        dependencies: |l, _| Some(theta(l).chain((0..l.nv).map(ControllerVariable::Nu)).collect()),
        slot: ControllerVariable::Eps,
    },
    ControllerEntry {
        name: "potential",
        shape: Shape::Scalar,
        len: |_| 1,
        kind: Kind::CALCULATED_OUTPUT,
        start: no_start,
        description: |_, _, _| "potential 1/2 sum c2 (Yhat - Y)^2 of the configuration term (J)".into(),
        dependencies: |l, _| Some(theta(l).collect()),
        slot: |_| ControllerVariable::Potential,
    },
    ControllerEntry {
        name: "target_error",
        shape: Shape::Array,
        len: |l| l.ny,
        kind: Kind::CALCULATED_OUTPUT,
        start: no_start,
        description: describe::target_error,
        dependencies: |l, _| Some(theta(l).collect()),
        slot: ControllerVariable::TargetError,
    },
];
