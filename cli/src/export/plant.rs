//! The plant FMU's modelDescription: the contract's variables with
//! descriptions that name each joint, component and unit.

use std::path::Path;

use modeldescription as md;
use modeldescription::fmi3 as md3;
use nudyn::integrate::MethodSetting;
use nudyn::model::{Model, SensorSource};
use nudyn::vehicle::{JointKind, SensorKind};
use nudyn_contract::plant::{
    ENERGY_PROJECTION_NAME, ENERGY_PROJECTION_VR, Layout, METHOD_NAME, METHOD_TYPE, METHOD_VR, OptionalOutputs,
    PlantResource, RealVariable, capabilities, method_value,
};
use nudyn_contract::resource::Resource;

use super::{
    Document, ExportError, FmiVersion, Header, PlatformBinary, check_model_identifier, documentation, fmi3,
    fmu_archive, generation_date_and_time, real_variable, write_file,
};

/// What `nudyn export` is asked for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ExportOptions {
    /// The model identifier: the shared library's name, a C identifier.
    pub model_identifier: String,
    /// The optional outputs.
    pub outputs: OptionalOutputs,
    /// The FMI version.
    pub fmi_version: FmiVersion,
}

/// What one coordinate or dof is, for variable descriptions: the joint, its
/// kind, and the component and unit of entry `k` within the joint.
fn joint_entry(model: &Model, index: usize, qpos: bool) -> (String, &'static str) {
    let joint = model
        .joints
        .iter()
        .rev()
        .find(|j| if qpos { j.qpos_adr <= index } else { j.dof_adr <= index })
        .expect("every coordinate belongs to a joint");
    let k = index - if qpos { joint.qpos_adr } else { joint.dof_adr };
    const AXES: [&str; 3] = ["x", "y", "z"];
    const QUAT: [&str; 4] = ["w", "x", "y", "z"];
    let (component, unit) = match (joint.kind, qpos) {
        (JointKind::Hinge, true) => (String::new(), "rad"),
        (JointKind::Hinge, false) => (String::new(), "rad/s"),
        (JointKind::Slide, true) => (String::new(), "m"),
        (JointKind::Slide, false) => (String::new(), "m/s"),
        (JointKind::Ball, true) => (format!(", quaternion {}", QUAT[k]), "1"),
        (JointKind::Ball, false) => (format!(", angular velocity {} in the body frame", AXES[k]), "rad/s"),
        (JointKind::Free, true) if k < 3 => (format!(", position {} in world", AXES[k]), "m"),
        (JointKind::Free, true) => (format!(", quaternion {}", QUAT[k - 3]), "1"),
        (JointKind::Free, false) if k < 3 => (format!(", linear velocity {} in world", AXES[k]), "m/s"),
        (JointKind::Free, false) => (format!(", angular velocity {} in the body frame", AXES[k - 3]), "rad/s"),
    };
    (format!("{} joint '{}'{component}", joint.kind.name(), joint.name), unit)
}

