//! `nudyn system`: a vehicle's plant FMU and controller FMU as one SSP 1.0
//! archive (Modelica Association, System Structure and Parameterization):
//!
//! - `SystemStructure.ssd`: the System with Components `plant` and
//!   `controller`, a Connector for every θ, ν and ε entry of each, a
//!   Connection per entry (plant θ, ν → controller; controller ε → plant),
//!   OMSimulator's annotation of the System's master (OMSimulator takes
//!   its master from `oms:FixedStepMaster` and aborts without one), and the
//!   DefaultExperiment with OSP's fixed-step annotation (libcosim reads its
//!   step from `osp:FixedStepAlgorithm baseStepSize`);
//! - `resources/plant.fmu`, `resources/controller.fmu`;
//! - `resources/plant.ssv`, `resources/controller.ssv`: the values set, one
//!   ParameterSet per component with names relative to it, bound by the
//!   component's ParameterBinding (libcosim reads component bindings only,
//!   and ignores a binding's `prefix`).
//!
//! libcosim does not apply a parameter value to an output (the plant's θ
//! and ν start values): the plant FMU carries the values set on it as its
//! own start values too, so that every importer starts where the file says.
//! No Enumeration connector is written: libcosim's SSP parser aborts the
//! process on one.

use std::collections::BTreeMap;
use std::path::Path;

use nudyn::control::ControlLaw;
use nudyn::math::normalize_wxyz;
use nudyn::model::{LinkJoint, Model};
use nudyn_contract::controller::ControllerLayout;
use nudyn_contract::plant::{DEFAULT_TOLERANCE, Layout, PlantResource, RealVariable};
use nudyn_contract::variable::{Kind, StartError, check_start};

use super::controller::{ControllerExportError, controller_fmu};
use super::plant::{ExportOptions, plant_fmu};
use super::{Entry, ExportError, FmiVersion, PlatformBinary, write_file, zip_archive};

/// The namespaces of SSP 1.0 and of OSP's annotations.
const SSD_NAMESPACE: &str = "http://ssp-standard.org/SSP1/SystemStructureDescription";
const SSC_NAMESPACE: &str = "http://ssp-standard.org/SSP1/SystemStructureCommon";
const SSV_NAMESPACE: &str = "http://ssp-standard.org/SSP1/SystemStructureParameterValues";
const OSP_NAMESPACE: &str = "http://opensimulationplatform.com/SSP/OSPAnnotations";
/// The namespace OMSimulator declares for its own annotations (it matches the `oms:` prefix itself).
const OMS_NAMESPACE: &str = "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd";

/// One of the system's two components.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Component {
    /// The vehicle's dynamics.
    Plant,
    /// The noninteracting control law.
    Controller,
}

impl Component {
    /// Its name in the SSD and in `--set`.
    pub fn name(self) -> &'static str {
        match self {
            Component::Plant => "plant",
            Component::Controller => "controller",
        }
    }
}

