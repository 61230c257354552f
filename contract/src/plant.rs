//! The plant FMU, the vehicle's dynamics: its variables, value references,
//! parameter defaults, capabilities and resource file.
//!
//! Variables follow MuJoCo's qpos/qvel order with 1-based structured names
//! (`theta[1]`): inputs `eps[1..nv]` and, for a vehicle with actuators,
//! `ctrl[1..nu]` in MuJoCo's actuator order; outputs `theta[1..nq]` and
//! `nu[1..nv]`, for a vehicle with sensors `sensordata[1..n]` in MuJoCo's
//! sensor order and layout, and the optional outputs chosen at export.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use nudyn::integrate::{Method, MethodSetting};
use nudyn::model::Model;
use nudyn::vehicle::SensorKind;

use crate::blocks::{Block, RealBlock, every_variable, numbered_blocks, real_blocks, value_reference_of, variable_at};
use crate::capabilities::Capabilities;
use crate::resource::Resource;
use crate::variable::{Kind, Range, StartError, check_start};

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
/// the energy residual, whose work integral only the FMU's own integration
/// keeps.
pub fn capabilities(outputs: OptionalOutputs) -> Capabilities {
    Capabilities { model_exchange: !outputs.energy_residual, ..CAPABILITIES }
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

/// The optional outputs chosen at export; those not chosen do not exist in
/// the FMU, so they cost nothing at run time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct OptionalOutputs {
    /// `qvel[1..nv]`: θ̇ in MuJoCo's convention.
    pub qvel: bool,
    /// `kinetic_energy`: K = ½|ν|².
    pub kinetic_energy: bool,
    /// `power`: ν·ε of the applied ε.
    pub power: bool,
    /// `momentum[1..6]`: spatial momentum (angular about the world origin, then linear), world axes.
    pub momentum: bool,
    /// `energy_residual`: K − K₀ − ∫ν·ν̇ dt, the integration's energy error.
    #[serde(default)]
    pub energy_residual: bool,
    /// `qfrc_constraint[1..nv]`: MuJoCo's qfrc_constraint, the constraint forces' joint forces.
    #[serde(default)]
    pub qfrc_constraint: bool,
}

/// The flag of one optional output in [`OptionalOutputs`].
type Flag = fn(&mut OptionalOutputs) -> &mut bool;

/// Every optional output: its name, as `--outputs` takes it, and its flag.
/// One list, which the names and the parser read.
const OPTIONAL_OUTPUTS: [(&str, Flag); 6] = [
    ("qvel", |o| &mut o.qvel),
    ("kinetic_energy", |o| &mut o.kinetic_energy),
    ("power", |o| &mut o.power),
    ("momentum", |o| &mut o.momentum),
    ("energy_residual", |o| &mut o.energy_residual),
    ("qfrc_constraint", |o| &mut o.qfrc_constraint),
];

impl OptionalOutputs {
    /// The name of every optional output, as `--outputs` takes them.
    pub const NAMES: [&str; OPTIONAL_OUTPUTS.len()] = {
        let mut names = [""; OPTIONAL_OUTPUTS.len()];
        let mut i = 0;
        while i < names.len() {
            names[i] = OPTIONAL_OUTPUTS[i].0;
            i += 1;
        }
        names
    };

    /// The flag of the output `name`, if it is one of [`OptionalOutputs::NAMES`].
    fn flag(&mut self, name: &str) -> Option<&mut bool> {
        OPTIONAL_OUTPUTS.iter().find(|(known, _)| *known == name).map(|(_, flag)| flag(self))
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
            *outputs.flag(name).ok_or_else(|| UnknownOutput(name.to_string()))? = true;
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
            let variable = layout
                .real_variables()
                .map(|(_, variable)| variable)
                .find(|&variable| layout.name(variable).as_ref() == Some(name))
                .ok_or_else(|| StartError::Unknown(name.clone()))?;
            check_start(name, variable.kind(), variable.start(&self.model).is_some(), value)?;
        }
        self.starts = starts;
        Ok(self)
    }

    /// The start value of `variable`: the one chosen at export, else its default.
    pub fn start(&self, variable: RealVariable) -> Option<f64> {
        // Most FMUs choose no start: no name to look up.
        let chosen = (!self.starts.is_empty())
            .then(|| self.layout().name(variable))
            .flatten()
            .and_then(|name| self.starts.get(&name).copied());
        chosen.or_else(|| variable.start(&self.model))
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
    /// Optional output `qfrc_constraint[k+1]` (MuJoCo's `d.qfrc_constraint`).
    QfrcConstraint(usize),
    /// `der(theta[k+1])`: the qpos rate, a state derivative of model exchange.
    DerTheta(usize),
    /// `der(nu[k+1])`: ν̇, a state derivative of model exchange.
    DerNu(usize),
}

