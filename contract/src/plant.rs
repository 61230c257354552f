//! The plant FMU, the vehicle's dynamics: its variables, value references,
//! parameter defaults, capabilities and resource file.
//!
//! Variables follow MuJoCo's qpos/qvel order with 1-based structured names
//! (`theta[1]`): inputs `eps[1..nv]` and, for a vehicle with actuators,
//! `ctrl[1..nu]` in MuJoCo's actuator order; outputs `theta[1..nq]` and
//! `nu[1..nv]`, for a vehicle with sensors `sensordata[1..n]` in MuJoCo's
//! sensor order and layout, and the optional outputs chosen at export;
//! for model exchange the event indicators `constraint_switch[1..n]` and
//! the state derivatives. Every variable is an entry of one table
//! ([`TABLE`], `plant/table.rs`).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use nudyn::integrate::{Method, MethodSetting};
use nudyn::model::{LinkJoint, Model};
use nudyn::vehicle::SensorKind;

use crate::blocks::{Block, RealBlock, every_variable, real_blocks, value_reference_of, variable_at};
use crate::capabilities::Capabilities;
use crate::resource::Resource;
use crate::variable::{Kind, StartError, check_start};

mod describe;
mod table;

pub use table::{Entry, TABLE};

/// Value reference of the Integer (enumeration) parameter `method`.
pub const METHOD_VR: u32 = 0;

/// The name of the Integer (enumeration) parameter `method`.
pub const METHOD_NAME: &str = "method";

/// Value reference of the Boolean parameter `energy_projection`.
pub const ENERGY_PROJECTION_VR: u32 = 0;

/// The name of the Boolean parameter `energy_projection`.
pub const ENERGY_PROJECTION_NAME: &str = "energy_projection";

/// Default of the `method` parameter.
pub const DEFAULT_METHOD: MethodSetting = MethodSetting::Fixed(Method::Dop853);

/// Default of the `max_step` parameter (s), the longest internal step: 0,
/// the method's own bound (none for the adaptive methods, whose error
/// control and the communication step decide; 0.01 s for RK4).
pub const DEFAULT_MAX_STEP: f64 = 0.0;

/// Default of the `tolerance` parameter.
pub const DEFAULT_TOLERANCE: f64 = 1e-8;

/// The name of the enumeration type of `method`.
pub const METHOD_TYPE: &str = "Method";

/// The value of `method` in the FMU's enumeration: 1-based, as FMI
/// enumerations usually are, in the order of [`MethodSetting::ALL`].
pub fn method_value(setting: impl Into<MethodSetting>) -> i32 {
    let setting = setting.into();
    MethodSetting::ALL.iter().position(|&m| m == setting).expect("listed") as i32 + 1
}

/// The method setting of an enumeration value, if it is one.
pub fn method_of_value(value: i32) -> Option<MethodSetting> {
    usize::try_from(value - 1).ok().and_then(|i| MethodSetting::ALL.get(i).copied())
}

/// "1 = rk4, 2 = dopri5, ...": the enumeration's items, for messages.
pub fn method_items() -> String {
    MethodSetting::ALL.iter().map(|&m| format!("{} = {}", method_value(m), m.name())).collect::<Vec<_>>().join(", ")
}

/// What a plant FMU with `outputs` can do: model exchange, unless it has
/// the energy residual ([`serves_model_exchange`]), and directional and
/// adjoint derivatives where they cover its outputs ([`derivatives_cover`]).
pub fn capabilities(outputs: OptionalOutputs) -> Capabilities {
    Capabilities {
        model_exchange: serves_model_exchange(outputs),
        provides_directional_derivative: derivatives_cover(outputs).is_ok(),
        ..CAPABILITIES
    }
}

/// Whether a plant FMU with `outputs` serves model exchange: not with the
/// energy residual, whose work integral only the FMU's own integration keeps.
pub fn serves_model_exchange(outputs: OptionalOutputs) -> bool {
    !outputs.has("energy_residual")
}

/// What a plant FMU has that its directional derivatives do not cover yet.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum NotCovered {
    /// An optional output whose derivative is not computed.
    #[error("derivatives do not cover the optional output {0}; this FMU has it")]
    Output(&'static str),
}

