//! The plant's variable table: one entry per kind of Real variable, in
//! value-reference order. Each entry says everything the exporter writes
//! and the FMU enforces about its elements (name, shape, whether it is an
//! optional output that `--outputs` makes exist, kind, start, description with its unit,
//! dependencies, the state it is the derivative of) and the slot the FMU
//! reads and writes; the value references, both modelDescriptions, the
//! documentation page, the SSP files, `nudyn describe` and docs/fmi.md's
//! table are rendered from it. Adding an output is one entry here and its
//! value in the FMU (`fmu/src/plant.rs`, the `match` on the slot).

use nudyn::model::Model;

use super::describe;
use super::{DEFAULT_MAX_STEP, DEFAULT_TOLERANCE, Layout, RealVariable, SensorDependence};
use crate::blocks::Shape;
use crate::variable::{Kind, Range};

/// The knowns (states and inputs) an element depends on; `None` for a
/// variable that is neither an output nor a state derivative.
type Dependencies = fn(&Layout, usize) -> Option<Vec<RealVariable>>;

/// One entry of the plant's variable table.
pub struct Entry {
    /// The name: of a scalar, of an array (`theta`), or of the array whose
    /// derivatives a [`Shape::Derivative`] entry holds (`der(theta)`).
    pub name: &'static str,
    /// Its shape, which also says whose derivative it is.
    pub shape: Shape,
    /// Whether it is an optional output (`--outputs` takes `name`): absent
    /// unless chosen at export.
    pub optional: bool,
    /// How many elements it has in a layout (when present).
    pub len: fn(&Layout) -> usize,
    /// What kind of variable every element is.
    pub kind: Kind,
    /// The start value of element k written into the modelDescription, if it has one.
    pub start: fn(&Model, usize) -> Option<f64>,
    /// The description of element k, naming its joint, sensor or
    /// component and its unit.
    pub description: fn(&Model, usize) -> String,
    /// The knowns element k depends on.
    pub dependencies: Dependencies,
    /// The slot of element k: what the FMU reads and writes.
    pub slot: fn(usize) -> RealVariable,
}

impl Entry {
    /// How many elements it has in `layout`: 0 if it is an optional output not chosen.
    pub fn len_in(&self, layout: &Layout) -> usize {
        if self.optional && !layout.outputs.has(self.name) { 0 } else { (self.len)(layout) }
    }
}

fn no_start(_: &Model, _: usize) -> Option<f64> {
    None
}

fn zero_start(_: &Model, _: usize) -> Option<f64> {
    Some(0.0)
}

fn not_an_unknown(_: &Layout, _: usize) -> Option<Vec<RealVariable>> {
    None
}

fn model_exchange(layout: &Layout) -> bool {
    super::serves_model_exchange(layout.outputs)
}