impl RealVariable {
    /// Its element index within its block (0 for a scalar).
    pub fn index(self) -> usize {
        match self {
            RealVariable::Tolerance
            | RealVariable::MaxStep
            | RealVariable::KineticEnergy
            | RealVariable::Power
            | RealVariable::EnergyResidual => 0,
            RealVariable::Eps(k)
            | RealVariable::Ctrl(k)
            | RealVariable::XfrcApplied(k)
            | RealVariable::Theta(k)
            | RealVariable::Nu(k)
            | RealVariable::Sensordata(k)
            | RealVariable::Qvel(k)
            | RealVariable::Momentum(k)
            | RealVariable::QfrcConstraint(k)
            | RealVariable::DerTheta(k)
            | RealVariable::DerNu(k) => k,
        }
    }

    /// What kind of variable it is. θ and ν are outputs with initial="exact":
    /// settable until initialization, which is how a master chooses the
    /// initial state.
    pub fn kind(self) -> Kind {
        match self {
            RealVariable::Tolerance => Kind::fixed_parameter(Range::Positive),
            RealVariable::MaxStep => Kind::fixed_parameter(Range::NonNegative),
            RealVariable::Eps(_) | RealVariable::Ctrl(_) | RealVariable::XfrcApplied(_) => Kind::INPUT,
            RealVariable::Theta(_) | RealVariable::Nu(_) => Kind::STATE_OUTPUT,
            RealVariable::DerTheta(_) | RealVariable::DerNu(_) => Kind::DERIVATIVE,
            _ => Kind::CALCULATED_OUTPUT,
        }
    }

    /// The start value written into the modelDescription, if it has one.
    pub fn start(self, model: &Model) -> Option<f64> {
        match self {
            RealVariable::Tolerance => Some(DEFAULT_TOLERANCE),
            RealVariable::MaxStep => Some(DEFAULT_MAX_STEP),
            RealVariable::Eps(_) | RealVariable::Ctrl(_) | RealVariable::XfrcApplied(_) | RealVariable::Nu(_) => {
                Some(0.0)
            }
            RealVariable::Theta(k) => Some(model.qpos0[k]),
            _ => None,
        }
    }