/// The description of `variable` in `modelDescription.xml`, naming the
/// joint and the unit. ν and ε are in √J = √kg·m/s and √kg·m/s² since K = ½|ν|².
pub fn description(model: &Model, variable: RealVariable) -> String {
    const MOMENTUM: [&str; 6] = [
        "angular momentum x about the world origin (kg*m^2/s)",
        "angular momentum y about the world origin (kg*m^2/s)",
        "angular momentum z about the world origin (kg*m^2/s)",
        "linear momentum x (kg*m/s)",
        "linear momentum y (kg*m/s)",
        "linear momentum z (kg*m/s)",
    ];
    match variable {
        RealVariable::Tolerance => format!(
            "error allowed per second of simulated time, relative to 1 + |value|, for the adaptive methods \
             (ros34pw2: 1/{} of it per internal step); \
             a tolerance passed at the start of the experiment (fmi2SetupExperiment, fmi3EnterInitializationMode) \
             replaces it (1)",
            (1.0 / nudyn::integrate::ROS34PW2_SHARE).round()
        ),
        RealVariable::MaxStep => format!(
            "longest internal integration step (s); 0: none for the adaptive methods dopri5, dop853, ros34pw2, bs3 and tsit5 \
             (the error control and the communication step decide), {} s for rk4",
            nudyn::integrate::DEFAULT_FIXED_STEP
        ),
        RealVariable::Eps(k) => {
            format!("diagonalized force eps of dof {} of {} (sqrt(kg)*m/s^2)", k + 1, joint_entry(model, k, false).0)
        }
        RealVariable::Ctrl(k) => control_description(model, k),
        RealVariable::XfrcApplied(k) => {
            const COMPONENTS: [&str; 6] =
                ["force x (N)", "force y (N)", "force z (N)", "torque x (N*m)", "torque y (N*m)", "torque z (N*m)"];
            format!(
                "external wrench on body '{}' (MuJoCo's xfrc_applied), world axes, at its centre of mass: {}",
                model.wrench_bodies[k / 6],
                COMPONENTS[k % 6]
            )
        }
        RealVariable::Theta(k) => {
            let (joint, unit) = joint_entry(model, k, true);
            format!("qpos of {joint} ({unit})")
        }
        RealVariable::Nu(k) => {
            format!("diagonalized velocity nu of dof {} of {} (sqrt(kg)*m/s)", k + 1, joint_entry(model, k, false).0)
        }
        RealVariable::Sensordata(k) => sensor_description(model, k),
        RealVariable::Qvel(k) => {
            let (joint, unit) = joint_entry(model, k, false);
            format!("qvel of {joint} ({unit})")
        }
        RealVariable::KineticEnergy => "kinetic energy 1/2 |nu|^2 (J)".into(),
        RealVariable::Power => "power of the applied eps, nu . eps (W)".into(),
        RealVariable::Momentum(k) => format!("spatial momentum of the vehicle, world axes: {}", MOMENTUM[k]),
        RealVariable::EnergyResidual => {
            "energy residual K - K(start) - integral of nu . nu_dot dt, the integration's energy error (J)".into()
        }
        RealVariable::QfrcConstraint(k) => {
            let (joint, unit) = joint_entry(model, k, false);
            let force_unit = if unit.contains("rad") { "N*m" } else { "N" };
            format!("constraint force (MuJoCo's qfrc_constraint) on {joint} ({force_unit})")
        }
        RealVariable::DerTheta(k) => {
            let (joint, unit) = joint_entry(model, k, true);
            format!("time derivative of the qpos of {joint} ({unit}/s)")
        }
        RealVariable::DerNu(k) => {
            format!("nu_dot of dof {} of {} (sqrt(kg)*m/s^2)", k + 1, joint_entry(model, k, false).0)
        }
    }
}

/// The description of `ctrl[k+1]`: the actuator, its transmission, gear
/// and limits, as MuJoCo applies them (the unit is the actuator's own: a
/// force for a motor, a length for a position servo).
fn control_description(model: &Model, k: usize) -> String {
    let actuator = &model.actuators[k];
    let target = &actuator.target;
    let mut text =
        format!("control (MuJoCo's ctrl) of actuator {}: {} '{}'", actuator.label(k), target.attribute, target.name);
    if let Some(refsite) = &target.refsite {
        text += &format!(" relative to site '{refsite}'");
    }
    let gear: Vec<String> = actuator.gear.iter().map(|g| g.to_string()).collect();
    text += &format!(", gear ({})", gear.join(", "));
    match actuator.ctrl_range {
        Some([low, high]) if model.actuation.clamp_ctrl => text += &format!(", clamped to ctrlrange [{low}, {high}]"),
        _ => {}
    }
    if let Some([low, high]) = actuator.force_range {
        text += &format!(", force clamped to forcerange [{low}, {high}]");
    }
    if !model.actuation.enabled {
        text += "; inactive: the file disables actuation";
    } else if !actuator.enabled {
        text += "; inactive: the file disables its group";
    }
    text
}