/// Whether the FMU's directional derivatives cover every unknown of a plant
/// FMU with `outputs`, or the first thing they do not: the dynamics'
/// derivatives cover every vehicle nudyn imports.
pub fn derivatives_cover(outputs: OptionalOutputs) -> Result<(), NotCovered> {
    // The energy residual is a record of the integration, not a function of the state.
    match outputs.has("energy_residual") {
        true => Err(NotCovered::Output("energy_residual")),
        false => Ok(()),
    }
}

/// Whether the dynamics are the tree's alone (no actuators, tendons or
/// constraint forces), which [`TreeDependence`] describes.
fn tree_alone(model: &Model) -> bool {
    model.actuators.is_empty() && model.tendons.is_empty() && !model.couples_beyond_tree()
}

/// What the plant FMU can do, at most.
pub const CAPABILITIES: Capabilities = Capabilities {
    can_interpolate_inputs: true,
    max_output_derivative_order: 1,
    can_get_and_set_fmu_state: true,
    can_serialize_fmu_state: true,
    provides_directional_derivative: false,
    can_handle_variable_communication_step_size: true,
    model_exchange: true,
};

/// The optional outputs chosen at export, the table's entries marked
/// `optional`; those not chosen do not exist in the FMU, so they cost
/// nothing at run time. The resource file holds them as an object of every
/// name with whether it is chosen (`{"qvel": false, ...}`, in the table's
/// order); a name missing there is not chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OptionalOutputs {
    /// Bit i: whether `NAMES[i]` is chosen.
    chosen: u32,
}

/// How many entries of the table are optional outputs.
const OPTIONAL_COUNT: usize = {
    let mut count = 0;
    let mut i = 0;
    while i < TABLE.len() {
        if TABLE[i].optional {
            count += 1;
        }
        i += 1;
    }
    count
};

impl OptionalOutputs {
    /// The name of every optional output, as `--outputs` takes them: the
    /// table's optional entries, in its order.
    pub const NAMES: [&str; OPTIONAL_COUNT] = {
        let mut names = [""; OPTIONAL_COUNT];
        let (mut i, mut n) = (0, 0);
        while i < TABLE.len() {
            if TABLE[i].optional {
                names[n] = TABLE[i].name;
                n += 1;
            }
            i += 1;
        }
        names
    };

    /// The bit of the optional output `name`, if it is one.
    fn bit(name: &str) -> Option<u32> {
        Self::NAMES.iter().position(|&known| known == name).map(|i| 1 << i)
    }

    /// Whether the optional output `name` is chosen.
    pub fn has(&self, name: &str) -> bool {
        debug_assert!(Self::bit(name).is_some(), "{name} is no optional output");
        Self::bit(name).is_some_and(|bit| self.chosen & bit != 0)
    }
}

impl Serialize for OptionalOutputs {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut map = serializer.serialize_map(Some(Self::NAMES.len()))?;
        for name in Self::NAMES {
            map.serialize_entry(name, &self.has(name))?;
        }
        map.end()
    }
}

impl<'de> Deserialize<'de> for OptionalOutputs {
    /// Names it does not know are left out, as for any field of the file a
    /// reader does not know ([`Resource::FORMAT`] says when that matters).
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let flags = BTreeMap::<String, bool>::deserialize(deserializer)?;
        let chosen = flags.iter().filter(|(_, on)| **on).filter_map(|(name, _)| Self::bit(name)).fold(0, |a, b| a | b);
        Ok(OptionalOutputs { chosen })
    }
}

/// Why a list of optional outputs cannot be parsed.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("unknown optional output '{0}': expected one of {names}", names = OptionalOutputs::NAMES.join(", "))]
pub struct UnknownOutput(pub String);

impl std::str::FromStr for OptionalOutputs {
    type Err = UnknownOutput;

    /// Parses a comma-separated list such as `qvel,kinetic_energy` (empty: none).
    fn from_str(list: &str) -> Result<Self, UnknownOutput> {
        let mut outputs = OptionalOutputs::default();
        for name in list.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            outputs.chosen |= Self::bit(name).ok_or_else(|| UnknownOutput(name.to_string()))?;
        }
        Ok(outputs)
    }
}