/// The table, in value-reference order from `tolerance` (1): parameters,
/// inputs, states, sensors, the optional outputs, then what model exchange
/// alone has. A new kind of variable goes after the optional outputs and
/// before the derivatives, which are last so that adding one moves no
/// value reference a script may hold (docs/fmi.md, "Which value references
/// are stable").
pub const TABLE: [Entry; 20] = [
    Entry {
        name: "tolerance",
        shape: Shape::Scalar,
        optional: false,
        len: |_| 1,
        kind: Kind::fixed_parameter(Range::Positive),
        start: |_, _| Some(DEFAULT_TOLERANCE),
        description: |_, _| describe::tolerance(),
        dependencies: not_an_unknown,
        slot: |_| RealVariable::Tolerance,
    },
    Entry {
        name: "max_step",
        shape: Shape::Scalar,
        optional: false,
        len: |_| 1,
        kind: Kind::fixed_parameter(Range::NonNegative),
        start: |_, _| Some(DEFAULT_MAX_STEP),
        description: |_, _| describe::max_step(),
        dependencies: not_an_unknown,
        slot: |_| RealVariable::MaxStep,
    },
    Entry {
        name: "eps",
        shape: Shape::Array,
        optional: false,
        len: |l| l.nv,
        kind: Kind::INPUT,
        start: zero_start,
        description: describe::eps,
        dependencies: not_an_unknown,
        slot: RealVariable::Eps,
    },
    Entry {
        name: "ctrl",
        shape: Shape::Array,
        optional: false,
        len: |l| l.nu,
        kind: Kind::INPUT,
        start: zero_start,
        description: describe::control,
        dependencies: not_an_unknown,
        slot: RealVariable::Ctrl,
    },
    Entry {
        name: "xfrc_applied",
        shape: Shape::Array,
        optional: false,
        len: |l| l.wrench_inputs,
        kind: Kind::INPUT,
        start: zero_start,
        description: describe::wrench,
        dependencies: not_an_unknown,
        slot: RealVariable::XfrcApplied,
    },
    // θ and ν are outputs with initial="exact": settable until
    // initialization, which is how a master chooses the initial state.
    Entry {
        name: "theta",
        shape: Shape::Array,
        optional: false,
        len: |l| l.nq,
        kind: Kind::STATE_OUTPUT,
        start: |model, k| Some(model.qpos0[k]),
        description: describe::theta,
        dependencies: |_, k| Some(vec![RealVariable::Theta(k)]),
        slot: RealVariable::Theta,
    },
    Entry {
        name: "nu",
        shape: Shape::Array,
        optional: false,
        len: |l| l.nv,
        kind: Kind::STATE_OUTPUT,
        start: zero_start,
        description: describe::nu,
        dependencies: |_, k| Some(vec![RealVariable::Nu(k)]),
        slot: RealVariable::Nu,
    },
    Entry {
        name: "sensordata",
        shape: Shape::Array,
        optional: false,
        len: |l| l.sensordata.len(),
        kind: Kind::CALCULATED_OUTPUT,
        start: no_start,
        description: describe::sensor,
        dependencies: |l, k| {
            Some(match l.sensordata[k] {
                SensorDependence::Nothing => Vec::new(),
                SensorDependence::Configuration => l.theta().collect(),
                SensorDependence::Motion => l.theta().chain(l.nu()).collect(),
                SensorDependence::Controls => l.theta().chain(l.nu()).chain(l.ctrl()).chain(l.act()).collect(),
                SensorDependence::Inputs => l.theta().chain(l.nu()).chain(l.inputs()).chain(l.act()).collect(),
            })
        },
        slot: RealVariable::Sensordata,
    },
    Entry {
        name: "qvel",
        shape: Shape::Array,
        optional: true,
        len: |l| l.nv,
        kind: Kind::CALCULATED_OUTPUT,
        start: no_start,
        description: describe::qvel,
        // θ̇ = ℓ*(θ)ν.
        dependencies: |l, k| match &l.tree {
            Some(tree) => Some(tree.theta(k).chain(tree.path(k)).collect()),
            None => Some(l.theta().chain(l.nu()).collect()),
        },
        slot: RealVariable::Qvel,
    },
    Entry {
        name: "kinetic_energy",
        shape: Shape::Scalar,
        optional: true,
        len: |_| 1,
        kind: Kind::CALCULATED_OUTPUT,
        start: no_start,
        description: |_, _| "kinetic energy 1/2 |nu|^2 (J)".into(),
        dependencies: |l, _| Some(l.nu().collect()),
        slot: |_| RealVariable::KineticEnergy,
    },
    Entry {
        name: "power",
        shape: Shape::Scalar,
        optional: true,
        len: |_| 1,
        kind: Kind::CALCULATED_OUTPUT,
        start: no_start,
        description: |_, _| "power of the applied eps, nu . eps (W)".into(),
        dependencies: |l, _| Some(l.nu().chain(l.eps()).collect()),
        slot: |_| RealVariable::Power,
    },
    Entry {
        name: "momentum",
        shape: Shape::Array,
        optional: true,
        len: |_| 6,
        kind: Kind::CALCULATED_OUTPUT,
        start: no_start,
        description: describe::momentum,
        dependencies: |l, _| Some(l.theta().chain(l.nu()).collect()),
        slot: RealVariable::Momentum,
    },
    Entry {
        name: "energy_residual",
        shape: Shape::Scalar,
        optional: true,
        len: |_| 1,
        kind: Kind::CALCULATED_OUTPUT,
        start: no_start,
        description: |_, _| {
            "energy residual K - K(start) - integral of nu . nu_dot dt, the integration's energy error (J)".into()
        },
        dependencies: |l, _| Some(l.theta().chain(l.nu()).collect()),
        slot: |_| RealVariable::EnergyResidual,
    },
    Entry {
        name: "modal_strain_energy",
        shape: Shape::Scalar,
        optional: true,
        len: |_| 1,
        kind: Kind::CALCULATED_OUTPUT,
        start: no_start,
        description: |_, _| {
            "strain energy of the flexible bodies' modes, 1/2 sum of omega^2 eta^2 (J); K + it is the mechanical energy"
                .into()
        },
        dependencies: |l, _| Some(l.theta().collect()),
        slot: |_| RealVariable::ModalStrainEnergy,
    },
    Entry {
        name: "qfrc_constraint",
        shape: Shape::Array,
        optional: true,
        len: |l| l.nv,
        kind: Kind::CALCULATED_OUTPUT,
        start: no_start,
        description: describe::qfrc_constraint,
        // One problem couples every row to every input's ε.
        dependencies: |l, _| Some(l.theta().chain(l.nu()).chain(l.inputs()).chain(l.act()).collect()),
        slot: RealVariable::QfrcConstraint,
    },
    Entry {
        name: "constraint_switch",
        shape: Shape::Array,
        optional: false,
        len: |l| if model_exchange(l) { l.switches } else { 0 },
        kind: Kind::EVENT_INDICATOR,
        start: no_start,
        description: describe::constraint_switch,
        // The margins of the constraint problem, which every input's ε enters.
        dependencies: |l, _| Some(l.theta().chain(l.nu()).chain(l.inputs()).chain(l.act()).collect()),
        slot: RealVariable::ConstraintSwitch,
    },
    // The actuators' activation states (MuJoCo's act), states like θ and ν,
    // present only for a vehicle with activation dynamics.
    Entry {
        name: "act",
        shape: Shape::Array,
        optional: false,
        len: |l| l.na,
        kind: Kind::STATE_OUTPUT,
        start: zero_start,
        description: describe::act,
        dependencies: |_, k| Some(vec![RealVariable::Act(k)]),
        slot: RealVariable::Act,
    },
    Entry {
        name: "theta",
        shape: Shape::Derivative,
        optional: false,
        len: |l| if model_exchange(l) { l.nq } else { 0 },
        kind: Kind::DERIVATIVE,
        start: no_start,
        description: describe::der_theta,
        // θ̇'s entry, or ½ q ⊗ (0, ω) with q of the same joint.
        dependencies: |l, k| match &l.tree {
            Some(tree) => Some(tree.theta(tree.dof_of(k)).chain(tree.path(tree.dof_of(k))).collect()),
            None => Some(l.theta().chain(l.nu()).collect()),
        },
        slot: RealVariable::DerTheta,
    },
    Entry {
        name: "nu",
        shape: Shape::Derivative,
        optional: false,
        len: |l| if model_exchange(l) { l.nv } else { 0 },
        kind: Kind::DERIVATIVE,
        start: no_start,
        description: describe::der_nu,
        // Every actuator's ε reaches every dof through ℓ in general; a
        // tree alone couples its own dofs only, a branch not its siblings.
        // ε enters ν̇ additively, unless the constraint forces, solved over
        // every dof, pass each entry of ε on to every other.
        dependencies: |l, k| {
            let forces = l.ctrl().chain(l.wrenches()).chain(l.act());
            Some(match &l.tree {
                Some(tree) => {
                    tree.theta(k).chain(tree.path_and_subtree(k)).chain([RealVariable::Eps(k)]).chain(forces).collect()
                }
                None if l.eps_coupled => l.theta().chain(l.nu()).chain(l.eps()).chain(forces).collect(),
                None => l.theta().chain(l.nu()).chain([RealVariable::Eps(k)]).chain(forces).collect(),
            })
        },
        slot: RealVariable::DerNu,
    },
    Entry {
        name: "act",
        shape: Shape::Derivative,
        optional: false,
        len: |l| if model_exchange(l) { l.na } else { 0 },
        kind: Kind::DERIVATIVE,
        start: no_start,
        description: describe::der_act,
        // act_dot is its actuator's ctrl and act (every ctrl listed: the layout keeps no owner).
        dependencies: |l, k| Some(l.ctrl().chain([RealVariable::Act(k)]).collect()),
        slot: RealVariable::DerAct,
    },
];