/// The description of `sensordata[k+1]`: the sensor, what it measures, the
/// component and the unit.
fn sensor_description(model: &Model, k: usize) -> String {
    use SensorKind::*;
    let (index, sensor) = model
        .sensors
        .iter()
        .enumerate()
        .find(|(_, s)| s.adr <= k && k < s.adr + s.dim())
        .expect("every sensordata entry belongs to a sensor");
    let j = k - sensor.adr;
    let component = match sensor.dim() {
        1 => String::new(),
        4 => format!(", quaternion {}", ["w", "x", "y", "z"][j]),
        _ => format!(", {}", ["x", "y", "z"][j]),
    };
    let joint_is_slide = || match sensor.source {
        SensorSource::Joint { dof, .. } => {
            model.joints.iter().any(|joint| joint.dof_adr == dof && joint.kind == JointKind::Slide)
        }
        _ => false,
    };
    let (meaning, unit) = match sensor.kind {
        JointPos if joint_is_slide() => ("position", "m"),
        JointPos => ("angle", "rad"),
        JointVel if joint_is_slide() => ("velocity", "m/s"),
        JointVel => ("angular velocity", "rad/s"),
        BallQuat => ("orientation", "1"),
        BallAngVel => ("angular velocity in the child body frame", "rad/s"),
        FramePos => ("position", "m"),
        FrameQuat => ("orientation", "1"),
        FrameXAxis => ("x axis", "1"),
        FrameYAxis => ("y axis", "1"),
        FrameZAxis => ("z axis", "1"),
        FrameLinVel => ("linear velocity", "m/s"),
        FrameAngVel => ("angular velocity", "rad/s"),
        FrameLinAcc => ("linear acceleration minus gravity, world axes", "m/s^2"),
        FrameAngAcc => ("angular acceleration, world axes", "rad/s^2"),
        SubtreeCom => ("centre of mass, world axes", "m"),
        SubtreeLinVel => ("velocity of the centre of mass, world axes", "m/s"),
        SubtreeAngMom => ("angular momentum about its centre of mass, world axes", "kg*m^2/s"),
        Gyro => ("angular velocity in the site frame", "rad/s"),
        Velocimeter => ("linear velocity in the site frame", "m/s"),
        Magnetometer => ("magnetic field in the site frame", "T"),
        Accelerometer => ("linear acceleration minus gravity in the site frame", "m/s^2"),
        Force => ("interaction force with the parent (site axes)", "N"),
        Torque => ("interaction torque with the parent about the site (site axes)", "N*m"),
        ActuatorFrc => ("force", "N or N*m: the actuator's own, before gear"),
        JointActuatorFrc if joint_is_slide() => ("total actuator force", "N"),
        JointActuatorFrc => ("total actuator torque", "N*m"),
        JointLimitPos if joint_is_slide() => ("distance to the active limit less its margin (0: none active)", "m"),
        JointLimitPos => ("distance to the active limit less its margin (0: none active)", "rad"),
        JointLimitVel if joint_is_slide() => ("velocity of the active limit row (0: none active)", "m/s"),
        JointLimitVel => ("velocity of the active limit row (0: none active)", "rad/s"),
        JointLimitFrc if joint_is_slide() => ("force of the active limit row (0: none active)", "N"),
        JointLimitFrc => ("torque of the active limit row (0: none active)", "N*m"),
        TendonPos => ("length", "m, or rad for a fixed tendon of hinges"),
        TendonVel => ("velocity", "m/s, or rad/s for a fixed tendon of hinges"),
        TendonActuatorFrc => ("total force of its actuators, before gear", "N"),
        TendonLimitPos => ("distance to the active limit less its margin (0: none active)", "m"),
        TendonLimitVel => ("velocity of the active limit row (0: none active)", "m/s"),
        TendonLimitFrc => ("force of the active limit row (0: none active)", "N"),
        ActuatorPos => ("length", "m or rad times gear"),
        ActuatorVel => ("velocity", "m/s or rad/s times gear"),
        Clock => ("simulation time", "s"),
    };
    let frame = match (&sensor.source, sensor.kind) {
        (SensorSource::Frame { reference: None, .. }, FramePos | FrameQuat | FrameXAxis | FrameYAxis | FrameZAxis)
        | (SensorSource::Frame { reference: None, .. }, FrameLinVel | FrameAngVel) => ", world axes",
        _ => "",
    };
    let cutoff = if sensor.cutoff > 0.0 { format!(", clamped to +-{}", sensor.cutoff) } else { String::new() };
    format!("sensor {}: {meaning} of {}{frame}{component}{cutoff} ({unit})", sensor.label(index), sensor.target)
}

/// What the plant's modelDescription says of the FMU as a whole.
fn header(model: &Model, options: &ExportOptions, guid: &str) -> Header {
    Header {
        model_name: if model.name.is_empty() { options.model_identifier.clone() } else { model.name.clone() },
        guid: guid.to_string(),
        description: match model.constraints.summary() {
            None => format!(
                "diagonalized dynamics of the vehicle '{}' (nq = {}, nv = {}): nu' + C(theta, nu) = eps",
                model.name, model.nq, model.nv
            ),
            Some(constraints) => format!(
                "diagonalized dynamics of the vehicle '{}' (nq = {}, nv = {}): nu' + C(theta, nu) = eps + eps_c; {}",
                model.name, model.nq, model.nv, constraints
            ),
        },
        model_identifier: options.model_identifier.clone(),
        capabilities: capabilities(options.outputs),
        event_indicators: model.constraints.switch_count(),
        generated: generation_date_and_time(),
    }
}