/// `resources/model.json`: what the plant FMU loads at instantiation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlantResource {
    /// [`Resource::FORMAT`] of the writer.
    pub format: u32,
    /// The optional outputs the FMU provides.
    pub outputs: OptionalOutputs,
    /// Start values chosen at export (a system file's `--set plant.NAME`),
    /// by variable name: the FMU takes them as its own, before any set.
    pub starts: BTreeMap<String, f64>,
    /// The start of the `method` parameter chosen at export (`--method`).
    pub method: MethodSetting,
    /// Whether the FMI 3.0 FMU declares every element as a scalar
    /// (`--fmi3-scalars`) instead of arrays: absent (false) in files of FMUs
    /// with arrays, so that their bytes and GUIDs stay as they were.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub fmi3_scalars: bool,
    /// The compiled vehicle.
    pub model: Model,
}

impl PlantResource {
    /// The resource of an FMU of `model` with `outputs` and the variables' default starts.
    pub fn new(model: Model, outputs: OptionalOutputs) -> Self {
        PlantResource {
            format: Self::FORMAT,
            outputs,
            starts: BTreeMap::new(),
            method: DEFAULT_METHOD,
            fmi3_scalars: false,
            model,
        }
    }

    /// The same FMU with start values `starts` (variable name → value)
    /// replacing the defaults; refused, naming the variable, if one is not
    /// a variable with a start value or its value is not one it accepts.
    pub fn with_starts(mut self, starts: BTreeMap<String, f64>) -> Result<Self, StartError> {
        let layout = self.layout();
        for (name, &value) in &starts {
            let element = layout
                .elements()
                .find(|element| &element.name() == name)
                .ok_or_else(|| StartError::Unknown(name.clone()))?;
            check_start(name, element.entry.kind, element.default_start(&self.model).is_some(), value)?;
        }
        self.starts = starts;
        Ok(self)
    }

    /// The start value of `element`: the one chosen at export, else its default.
    pub fn start(&self, element: &Element) -> Option<f64> {
        // Most FMUs choose no start: no name to look up.
        let chosen = (!self.starts.is_empty()).then(|| self.starts.get(&element.name()).copied()).flatten();
        chosen.or_else(|| element.default_start(&self.model))
    }

    /// The layout of its variables.
    pub fn layout(&self) -> Layout {
        Layout::new(&self.model, self.outputs)
    }
}

impl Resource for PlantResource {
    const FILE: &'static str = "model.json";
    const FORMAT: u32 = 5;

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

    fn enumerations(&self) -> Vec<(u32, String)> {
        vec![(METHOD_VR, METHOD_NAME.into())]
    }

    fn booleans(&self) -> Vec<(u32, String)> {
        vec![(ENERGY_PROJECTION_VR, ENERGY_PROJECTION_NAME.into())]
    }

    fn dependencies(&self, vr: u32) -> Option<Vec<u32>> {
        self.layout().dependency_vrs(vr)
    }
}

/// One Real variable of the plant; indices are 0-based here, 1-based in names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RealVariable {
    /// Parameter `tolerance`.
    Tolerance,
    /// Parameter `max_step`.
    MaxStep,
    /// Input `eps[k+1]`.
    Eps(usize),
    /// Input `ctrl[k+1]`: the control of actuator k (MuJoCo's `d.ctrl`).
    Ctrl(usize),
    /// Input `xfrc_applied[k+1]`: component k % 6 of the wrench on wrench
    /// body k / 6 (MuJoCo's `xfrc_applied`: force, then torque, world axes).
    XfrcApplied(usize),
    /// Output `theta[k+1]` (qpos).
    Theta(usize),
    /// Output `nu[k+1]`.
    Nu(usize),
    /// Output `sensordata[k+1]` (MuJoCo's `d.sensordata`).
    Sensordata(usize),
    /// Optional output `qvel[k+1]`.
    Qvel(usize),
    /// Optional output `kinetic_energy`.
    KineticEnergy,
    /// Optional output `power`.
    Power,
    /// Optional output `momentum[k+1]`.
    Momentum(usize),
    /// Optional output `energy_residual`.
    EnergyResidual,
    /// Optional output `modal_strain_energy`.
    ModalStrainEnergy,
    /// Optional output `qfrc_constraint[k+1]` (MuJoCo's `d.qfrc_constraint`).
    QfrcConstraint(usize),
    /// `constraint_switch[k+1]`: event indicator k of model exchange, the
    /// margin of switch k of the constraint forces.
    ConstraintSwitch(usize),
    /// `der(theta[k+1])`: the qpos rate, a state derivative of model exchange.
    DerTheta(usize),
    /// `der(nu[k+1])`: ν̇, a state derivative of model exchange.
    DerNu(usize),
    /// Output `act[k+1]`: activation state k (MuJoCo's `act`), a state of
    /// model exchange after θ and ν.
    Act(usize),
    /// `der(act[k+1])`: act's rate, a state derivative of model exchange.
    DerAct(usize),
}