/// Why a system file cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum SystemError {
    /// A `--set` that is not COMPONENT.NAME=VALUE.
    #[error("--set {0}: expected COMPONENT.NAME=VALUE, e.g. controller.c1=2 or plant.nu[4]=0.5")]
    Syntax(String),
    /// A `--set` naming a component the system does not have.
    #[error("--set {0}: the system's components are plant and controller")]
    UnknownComponent(String),
    /// A `--set` whose value is not a number.
    #[error("--set {text}: '{value}' is not a number")]
    NotANumber {
        /// The option's text.
        text: String,
        /// The value given.
        value: String,
    },
    /// A `--set` naming no variable of the component with a start value.
    #[error("--set {text}: {component} has no variable {name} with a start value (it has {settable})")]
    UnknownVariable {
        /// The option's text.
        text: String,
        /// The component.
        component: &'static str,
        /// The name given.
        name: String,
        /// The names it has, arrays as `name[1..n]`.
        settable: String,
    },
    /// Two `--set` options naming the same variable (one would be lost).
    #[error("--set {text}: {component}.{name} is already set by --set {first}; set each variable once")]
    SetTwice {
        /// The option's text.
        text: String,
        /// The component.
        component: &'static str,
        /// The variable set twice.
        name: String,
        /// The text of the option that set it first.
        first: String,
    },
    /// Values that leave one of θ's quaternions with zero norm.
    #[error(
        "{sets}: theta[{first}] to theta[{last}] (joint '{joint}') would be a zero quaternion, which no host can \
         start the plant from; a quaternion needs a non-zero norm (the plant FMU normalizes a non-unit one at \
         initialization, as MuJoCo does)"
    )]
    ZeroQuaternion {
        /// The options that set its entries, as given ("--set plant.theta=0").
        sets: String,
        /// Its first entry, numbered from 1 as the FMU's variables.
        first: usize,
        /// Its last entry.
        last: usize,
        /// The joint it belongs to.
        joint: String,
    },
    /// A value the variable does not accept.
    #[error("--set {text}: {source}")]
    Refused {
        /// The option's text.
        text: String,
        /// Why.
        source: StartError,
    },
    /// The stop time or step cannot describe a run.
    #[error("{0}")]
    Experiment(String),
    /// FMI 3.0 components were asked for.
    #[error(
        "--fmi-version 3: the SSP importers nudyn is tested with run FMI 2.0 components only (FMPy's simulate_ssp \
         instantiates FMI 2.0 slaves; libcosim's SSP loader reads FMI 1.0 and 2.0); use --fmi-version 2"
    )]
    Fmi3,
    /// An FMU cannot be written.
    #[error(transparent)]
    Export(#[from] ExportError),
    /// The controller FMU cannot be written.
    #[error(transparent)]
    Controller(#[from] ControllerExportError),
}

/// What `nudyn system` is asked for.
#[derive(Clone, Debug)]
pub struct SystemOptions {
    /// The plant FMU's model identifier.
    pub plant_identifier: String,
    /// The controller FMU's model identifier.
    pub controller_identifier: String,
    /// The plant's optional outputs and FMI version.
    pub plant: ExportOptions,
    /// The DefaultExperiment's communication step (s).
    pub step: f64,
    /// The DefaultExperiment's stop time (s).
    pub stop: f64,
    /// The `--set` options as given.
    pub sets: Vec<String>,
}

/// A variable a `--set` may name.
struct Settable {
    name: String,
    kind: Kind,
    has_start: bool,
}

/// The values set, by component, as (variable name, value) in name order.
pub type Values = BTreeMap<Component, BTreeMap<String, f64>>;

/// A quaternion of the plant's θ: four entries that must not all be zero.
struct Quaternion {
    /// The joint it belongs to.
    joint: String,
    /// Its first entry's index in θ (from 0).
    first: usize,
    /// Its entries' default start values (qpos0).
    default: [f64; 4],
}

/// The quaternions of `model`'s θ (ball joints and the rotation of free joints).
fn quaternions(model: &Model) -> Vec<Quaternion> {
    model
        .links
        .iter()
        .filter(|link| link.joint == LinkJoint::Ball)
        .map(|link| {
            let q = &model.qpos0[link.qpos_adr..link.qpos_adr + 4];
            Quaternion { joint: link.joint_name.clone(), first: link.qpos_adr, default: [q[0], q[1], q[2], q[3]] }
        })
        .collect()
}

/// Reads the `--set` options against the two components' variables; a name
/// without an index on an array sets every entry (`controller.c1=2`). A
/// variable set by two options is refused, as is a quaternion of the
/// plant's `quaternions` left with zero norm.
fn values_set(
    sets: &[String],
    plant: &[Settable],
    controller: &[Settable],
    quaternions: &[Quaternion],
) -> Result<Values, SystemError> {
    let mut values = Values::new();
    // The option that set each variable, for the refusals.
    let mut set_by: BTreeMap<(Component, String), &String> = BTreeMap::new();
    for text in sets {
        let syntax = || SystemError::Syntax(text.clone());
        let (path, value) = text.split_once('=').ok_or_else(syntax)?;
        let (component, name) = path.trim().split_once('.').ok_or_else(syntax)?;
        let (component, variables) = match component {
            "plant" => (Component::Plant, plant),
            "controller" => (Component::Controller, controller),
            _ => return Err(SystemError::UnknownComponent(text.clone())),
        };
        let value_text = value.trim();
        let value: f64 = value_text
            .parse()
            .map_err(|_| SystemError::NotANumber { text: text.clone(), value: value_text.to_string() })?;
        let array_entry = format!("{name}[");
        let named: Vec<&Settable> = match variables.iter().find(|v| v.name == name) {
            Some(variable) => vec![variable],
            None => variables.iter().filter(|v| v.name.starts_with(&array_entry) && v.has_start).collect(),
        };
        if named.is_empty() {
            return Err(SystemError::UnknownVariable {
                text: text.clone(),
                component: component.name(),
                name: name.to_string(),
                settable: settable_names(variables),
            });
        }
        for variable in named {
            check_start(&variable.name, variable.kind, variable.has_start, value)
                .map_err(|source| SystemError::Refused { text: text.clone(), source })?;
            if let Some(first) = set_by.insert((component, variable.name.clone()), text) {
                return Err(SystemError::SetTwice {
                    text: text.clone(),
                    component: component.name(),
                    name: variable.name.clone(),
                    first: first.clone(),
                });
            }
            values.entry(component).or_default().insert(variable.name.clone(), value);
        }
    }
    let plant_values = values.get(&Component::Plant);
    for quaternion in quaternions {
        let names: Vec<String> = (1..=4).map(|i| format!("theta[{}]", quaternion.first + i)).collect();
        let mut q = quaternion.default;
        for (entry, name) in q.iter_mut().zip(&names) {
            if let Some(&value) = plant_values.and_then(|set| set.get(name)) {
                *entry = value;
            }
        }
        if normalize_wxyz(&mut q).is_none() {
            let mut sets: Vec<String> = Vec::new();
            for name in &names {
                let option = set_by.get(&(Component::Plant, name.clone())).map(|text| format!("--set {text}"));
                if let Some(option) = option.filter(|option| !sets.contains(option)) {
                    sets.push(option);
                }
            }
            return Err(SystemError::ZeroQuaternion {
                sets: sets.join(", "),
                first: quaternion.first + 1,
                last: quaternion.first + 4,
                joint: quaternion.joint.clone(),
            });
        }
    }
    Ok(values)
}

/// "tolerance, max_step, eps[1..6], theta[1..7]": the names with a start
/// value, an array's entries as one range.
fn settable_names(variables: &[Settable]) -> String {
    let mut groups: Vec<(String, usize)> = Vec::new();
    for variable in variables.iter().filter(|v| v.has_start) {
        let base = variable.name.split('[').next().unwrap_or(&variable.name).to_string();
        match groups.last_mut() {
            Some((last, count)) if *last == base && variable.name.contains('[') => *count += 1,
            _ => groups.push((base, usize::from(variable.name.contains('[')))),
        }
    }
    let names: Vec<String> =
        groups.into_iter().map(|(base, n)| if n == 0 { base } else { format!("{base}[1..{n}]") }).collect();
    names.join(", ")
}

/// Writes the SSP archive `out` for `model` with `law`: both FMUs built
/// from `binaries`, the SSD and the values' SSV files. Returns the values
/// set, by component. Written whole or not at all (crate::output).
pub fn write_system(
    model: &Model,
    law: &ControlLaw,
    options: &SystemOptions,
    binaries: &[PlatformBinary],
    out: &Path,
) -> Result<Values, SystemError> {
    if options.plant.fmi_version == FmiVersion::Fmi3 {
        return Err(SystemError::Fmi3);
    }
    check_experiment(options.step, options.stop)?;
    let plant_resource = PlantResource::new(model.clone(), options.plant.outputs);
    let plant_layout = plant_resource.layout();
    let plant_variables: Vec<Settable> = plant_layout
        .elements()
        .map(|element| Settable {
            name: element.name(),
            kind: element.kind(),
            has_start: element.default_start(model).is_some(),
        })
        .collect();
    let defaults = law.default_parameters(model).map_err(ControllerExportError::from)?;
    let layout = ControllerLayout::new(model, law);
    let controller_variables: Vec<Settable> = layout
        .elements()
        .map(|e| Settable { name: e.name(), kind: e.kind(), has_start: e.start(model, &defaults).is_some() })
        .collect();
    let values = values_set(&options.sets, &plant_variables, &controller_variables, &quaternions(model))?;

    let plant_starts = values.get(&Component::Plant).cloned().unwrap_or_default();
    let plant_resource = plant_resource.with_starts(plant_starts).expect("checked against the same variables");
    let plant_options = ExportOptions { model_identifier: options.plant_identifier.clone(), ..options.plant.clone() };
    let plant = plant_fmu(&plant_resource, &plant_options, binaries, out)?;
    let controller_identifier = &options.controller_identifier;
    let controller = controller_fmu(model, law, controller_identifier, FmiVersion::Fmi2, false, binaries, out)?;
    let ssd = system_structure(model, options, &values);
    let ssvs: Vec<(String, String)> =
        values.iter().map(|(component, set)| (ssv_path(*component), parameter_set(component.name(), set))).collect();
    let mut entries = vec![
        Entry { name: "SystemStructure.ssd".to_string(), bytes: ssd.as_bytes(), mode: 0o644 },
        Entry { name: "resources/plant.fmu".to_string(), bytes: &plant, mode: 0o644 },
        Entry { name: "resources/controller.fmu".to_string(), bytes: &controller, mode: 0o644 },
    ];
    entries.extend(ssvs.iter().map(|(name, text)| Entry { name: name.clone(), bytes: text.as_bytes(), mode: 0o644 }));
    write_file(out, &zip_archive(&entries, out)?)?;
    Ok(values)
}

/// Refuses a step and stop time that cannot describe a run of whole steps.
fn check_experiment(step: f64, stop: f64) -> Result<(), SystemError> {
    if !(step.is_finite() && step > 0.0 && stop.is_finite() && stop > 0.0) {
        return Err(SystemError::Experiment(format!("--step and --stop must be positive, found {step} and {stop}")));
    }
    let steps = (stop / step).round();
    if steps < 1.0 || ((steps * step - stop) / step).abs() > 1e-9 {
        return Err(SystemError::Experiment(format!("--stop {stop} is not a multiple of --step {step}")));
    }
    Ok(())
}

/// The path of a component's ParameterValues file in the archive.
fn ssv_path(component: Component) -> String {
    format!("resources/{}.ssv", component.name())
}

/// A number as XML's xs:double reads it back exactly (shortest round trip).
fn double(x: f64) -> String {
    let mut buffer = ryu::Buffer::new();
    buffer.format(x).to_string()
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// `SystemStructure.ssd`: the plant's θ, ν and ε connected to the
/// controller's variables of the same names, listed from the plant's layout.
fn system_structure(model: &Model, options: &SystemOptions, values: &Values) -> String {
    let plant = Layout::new(model, options.plant.outputs);
    let names = |connected: fn(&RealVariable) -> bool| -> Vec<String> {
        plant.real_variables().filter(|(_, v)| connected(v)).filter_map(|(_, v)| plant.name(v)).collect()
    };
    let state = names(|v| matches!(v, RealVariable::Theta(_) | RealVariable::Nu(_)));
    let eps = names(|v| matches!(v, RealVariable::Eps(_)));
    let connector = |name: &String, kind: &str| {
        format!("          <ssd:Connector name=\"{}\" kind=\"{kind}\"><ssc:Real/></ssd:Connector>\n", escape(name))
    };
    let component = |component: Component, outputs: &[String], inputs: &[String]| {
        let mut xml = format!(
            "      <ssd:Component name=\"{0}\" type=\"application/x-fmu-sharedlibrary\" source=\"resources/{0}.fmu\">\n\
             \x20       <ssd:Connectors>\n",
            component.name()
        );
        xml += &outputs.iter().map(|n| connector(n, "output")).collect::<String>();
        xml += &inputs.iter().map(|n| connector(n, "input")).collect::<String>();
        xml += "        </ssd:Connectors>\n";
        if values.contains_key(&component) {
            xml += &format!(
                "        <ssd:ParameterBindings>\n          <ssd:ParameterBinding source=\"{}\"/>\n        </ssd:ParameterBindings>\n",
                ssv_path(component)
            );
        }
        xml + "      </ssd:Component>\n"
    };
    let connection = |from: Component, to: Component, name: &String| {
        format!(
            "      <ssd:Connection startElement=\"{from}\" startConnector=\"{name}\" endElement=\"{to}\" endConnector=\"{name}\"/>\n",
            from = from.name(),
            name = escape(name),
            to = to.name()
        )
    };
    let connections: String = state
        .iter()
        .map(|n| connection(Component::Plant, Component::Controller, n))
        .chain(eps.iter().map(|n| connection(Component::Controller, Component::Plant, n)))
        .collect();
    let (step, stop) = (double(options.step), double(options.stop));
    // OMSimulator hands its master's tolerance to the FMUs (fmi2SetupExperiment),
    // where it takes the place of the plant's `tolerance`: the plant's own value.
    let tolerance =
        values.get(&Component::Plant).and_then(|plant| plant.get("tolerance")).copied().unwrap_or(DEFAULT_TOLERANCE);
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <ssd:SystemStructureDescription xmlns:ssd=\"{SSD_NAMESPACE}\" xmlns:ssc=\"{SSC_NAMESPACE}\" \
         xmlns:osp=\"{OSP_NAMESPACE}\" version=\"1.0\" name=\"{name}\" generationTool=\"nudyn {version}\">\n\
         \x20 <ssd:System name=\"{name}\" description=\"plant FMU and noninteracting controller FMU, connected name to name\">\n\
         \x20   <ssd:Elements>\n{plant}{controller}    </ssd:Elements>\n\
         \x20   <ssd:Connections>\n{connections}    </ssd:Connections>\n\
         \x20   <ssd:Annotations>\n\
         \x20     <ssc:Annotation type=\"org.openmodelica\">\n\
         \x20       <oms:Annotations xmlns:oms=\"{OMS_NAMESPACE}\">\n\
         \x20         <oms:SimulationInformation>\n\
         \x20           <oms:FixedStepMaster description=\"oms-ma\" stepSize=\"{step}\" \
         absoluteTolerance=\"{tolerance}\" relativeTolerance=\"{tolerance}\"/>\n\
         \x20         </oms:SimulationInformation>\n\
         \x20       </oms:Annotations>\n\
         \x20     </ssc:Annotation>\n\
         \x20   </ssd:Annotations>\n\
         \x20 </ssd:System>\n\
         \x20 <ssd:DefaultExperiment startTime=\"0\" stopTime=\"{stop}\">\n\
         \x20   <ssd:Annotations>\n\
         \x20     <ssc:Annotation type=\"com.opensimulationplatform\">\n\
         \x20       <osp:Algorithm><osp:FixedStepAlgorithm baseStepSize=\"{step}\"/></osp:Algorithm>\n\
         \x20     </ssc:Annotation>\n\
         \x20   </ssd:Annotations>\n\
         \x20 </ssd:DefaultExperiment>\n\
         </ssd:SystemStructureDescription>\n",
        name = escape(&options.plant_identifier),
        tolerance = double(tolerance),
        version = env!("CARGO_PKG_VERSION"),
        plant = component(Component::Plant, &state, &eps),
        controller = component(Component::Controller, &eps, &state),
    )
}

/// A component's ParameterValues file: its values, names relative to it.
fn parameter_set(component: &str, values: &BTreeMap<String, f64>) -> String {
    let parameters: String = values
        .iter()
        .map(|(name, value)| {
            format!(
                "    <ssv:Parameter name=\"{}\"><ssv:Real value=\"{}\"/></ssv:Parameter>\n",
                escape(name),
                double(*value)
            )
        })
        .collect();
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <ssv:ParameterSet xmlns:ssv=\"{SSV_NAMESPACE}\" version=\"1.0\" name=\"{component}\">\n\
         \x20 <ssv:Parameters>\n{parameters}  </ssv:Parameters>\n\
         </ssv:ParameterSet>\n"
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use nudyn_contract::variable::{Kind, Range};

    fn settable(name: &str, kind: Kind) -> Settable {
        Settable { name: name.into(), kind, has_start: true }
    }

    #[test]
    fn sets_name_entries_and_whole_arrays() {
        let gain = Kind::tunable_parameter(Range::NonNegative);
        let controller = [settable("c1[1]", gain), settable("c1[2]", gain)];
        let plant =
            [settable("nu[1]", Kind::STATE_OUTPUT), settable("tolerance", Kind::fixed_parameter(Range::Positive))];
        let sets = ["controller.c1=2".to_string(), "plant.nu[1]=-0.5".to_string()];
        let values = values_set(&sets, &plant, &controller, &[]).unwrap();
        assert_eq!(values[&Component::Controller].len(), 2);
        assert_eq!(values[&Component::Controller]["c1[2]"], 2.0);
        assert_eq!(values[&Component::Plant]["nu[1]"], -0.5);

        let refused = |set: &str| values_set(&[set.to_string()], &plant, &controller, &[]).unwrap_err().to_string();
        assert!(refused("controller.c1=-1").contains("c1[1] = -1 is refused: it must be non-negative"));
        assert!(refused("plant.tolerance=0").contains("must be positive"));
        assert!(refused("plant.nu[1]=NaN").contains("must be finite"));
        assert!(
            refused("plant.nu[2]=1")
                .contains("plant has no variable nu[2] with a start value (it has nu[1..1], tolerance)")
        );
        assert!(refused("plant.nu[1]=fast").contains("'fast' is not a number"));
        assert!(refused("ground.x=1").contains("components are plant and controller"));
        assert!(refused("nu[1]=1").contains("expected COMPONENT.NAME=VALUE"));
    }

    #[test]
    fn a_variable_set_twice_is_refused_naming_both_options() {
        let gain = Kind::tunable_parameter(Range::NonNegative);
        let controller = [settable("c1[1]", gain), settable("c1[2]", gain)];
        let twice = |sets: &[&str]| {
            let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
            values_set(&sets, &[], &controller, &[]).unwrap_err().to_string()
        };
        assert_eq!(
            twice(&["controller.c1[2]=1", "controller.c1[2]=3"]),
            "--set controller.c1[2]=3: controller.c1[2] is already set by --set controller.c1[2]=1; set each variable once"
        );
        assert!(
            twice(&["controller.c1=2", "controller.c1[1]=3"])
                .starts_with("--set controller.c1[1]=3: controller.c1[1] is already set by --set controller.c1=2;")
        );
    }

    #[test]
    fn a_zero_quaternion_is_refused_and_a_non_unit_one_kept() {
        let plant: Vec<Settable> = (1..=8).map(|k| settable(&format!("theta[{k}]"), Kind::STATE_OUTPUT)).collect();
        // A free joint: position theta[1..3], quaternion theta[4..7]; a hinge theta[8].
        let quaternion = [Quaternion { joint: "bus_free".into(), first: 3, default: [1.0, 0.0, 0.0, 0.0] }];
        let set = |sets: &[&str]| {
            let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
            values_set(&sets, &plant, &[], &quaternion)
        };
        let zero = set(&["plant.theta=0"]).unwrap_err().to_string();
        assert!(
            zero.starts_with(
                "--set plant.theta=0: theta[4] to theta[7] (joint 'bus_free') would be a zero quaternion, which no host \
                 can start the plant from; a quaternion needs a non-zero norm"
            ),
            "{zero}"
        );
        // The entries left at qpos0 count: w = 0 alone leaves (0, 0, 0, 0) here.
        let by_entries = set(&["plant.theta[8]=1", "plant.theta[4]=0"]).unwrap_err().to_string();
        assert!(by_entries.starts_with("--set plant.theta[4]=0: theta[4] to theta[7]"), "{by_entries}");
        assert!(set(&["plant.theta[4]=0", "plant.theta[5]=1"]).is_ok());
        // A non-unit quaternion is written as given: the plant normalizes it at initialization.
        let values = set(&["plant.theta[4]=2"]).unwrap();
        assert_eq!(values[&Component::Plant]["theta[4]"], 2.0);
    }
}