const METHOD_DESCRIPTION: &str = "integration method";

const ENERGY_PROJECTION_DESCRIPTION: &str = "rescale nu after each internal step so that the kinetic energy follows \
     the work done (keeps K exactly when no force acts)";

/// The item description of `method` in the enumeration type.
fn method_item_description(method: MethodSetting) -> String {
    format!("{} (Munthe-Kaas on rotations)", method.description())
}

/// The typed FMI 3.0 modelDescription of the plant FMU (not yet validated).
pub fn model_description3(resource: &PlantResource, options: &ExportOptions, guid: &str) -> md3::Fmi3ModelDescription {
    let model = &resource.model;
    let layout = resource.layout();
    let table = resource.fmi3_variables();
    let method_type = md3::EnumerationType {
        name: METHOD_TYPE.into(),
        description: Some(METHOD_DESCRIPTION.into()),
        items: MethodSetting::ALL
            .iter()
            .map(|&method| md3::Item {
                name: method.name().into(),
                value: i64::from(method_value(method)),
                description: Some(method_item_description(method)),
            })
            .collect(),
    };
    let vr = |name: &str| table.value_reference(name).expect("the plant's table has it");
    let method = md3::Variable::Enumeration(md3::Enumeration {
        name: METHOD_NAME.into(),
        value_reference: vr(METHOD_NAME),
        description: Some(METHOD_DESCRIPTION.into()),
        causality: "parameter".into(),
        variability: "fixed".into(),
        initial: Some("exact".into()),
        declared_type: METHOD_TYPE.into(),
        start: Some(i64::from(method_value(resource.method))),
    });
    let energy_projection = md3::Variable::Boolean(md3::Boolean {
        name: ENERGY_PROJECTION_NAME.into(),
        value_reference: vr(ENERGY_PROJECTION_NAME),
        description: Some(ENERGY_PROJECTION_DESCRIPTION.into()),
        causality: "parameter".into(),
        variability: "fixed".into(),
        initial: Some("exact".into()),
        start: Some(false),
    });
    let others = fmi3::Others { enumeration_types: vec![method_type], variables: vec![method, energy_projection] };
    let real = |vr: u32| {
        let variable = layout.real_variable(vr).expect("the table's Reals are the layout's");
        fmi3::RealScalar {
            kind: variable.kind(),
            start: resource.start(variable),
            description: description(model, variable),
        }
    };
    let dependencies = |vr| layout.dependency_vrs(vr);
    fmi3::model_description(header(model, options, guid), &table, real, dependencies, others)
}