impl RealVariable {
    /// Its element index within its block (0 for a scalar).
    pub fn index(self) -> usize {
        match self {
            RealVariable::Tolerance
            | RealVariable::MaxStep
            | RealVariable::KineticEnergy
            | RealVariable::Power
            | RealVariable::EnergyResidual
            | RealVariable::ModalStrainEnergy => 0,
            RealVariable::Eps(k)
            | RealVariable::Ctrl(k)
            | RealVariable::XfrcApplied(k)
            | RealVariable::Theta(k)
            | RealVariable::Nu(k)
            | RealVariable::Sensordata(k)
            | RealVariable::Qvel(k)
            | RealVariable::Momentum(k)
            | RealVariable::QfrcConstraint(k)
            | RealVariable::ConstraintSwitch(k)
            | RealVariable::DerTheta(k)
            | RealVariable::DerNu(k)
            | RealVariable::Act(k)
            | RealVariable::DerAct(k) => k,
        }
    }

    /// Whether it is a state derivative of model exchange.
    pub fn is_derivative(self) -> bool {
        matches!(self, RealVariable::DerTheta(_) | RealVariable::DerNu(_) | RealVariable::DerAct(_))
    }
}

/// The description of the plant variable `variable` in an FMU of `model`,
/// from its entry of the table (the controller's inputs and outputs
/// describe themselves by the plant's).
pub fn description(model: &Model, variable: RealVariable) -> String {
    let k = variable.index();
    let entry = TABLE.iter().find(|entry| (entry.slot)(k) == variable).expect("every slot has an entry");
    (entry.description)(model, k)
}

/// What a sensor's values depend on, besides time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SensorDependence {
    /// Nothing the FMU knows (the clock).
    Nothing,
    /// The configuration θ.
    Configuration,
    /// θ and ν.
    Motion,
    /// θ, ν and the controls (actuator forces).
    Controls,
    /// θ, ν and every input (accelerations: ε and ctrl feed through).
    Inputs,
}

impl SensorDependence {
    /// What a sensor of `kind` depends on.
    pub fn of(kind: SensorKind) -> SensorDependence {
        use SensorKind::*;
        match kind {
            Clock => SensorDependence::Nothing,
            JointPos | BallQuat | FramePos | FrameQuat | FrameXAxis | FrameYAxis | FrameZAxis | SubtreeCom
            | ActuatorPos | JointLimitPos | TendonPos | TendonLimitPos | Magnetometer => {
                SensorDependence::Configuration
            }
            JointVel | BallAngVel | FrameLinVel | FrameAngVel | SubtreeLinVel | SubtreeAngMom | Gyro | Velocimeter
            | ActuatorVel | JointLimitVel | TendonVel | TendonLimitVel => SensorDependence::Motion,
            ActuatorFrc | JointActuatorFrc | TendonActuatorFrc => SensorDependence::Controls,
            // A limit's force solves one problem with every input's ε; a
            // body's interaction force takes the accelerations.
            FrameLinAcc | FrameAngAcc | Accelerometer | JointLimitFrc | TendonLimitFrc | Force | Torque => {
                SensorDependence::Inputs
            }
        }
    }
}

/// What sizes a vehicle and an option set give the entries of the
/// variable table ([`TABLE`]): the plant's Real variables are the entries
/// present, numbered consecutively from `tolerance` (1) in the table's order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Layout {
    /// Number of position coordinates.
    pub nq: usize,
    /// Number of dofs.
    pub nv: usize,
    /// Number of actuators (MuJoCo's nu).
    pub nu: usize,
    /// Number of wrench inputs (six per wrench body).
    pub wrench_inputs: usize,
    /// Number of activation states (MuJoCo's na).
    pub na: usize,
    /// What each sensordata entry depends on (MuJoCo's nsensordata entries).
    pub sensordata: Vec<SensorDependence>,
    /// Number of switches of the constraint forces (limit sides, and two
    /// per constraint row), the event indicators of model exchange.
    pub switches: usize,
    /// Whether ν̇ feels every entry of ε, not its own alone: the
    /// constraint forces (and the tendons' armature) solve one problem
    /// over every dof.
    pub eps_coupled: bool,
    /// The optional outputs present.
    pub outputs: OptionalOutputs,
    /// Which of the tree's knowns its unknowns depend on, where the
    /// dynamics are the tree's alone (no actuators, tendons or constraint forces);
    /// `None` elsewhere, where every unknown is taken to depend on every
    /// state.
    pub tree: Option<TreeDependence>,
}