    /// Whether it is a state derivative of model exchange.
    pub fn is_derivative(self) -> bool {
        matches!(self, RealVariable::DerTheta(_) | RealVariable::DerNu(_))
    }
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

/// The plant's Real variables and their value references: consecutive
/// blocks after the two parameters, `tolerance` (1) and `max_step` (2), in
/// the order eps, ctrl, xfrc_applied, theta, nu, sensordata, the chosen optional outputs, then the state
/// derivatives der(theta) and der(nu) of model exchange, when the FMU serves
/// it (last, so that the blocks before keep the value references they had
/// before model exchange).
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
    /// What each sensordata entry depends on (MuJoCo's nsensordata entries).
    pub sensordata: Vec<SensorDependence>,
    /// The optional outputs present.
    pub outputs: OptionalOutputs,
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
            sensordata,
            outputs,
        }
    }

    /// The blocks in value-reference order, each with its first value reference.
    fn blocks(&self) -> impl Iterator<Item = (u32, Block<RealVariable>)> {
        let o = self.outputs;
        let model_exchange = capabilities(o).model_exchange;
        let optional = |present: bool, len: usize| if present { len } else { 0 };
        let blocks = [
            Block::scalar("tolerance", true, |_| RealVariable::Tolerance),
            Block::scalar("max_step", true, |_| RealVariable::MaxStep),
            Block::array("eps", self.nv, RealVariable::Eps),
            Block::array("ctrl", self.nu, RealVariable::Ctrl),
            Block::array("xfrc_applied", self.wrench_inputs, RealVariable::XfrcApplied),
            Block::array("theta", self.nq, RealVariable::Theta),
            Block::array("nu", self.nv, RealVariable::Nu),
            Block::array("sensordata", self.sensordata.len(), RealVariable::Sensordata),
            Block::array("qvel", optional(o.qvel, self.nv), RealVariable::Qvel),
            Block::scalar("kinetic_energy", o.kinetic_energy, |_| RealVariable::KineticEnergy),
            Block::scalar("power", o.power, |_| RealVariable::Power),
            Block::array("momentum", optional(o.momentum, 6), RealVariable::Momentum),
            Block::scalar("energy_residual", o.energy_residual, |_| RealVariable::EnergyResidual),
            Block::array("qfrc_constraint", optional(o.qfrc_constraint, self.nv), RealVariable::QfrcConstraint),
            Block::derivative("theta", optional(model_exchange, self.nq), RealVariable::DerTheta),
            Block::derivative("nu", optional(model_exchange, self.nv), RealVariable::DerNu),
        ];
        numbered_blocks(METHOD_VR + 1, blocks)
    }

    /// The Real variables' blocks, numbered.
    pub fn real_blocks(&self) -> Vec<RealBlock> {
        real_blocks(self.blocks())
    }

    /// The variable with value reference `vr`, if any.
    pub fn real_variable(&self, vr: u32) -> Option<RealVariable> {
        variable_at(self.blocks(), vr)
    }

    /// All Real variables with their value references, in order.
    pub fn real_variables(&self) -> impl Iterator<Item = (u32, RealVariable)> {
        every_variable(self.blocks())
    }

    /// The knowns (states θ, ν and inputs ε, ctrl) that the output or state
    /// derivative `variable` depends on; `None` for a parameter, an input or
    /// a state. For co-simulation this says that no output but the power
    /// feeds through from the inputs.
    pub fn dependencies(&self, variable: RealVariable) -> Option<Vec<RealVariable>> {
        let theta = (0..self.nq).map(RealVariable::Theta);
        let nu = (0..self.nv).map(RealVariable::Nu);
        let eps = (0..self.nv).map(RealVariable::Eps);
        let ctrl = (0..self.nu).map(RealVariable::Ctrl);
        let wrenches = (0..self.wrench_inputs).map(RealVariable::XfrcApplied);
        let list = match variable {
            RealVariable::Tolerance
            | RealVariable::MaxStep
            | RealVariable::Eps(_)
            | RealVariable::Ctrl(_)
            | RealVariable::XfrcApplied(_) => {
                return None;
            }
            // The states themselves.
            RealVariable::Theta(_) | RealVariable::Nu(_) => vec![variable],
            RealVariable::KineticEnergy => nu.collect(),
            RealVariable::Power => nu.chain(eps).collect(),
            // One problem couples every row to every input's ε.
            RealVariable::QfrcConstraint(_) => theta.chain(nu).chain(eps).chain(ctrl).chain(wrenches).collect(),
            // Every actuator's ε reaches every dof through ℓ in general.
            RealVariable::DerNu(k) => {
                theta.chain(nu).chain([RealVariable::Eps(k)]).chain(ctrl).chain(wrenches).collect()
            }
            RealVariable::Sensordata(k) => match self.sensordata[k] {
                SensorDependence::Nothing => Vec::new(),
                SensorDependence::Configuration => theta.collect(),
                SensorDependence::Motion => theta.chain(nu).collect(),
                SensorDependence::Controls => theta.chain(nu).chain(ctrl).collect(),
                SensorDependence::Inputs => theta.chain(nu).chain(eps).chain(ctrl).chain(wrenches).collect(),
            },
            // θ̇ = ℓ*(θ)ν, the momentum and the energy residual depend on the configuration and every ν.
            RealVariable::Qvel(_)
            | RealVariable::Momentum(_)
            | RealVariable::EnergyResidual
            | RealVariable::DerTheta(_) => theta.chain(nu).collect(),
        };
        Some(list)
    }

    /// [`Layout::dependencies`] by value reference: those of the knowns of
    /// the Real `vr`, ascending.
    pub fn dependency_vrs(&self, vr: u32) -> Option<Vec<u32>> {
        let knowns = self.dependencies(self.real_variable(vr)?)?;
        let mut vrs: Vec<u32> = knowns.into_iter().filter_map(|known| self.value_reference(known)).collect();
        vrs.sort_unstable();
        Some(vrs)
    }

    /// The structured, 1-based name of `variable` (as in
    /// `modelDescription.xml`), from its block; `None` if this layout does
    /// not have it.
    pub fn name(&self, variable: RealVariable) -> Option<String> {
        let k = variable.index();
        self.blocks().find(|(_, block)| k < block.len && (block.variable)(k) == variable).map(|(first, block)| {
            RealBlock { name: block.name, shape: block.shape, first, len: block.len }.element_name(k)
        })
    }

    /// The value reference of `variable`, if this layout has it (in constant
    /// time, one pass over the blocks: dependency lists of large vehicles look up millions).
    pub fn value_reference(&self, variable: RealVariable) -> Option<u32> {
        value_reference_of(self.blocks(), variable, variable.index())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_optional_outputs() {
        let all: OptionalOutputs = "qvel, kinetic_energy,power,momentum".parse().unwrap();
        assert_eq!(
            all,
            OptionalOutputs {
                qvel: true,
                kinetic_energy: true,
                power: true,
                momentum: true,
                energy_residual: false,
                qfrc_constraint: false
            }
        );
        assert_eq!("".parse::<OptionalOutputs>().unwrap(), OptionalOutputs::default());
        assert_eq!("qvel,speed".parse::<OptionalOutputs>(), Err(UnknownOutput("speed".into())));
        for name in OptionalOutputs::NAMES {
            assert_ne!(name.parse::<OptionalOutputs>().unwrap(), OptionalOutputs::default(), "{name}");
        }
        assert!(UnknownOutput("x".into()).to_string().contains("energy_residual"));
    }

    #[test]
    fn value_references_are_consecutive_and_decode() {
        let layout = Layout {
            nq: 7,
            nv: 6,
            nu: 2,
            wrench_inputs: 0,
            sensordata: Vec::new(),
            outputs: "qvel,power,momentum".parse().unwrap(),
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
            sensordata: Vec::new(),
            outputs: "energy_residual".parse().unwrap(),
        };
        assert!(residual.real_variables().all(|(_, v)| !v.is_derivative()));
        assert!(!capabilities(residual.outputs).model_exchange);
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