/// The typed modelDescription of the plant FMU (not yet validated).
pub fn model_description(resource: &PlantResource, options: &ExportOptions, guid: &str) -> md::FmiModelDescription {
    let model = &resource.model;
    let layout = Layout::new(model, options.outputs);
    let method = md::ScalarVariable {
        name: METHOD_NAME.into(),
        value_reference: METHOD_VR,
        description: Some(METHOD_DESCRIPTION.into()),
        causality: md::Causality::Parameter,
        variability: md::Variability::Fixed,
        initial: Some(md::Initial::Exact),
        can_handle_multiple_set_per_time_instant: None,
        kind: md::VariableKind::Enumeration(md::EnumerationVariable {
            declared_type: METHOD_TYPE.into(),
            quantity: None,
            min: None,
            max: None,
            start: Some(method_value(resource.method)),
        }),
    };
    let energy_projection = md::ScalarVariable {
        name: ENERGY_PROJECTION_NAME.into(),
        value_reference: ENERGY_PROJECTION_VR,
        description: Some(ENERGY_PROJECTION_DESCRIPTION.into()),
        causality: md::Causality::Parameter,
        variability: md::Variability::Fixed,
        initial: Some(md::Initial::Exact),
        can_handle_multiple_set_per_time_instant: None,
        kind: md::VariableKind::Boolean(md::BooleanVariable { start: Some(false), ..Default::default() }),
    };
    let reals: Vec<(u32, RealVariable)> = layout.real_variables().collect();
    // 1-based ScalarVariable indices, as <ModelStructure> and `derivative` refer to them: the
    // Reals' value references run from 1 in ScalarVariable order, after method and energy_projection.
    let index_of = |variable: RealVariable| 2 + layout.value_reference(variable).expect("the variable is listed");
    let state_of = |variable: RealVariable| match variable {
        RealVariable::DerTheta(k) => Some(index_of(RealVariable::Theta(k))),
        RealVariable::DerNu(k) => Some(index_of(RealVariable::Nu(k))),
        _ => None,
    };
    let name = |variable: RealVariable| layout.name(variable).expect("a variable of the layout");
    let scalar_variables = reals.iter().map(|&(vr, variable)| {
        let mut scalar =
            real_variable(name(variable), vr, description(model, variable), variable.kind(), resource.start(variable));
        if let md::VariableKind::Real(real) = &mut scalar.kind {
            real.derivative = state_of(variable);
        }
        scalar
    });
    let model_variables: Vec<md::ScalarVariable> =
        [method, energy_projection].into_iter().chain(scalar_variables).collect();

    let mut outputs = Vec::new();
    let mut derivatives = Vec::new();
    let mut initial_unknowns = Vec::new();
    for &(_, variable) in &reals {
        let kind = variable.kind();
        let unknown = md::Unknown {
            index: index_of(variable),
            dependencies: layout.dependencies(variable).map(|knowns| {
                let mut indices: Vec<u32> = knowns.into_iter().map(index_of).collect();
                indices.sort_unstable();
                indices
            }),
            dependencies_kind: None,
        };
        if kind.causality == nudyn_contract::variable::Causality::Output {
            outputs.push(unknown);
        } else if variable.is_derivative() {
            derivatives.push(unknown);
        } else {
            continue;
        }
        if !kind.exact_start {
            // Calculated outputs and the derivatives are initial unknowns;
            // they may depend on every exact start value and input.
            initial_unknowns.push(md::Unknown::new(index_of(variable)));
        }
    }

    let method_type = md::SimpleType {
        name: METHOD_TYPE.into(),
        description: Some(METHOD_DESCRIPTION.into()),
        kind: md::SimpleTypeKind::Enumeration(md::EnumerationType {
            quantity: None,
            items: MethodSetting::ALL
                .iter()
                .map(|&method| md::Item {
                    name: method.name().into(),
                    value: method_value(method),
                    description: Some(method_item_description(method)),
                })
                .collect(),
        }),
    };
    let header = header(model, options, guid);
    let structure = md::ModelStructure { outputs, derivatives, initial_unknowns };
    header.into_model_description(vec![method_type], model_variables, structure)
}

/// Writes the plant FMU `out` of `model`: modelDescription.xml (validated
/// first), the `nudyn_fmu` cdylib built for each platform of `binaries`
/// (e.g. `binaries/linux64/<modelIdentifier>.so`), `resources/model.json`
/// and `documentation/index.html`.
pub fn write_fmu(
    model: &Model,
    options: &ExportOptions,
    binaries: &[PlatformBinary],
    out: &Path,
) -> Result<(), ExportError> {
    write_plant_fmu(&PlantResource::new(model.clone(), options.outputs), options, binaries, out)
}

/// Writes the plant FMU `out` of `resource` (its model, optional outputs
/// and start values) as [`write_fmu`] does.
pub fn write_plant_fmu(
    resource: &PlantResource,
    options: &ExportOptions,
    binaries: &[PlatformBinary],
    out: &Path,
) -> Result<(), ExportError> {
    write_file(out, &plant_fmu(resource, options, binaries, out)?)
}

/// The bytes of the plant FMU of `resource`, built in memory (`out` names
/// it in messages): for a file of its own or an entry of a system file.
pub fn plant_fmu(
    resource: &PlantResource,
    options: &ExportOptions,
    binaries: &[PlatformBinary],
    out: &Path,
) -> Result<Vec<u8>, ExportError> {
    check_model_identifier(&options.model_identifier)?;
    let bytes = resource.to_json()?;
    let guid = resource.guid(&bytes);
    let description = match options.fmi_version {
        FmiVersion::Fmi2 => Document::Fmi2(model_description(resource, options, &guid)),
        FmiVersion::Fmi3 => Document::Fmi3(model_description3(resource, options, &guid)),
    };
    let documentation = documentation::index_html(&resource.model, &description, "plant");
    fmu_archive::<PlantResource>(&description, &bytes, &documentation, binaries, out)
}