/// What the dynamics of a tree alone (no actuators, tendons or constraint
/// forces) depend on, as the exact derivatives show it: each tree (a root
/// link and its descendants) moves by its own θ and ν only; nothing
/// depends on a free base's position (gravity is uniform); θ̇ of a joint
/// depends on the ν of its own and its ancestors' joints (θ̇ = ℓ*(θ)ν, an
/// operator that runs outward from the root), and its ν̇ on the ν of
/// those and of its descendants' joints, not on a sibling branch's (the
/// diagonalized dynamics do not couple them), and on the whole tree's θ
/// (through the articulated inertias).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TreeDependence {
    /// Per coordinate of θ: its tree, or `None` for a free base's position.
    qpos_tree: Vec<Option<usize>>,
    /// Per coordinate of θ: its joint's link.
    qpos_link: Vec<usize>,
    /// Per dof: its link.
    dof_link: Vec<usize>,
    /// Per link, then per flexible body's modal block: its tree (its root
    /// link), parent, children and dofs.
    links: Vec<TreeLink>,
}

#[derive(Clone, Debug, PartialEq, Eq)]
struct TreeLink {
    tree: usize,
    parent: Option<usize>,
    children: Vec<usize>,
    dofs: std::ops::Range<usize>,
}

impl TreeDependence {
    /// That of `model`, if its dynamics are its tree's alone.
    pub fn of(model: &Model) -> Option<Self> {
        if !tree_alone(model) {
            return None;
        }
        let (mut qpos_tree, mut qpos_link) = (vec![None; model.nq], vec![0; model.nq]);
        let mut dof_link = vec![0; model.nv];
        let mut links: Vec<TreeLink> = Vec::with_capacity(model.links.len());
        // Links are parent-first: a parent's tree is known before its children's.
        for (i, link) in model.links.iter().enumerate() {
            let tree = link.parent.map_or(i, |parent| links[parent].tree);
            if let Some(parent) = link.parent {
                links[parent].children.push(i);
            }
            let dofs = link.dof_adr..link.dof_adr + link.ndof;
            dof_link[dofs.clone()].fill(i);
            let root_position = link.parent.is_none() && link.joint == LinkJoint::Translation;
            let coordinates = match link.joint {
                LinkJoint::Hinge | LinkJoint::Slide => 1,
                LinkJoint::Translation => 3,
                LinkJoint::Ball => 4,
            };
            for q in link.qpos_adr..link.qpos_adr + coordinates {
                qpos_tree[q] = (!root_position).then_some(tree);
                qpos_link[q] = i;
            }
            links.push(TreeLink { tree, parent: link.parent, children: Vec::new(), dofs });
        }
        // A flexible body's modes are one more child of its link (the passes' modal block).
        for flexible in &model.flexible {
            let (block, tree) = (links.len(), links[flexible.link].tree);
            let (m, dofs) = (flexible.mode_count(), flexible.dof_adr..flexible.dof_adr + flexible.mode_count());
            links[flexible.link].children.push(block);
            dof_link[dofs.clone()].fill(block);
            qpos_tree[flexible.qpos_adr..flexible.qpos_adr + m].fill(Some(tree));
            qpos_link[flexible.qpos_adr..flexible.qpos_adr + m].fill(block);
            links.push(TreeLink { tree, parent: Some(flexible.link), children: Vec::new(), dofs });
        }
        Some(TreeDependence { qpos_tree, qpos_link, dof_link, links })
    }

    /// The coordinates of θ that the tree of dof `dof` depends on.
    pub(crate) fn theta(&self, dof: usize) -> impl Iterator<Item = RealVariable> + '_ {
        let tree = Some(self.links[self.dof_link[dof]].tree);
        (0..self.qpos_tree.len()).filter(move |&q| self.qpos_tree[q] == tree).map(RealVariable::Theta)
    }

    /// The ν of the joints from the root to dof `dof`'s, its own included.
    pub(crate) fn path(&self, dof: usize) -> impl Iterator<Item = RealVariable> + '_ {
        let ancestors = std::iter::successors(Some(self.dof_link[dof]), |&link| self.links[link].parent);
        ancestors.flat_map(|link| self.links[link].dofs.clone()).map(RealVariable::Nu)
    }

    /// The ν of the path to dof `dof` and of every joint below its own.
    pub(crate) fn path_and_subtree(&self, dof: usize) -> impl Iterator<Item = RealVariable> + '_ {
        let own = self.dof_link[dof];
        let mut below = self.links[own].children.clone();
        let subtree = std::iter::from_fn(move || {
            let link = below.pop()?;
            below.extend_from_slice(&self.links[link].children);
            Some(link)
        });
        self.path(dof).chain(subtree.flat_map(|link| self.links[link].dofs.clone()).map(RealVariable::Nu))
    }

    /// The first dof of the joint of coordinate `q` of θ.
    pub(crate) fn dof_of(&self, q: usize) -> usize {
        self.links[self.qpos_link[q]].dofs.start
    }
}

impl Layout {
    /// The layout of an FMU of `model` with `outputs`.
    pub fn new(model: &Model, outputs: OptionalOutputs) -> Self {
        let sensordata =
            model.sensors.iter().flat_map(|s| std::iter::repeat_n(SensorDependence::of(s.kind), s.dim())).collect();
        Layout {
            nq: model.nq,
            nv: model.nv,
            nu: model.mjcf_actuator_count(),
            wrench_inputs: 6 * model.wrench_bodies.len(),
            na: model.activation_count(),
            sensordata,
            switches: model.switch_count(),
            eps_coupled: model.couples_beyond_tree(),
            outputs,
            tree: TreeDependence::of(model),
        }
    }

    /// The table's entries in value-reference order, each with the value
    /// reference of its first element and its length in this layout.
    fn entries(&self) -> impl Iterator<Item = (u32, &'static Entry, usize)> + '_ {
        let mut next = METHOD_VR + 1;
        TABLE.iter().map(move |entry| {
            let (first, len) = (next, entry.len_in(self));
            next += len as u32;
            (first, entry, len)
        })
    }

    /// The blocks in value-reference order, each with its first value reference.
    fn blocks(&self) -> impl Iterator<Item = (u32, Block<RealVariable>)> + '_ {
        self.entries().map(|(first, entry, len)| {
            (first, Block { name: entry.name, shape: entry.shape, len, variable: entry.slot })
        })
    }

    /// The Real variables' blocks, numbered.
    pub fn real_blocks(&self) -> Vec<RealBlock> {
        real_blocks(self.blocks())
    }

    /// Every element of the table present in this layout, in value-reference order.
    pub fn elements(&self) -> impl Iterator<Item = Element> + '_ {
        self.entries().flat_map(|(first, entry, len)| {
            (0..len).map(move |k| Element { value_reference: first + k as u32, entry, index: k, len })
        })
    }

    /// The element with value reference `vr`, if any.
    pub fn element(&self, vr: u32) -> Option<Element> {
        self.entries()
            .find(|&(first, _, len)| vr >= first && ((vr - first) as usize) < len)
            .map(|(first, entry, len)| Element { value_reference: vr, entry, index: (vr - first) as usize, len })
    }

    /// The element whose slot is `variable`, if this layout has it.
    pub fn element_of(&self, variable: RealVariable) -> Option<Element> {
        let k = variable.index();
        self.entries()
            .find(|&(_, entry, len)| k < len && (entry.slot)(k) == variable)
            .map(|(first, entry, len)| Element { value_reference: first + k as u32, entry, index: k, len })
    }

    /// The number of event indicators of model exchange: the elements of
    /// the entries whose kind says so.
    pub fn event_indicator_count(&self) -> usize {
        self.entries().filter(|(_, entry, _)| entry.kind.event_indicator).map(|(_, _, len)| len).sum()
    }

    /// The variable with value reference `vr`, if any.
    pub fn real_variable(&self, vr: u32) -> Option<RealVariable> {
        variable_at(self.blocks(), vr)
    }

    /// All Real variables with their value references, in order.
    pub fn real_variables(&self) -> impl Iterator<Item = (u32, RealVariable)> + '_ {
        every_variable(self.blocks())
    }

    /// The states θ.
    pub(crate) fn theta(&self) -> impl Iterator<Item = RealVariable> + use<> {
        (0..self.nq).map(RealVariable::Theta)
    }

    /// The states ν.
    pub(crate) fn nu(&self) -> impl Iterator<Item = RealVariable> + use<> {
        (0..self.nv).map(RealVariable::Nu)
    }

    /// The inputs ε.
    pub(crate) fn eps(&self) -> impl Iterator<Item = RealVariable> + use<> {
        (0..self.nv).map(RealVariable::Eps)
    }

    /// The inputs ctrl.
    pub(crate) fn ctrl(&self) -> impl Iterator<Item = RealVariable> + use<> {
        (0..self.nu).map(RealVariable::Ctrl)
    }

    /// The wrench inputs.
    pub(crate) fn wrenches(&self) -> impl Iterator<Item = RealVariable> + use<> {
        (0..self.wrench_inputs).map(RealVariable::XfrcApplied)
    }

    /// Every input: ε, ctrl and the wrenches.
    pub(crate) fn inputs(&self) -> impl Iterator<Item = RealVariable> + use<> {
        self.eps().chain(self.ctrl()).chain(self.wrenches())
    }

    /// The states act, which the actuators' forces read beside ctrl.
    pub(crate) fn act(&self) -> impl Iterator<Item = RealVariable> + use<> {
        (0..self.na).map(RealVariable::Act)
    }

    /// The knowns (states θ, ν, act and inputs ε, ctrl) that the output or state
    /// derivative `variable` depends on; `None` for a parameter, an input or
    /// a state. For co-simulation this says that no output but the power
    /// feeds through from the inputs.
    pub fn dependencies(&self, variable: RealVariable) -> Option<Vec<RealVariable>> {
        let element = self.element_of(variable)?;
        (element.entry.dependencies)(self, element.index)
    }

    /// [`Layout::dependencies`] by value reference: those of the knowns of
    /// the Real `vr`, ascending.
    pub fn dependency_vrs(&self, vr: u32) -> Option<Vec<u32>> {
        let element = self.element(vr)?;
        let knowns = (element.entry.dependencies)(self, element.index)?;
        let mut vrs: Vec<u32> = knowns.into_iter().filter_map(|known| self.value_reference(known)).collect();
        vrs.sort_unstable();
        Some(vrs)
    }

    /// The structured, 1-based name of `variable` (as in
    /// `modelDescription.xml`); `None` if this layout does not have it.
    pub fn name(&self, variable: RealVariable) -> Option<String> {
        self.element_of(variable).map(|element| element.name())
    }

    /// The value reference of `variable`, if this layout has it (in constant
    /// time, one pass over the blocks: dependency lists of large vehicles look up millions).
    pub fn value_reference(&self, variable: RealVariable) -> Option<u32> {
        value_reference_of(self.blocks(), variable, variable.index())
    }
}

/// One element of the table in a layout: an entry, and which of its elements.
#[derive(Clone, Copy)]
pub struct Element {
    /// Its FMI 2.0 value reference.
    pub value_reference: u32,
    /// Its entry of the table.
    pub entry: &'static Entry,
    /// Its index within the entry (0-based; 0 for a scalar).
    pub index: usize,
    /// The number of elements of its entry in the layout.
    pub len: usize,
}

impl Element {
    /// Its FMI 2.0 name: `name`, `name[k+1]` or `der(name[k+1])`.
    pub fn name(&self) -> String {
        let block = RealBlock { name: self.entry.name, shape: self.entry.shape, first: 0, len: self.len };
        block.element_name(self.index)
    }

    /// Its slot: what the FMU reads and writes.
    pub fn variable(&self) -> RealVariable {
        (self.entry.slot)(self.index)
    }

    /// Its kind.
    pub fn kind(&self) -> Kind {
        self.entry.kind
    }

    /// Its description.
    pub fn description(&self, model: &Model) -> String {
        (self.entry.description)(model, self.index)
    }

    /// Its start value in an FMU of `model` that chose none at export.
    pub fn default_start(&self, model: &Model) -> Option<f64> {
        (self.entry.start)(model, self.index)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_optional_outputs() {
        let all: OptionalOutputs = "qvel, kinetic_energy,power,momentum".parse().unwrap();
        assert!(all.has("qvel") && all.has("kinetic_energy") && all.has("power") && all.has("momentum"));
        assert!(!all.has("energy_residual") && !all.has("qfrc_constraint"));
        assert_eq!("".parse::<OptionalOutputs>().unwrap(), OptionalOutputs::default());
        assert_eq!("qvel,speed".parse::<OptionalOutputs>(), Err(UnknownOutput("speed".into())));
        for name in OptionalOutputs::NAMES {
            assert_ne!(name.parse::<OptionalOutputs>().unwrap(), OptionalOutputs::default(), "{name}");
        }
        assert!(UnknownOutput("x".into()).to_string().contains("energy_residual"));
        // The resource file's object: every name in the table's order, unknown names left out.
        let written = serde_json::to_string(&all).unwrap();
        assert_eq!(
            written,
            r#"{"qvel":true,"kinetic_energy":true,"power":true,"momentum":true,"energy_residual":false,"modal_strain_energy":false,"qfrc_constraint":false}"#
        );
        assert_eq!(serde_json::from_str::<OptionalOutputs>(&written).unwrap(), all);
        let older: OptionalOutputs = serde_json::from_str(r#"{"qvel":true,"future":true}"#).unwrap();
        assert_eq!(older, "qvel".parse().unwrap());
    }

    #[test]
    fn value_references_are_consecutive_and_decode() {
        let layout = Layout {
            nq: 7,
            nv: 6,
            nu: 2,
            wrench_inputs: 0,
            na: 0,
            sensordata: Vec::new(),
            switches: 0,
            eps_coupled: false,
            outputs: "qvel,power,momentum".parse().unwrap(),
            tree: None,
        };
        let all: Vec<(u32, RealVariable)> = layout.real_variables().collect();
        // Parameters, eps, ctrl, theta, nu, qvel, power, momentum, der(theta), der(nu).
        assert_eq!(all.len(), 2 + 6 + 2 + 7 + 6 + 6 + 1 + 6 + 7 + 6);
        for (k, &(vr, variable)) in all.iter().enumerate() {
            assert_eq!(vr, k as u32 + 1);
            assert_eq!(layout.real_variable(vr), Some(variable));
        }
        assert_eq!(layout.real_variable(0), None, "vr 0 is the Integer method");
        assert_eq!(layout.real_variable(all.len() as u32 + 1), None);
        assert_eq!(layout.value_reference(RealVariable::Ctrl(1)), Some(10));
        assert_eq!(layout.value_reference(RealVariable::Theta(0)), Some(11));
        assert_eq!(layout.value_reference(RealVariable::Ctrl(2)), None);
        // ν̇ feels every control; the outputs but the power none.
        let der_nu = layout.dependencies(RealVariable::DerNu(0)).unwrap();
        assert!(der_nu.contains(&RealVariable::Ctrl(0)) && der_nu.contains(&RealVariable::Ctrl(1)));
        assert!(!layout.dependencies(RealVariable::Qvel(0)).unwrap().contains(&RealVariable::Ctrl(0)));
        assert_eq!(layout.value_reference(RealVariable::KineticEnergy), None);
        assert_eq!(layout.value_reference(RealVariable::DerNu(5)), Some(all.len() as u32));
        // The energy residual's work integral is kept by the FMU's own integration only: no model exchange.
        let residual = Layout {
            nq: 7,
            nv: 6,
            nu: 0,
            wrench_inputs: 0,
            na: 0,
            sensordata: Vec::new(),
            switches: 0,
            eps_coupled: false,
            outputs: "energy_residual".parse().unwrap(),
            tree: None,
        };
        assert!(residual.real_variables().all(|(_, v)| !v.is_derivative()));
        assert!(!serves_model_exchange(residual.outputs));
    }

    #[test]
    fn method_values_round_trip() {
        for method in MethodSetting::ALL {
            assert_eq!(method_of_value(method_value(method)), Some(method));
        }
        assert_eq!(method_of_value(0), None);
        assert_eq!(method_of_value(MethodSetting::ALL.len() as i32 + 1), None);
        // Appended, never renumbered: the values a shipped FMU's users set.
        assert_eq!(method_value(Method::Dop853), 3);
        assert_eq!(method_value(Method::Tsit5), 6);
        assert_eq!(method_value(MethodSetting::Auto), 7);
    }
}
