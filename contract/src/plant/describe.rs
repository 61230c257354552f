//! The descriptions of the plant's variables, per element: each names its
//! joint, actuator, sensor or component and its unit. ν and ε are in
//! √J = √kg·m/s and √kg·m/s² since K = ½|ν|².

use nudyn::model::{Model, SensorSource};
use nudyn::vehicle::{ActivationKind, JointKind, SensorKind};

/// What one coordinate or dof is, for variable descriptions: the joint, its
/// kind, and the component and unit of entry `k` within the joint.
fn joint_entry(model: &Model, index: usize, qpos: bool) -> (String, &'static str) {
    if let Some((mode, flexible)) = model.flexible.iter().find_map(|f| {
        let first = if qpos { f.qpos_adr } else { f.dof_adr };
        (first..first + f.mode_count()).contains(&index).then(|| (index - first, f))
    }) {
        let hertz = flexible.modal.modes[mode].angular_frequency / std::f64::consts::TAU;
        let unit = if qpos { "sqrt(kg)*m" } else { "sqrt(kg)*m/s" };
        return (format!("mode {} ({hertz:.4} Hz) of flexible body '{}'", mode + 1, flexible.modal.body), unit);
    }
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

/// The description of `ctrl[k+1]`: the actuator, its transmission, gear
/// and limits, as MuJoCo applies them (the unit is the actuator's own: a
/// force for a motor, a length for a position servo).
pub(super) fn control(model: &Model, k: usize) -> String {
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
pub(super) fn sensor(model: &Model, k: usize) -> String {
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

pub(super) fn tolerance() -> String {
    format!(
        "error allowed per second of simulated time, relative to 1 + |value|, for the adaptive methods \
         (ros34pw2: 1/{} of it per internal step); \
         a tolerance passed at the start of the experiment (fmi2SetupExperiment, fmi3EnterInitializationMode) \
         replaces it (1)",
        (1.0 / nudyn::integrate::ROS34PW2_SHARE).round()
    )
}

pub(super) fn max_step() -> String {
    format!(
        "longest internal integration step (s); 0: none for the adaptive methods dopri5, dop853, ros34pw2, bs3 and tsit5 \
         (the error control and the communication step decide), {} s for rk4",
        nudyn::integrate::DEFAULT_FIXED_STEP
    )
}

pub(super) fn eps(model: &Model, k: usize) -> String {
    format!("diagonalized force eps of dof {} of {} (sqrt(kg)*m/s^2)", k + 1, joint_entry(model, k, false).0)
}

pub(super) fn wrench(model: &Model, k: usize) -> String {
    const COMPONENTS: [&str; 6] =
        ["force x (N)", "force y (N)", "force z (N)", "torque x (N*m)", "torque y (N*m)", "torque z (N*m)"];
    format!(
        "external wrench on body '{}' (MuJoCo's xfrc_applied), world axes, at its centre of mass: {}",
        model.wrench_bodies[k / 6],
        COMPONENTS[k % 6]
    )
}

pub(super) fn theta(model: &Model, k: usize) -> String {
    let (joint, unit) = joint_entry(model, k, true);
    format!("qpos of {joint} ({unit})")
}

pub(super) fn nu(model: &Model, k: usize) -> String {
    format!("diagonalized velocity nu of dof {} of {} (sqrt(kg)*m/s)", k + 1, joint_entry(model, k, false).0)
}

pub(super) fn qvel(model: &Model, k: usize) -> String {
    let (joint, unit) = joint_entry(model, k, false);
    format!("qvel of {joint} ({unit})")
}

pub(super) fn momentum(_: &Model, k: usize) -> String {
    const MOMENTUM: [&str; 6] = [
        "angular momentum x about the world origin (kg*m^2/s)",
        "angular momentum y about the world origin (kg*m^2/s)",
        "angular momentum z about the world origin (kg*m^2/s)",
        "linear momentum x (kg*m/s)",
        "linear momentum y (kg*m/s)",
        "linear momentum z (kg*m/s)",
    ];
    format!("spatial momentum of the vehicle, world axes: {}", MOMENTUM[k])
}

pub(super) fn qfrc_constraint(model: &Model, k: usize) -> String {
    let (joint, unit) = joint_entry(model, k, false);
    let force_unit = if unit.contains("rad") { "N*m" } else { "N" };
    format!("constraint force (MuJoCo's qfrc_constraint) on {joint} ({force_unit})")
}

pub(super) fn der_theta(model: &Model, k: usize) -> String {
    let (joint, unit) = joint_entry(model, k, true);
    format!("time derivative of the qpos of {joint} ({unit}/s)")
}

pub(super) fn der_nu(model: &Model, k: usize) -> String {
    format!("nu_dot of dof {} of {} (sqrt(kg)*m/s^2)", k + 1, joint_entry(model, k, false).0)
}

/// The actuator that owns activation state k, with its dynamics, range
/// and look-ahead.
fn activation_owner(model: &Model, k: usize) -> String {
    let (index, actuator) = model
        .actuators
        .iter()
        .enumerate()
        .filter(|(_, a)| a.activation.is_some())
        .nth(k)
        .expect("one actuator per activation state");
    let activation = actuator.activation.expect("filtered");
    let dynamics = match activation.kind {
        ActivationKind::Integrator => "an integrator of ctrl".to_string(),
        ActivationKind::Filter | ActivationKind::FilterExact => {
            format!("a filter of ctrl with time constant {} s", activation.time_constant)
        }
    };
    let mut text = format!("actuator {} (ctrl[{}]), {dynamics}", actuator.label(index), index + 1);
    if let Some([low, high]) = activation.range {
        text += &format!(", within actrange [{low}, {high}]");
    }
    if activation.early {
        text += ", its force reading act one timestep ahead (actearly)";
    }
    text
}

pub(super) fn act(model: &Model, k: usize) -> String {
    format!("activation state (MuJoCo's act) of {}", activation_owner(model, k))
}

pub(super) fn der_act(model: &Model, k: usize) -> String {
    format!(
        "time derivative of the activation state (MuJoCo's act_dot, 0 at a bound it would leave) of {}",
        activation_owner(model, k)
    )
}

/// Event indicator k: the limit sides first (two per limited joint, then
/// per limited tendon), then per constraint row slot its force's working
/// set and then its impedance piece (crate::dynamics::mode).
pub(super) fn constraint_switch(model: &Model, k: usize) -> String {
    const SIDES: [&str; 2] = ["lower", "upper"];
    let constraints = &model.constraints;
    let (joint_sides, limit_sides, rows) =
        (2 * constraints.limits.len(), constraints.limit_sides(), constraints.max_rows());
    let what = if k < joint_sides {
        let limit = &constraints.limits[k / 2];
        let joint = &model.joints[limit.joint].name;
        match (limit.kind, k % 2) {
            (JointKind::Ball, 0) => format!("limit of ball joint '{joint}' switching on or off"),
            (JointKind::Ball, _) => format!("second side of ball joint '{joint}', which has none (never switches)"),
            (_, side) => format!("{} side of the limit of joint '{joint}' switching on or off", SIDES[side]),
        }
    } else if k < limit_sides {
        let j = k - joint_sides;
        let tendon = constraints.tendon_limits[j / 2].tendon;
        format!(
            "{} side of the limit of tendon {} switching on or off",
            SIDES[j % 2],
            model.tendons[tendon].label(tendon)
        )
    } else if k < limit_sides + rows {
        format!("force of constraint row {} reaching or leaving a bound", k - limit_sides + 1)
    } else {
        format!("impedance of constraint row {} changing piece", k - limit_sides - rows + 1)
    };
    format!(
        "event indicator (model exchange): margin of the {what}, held since the last event; \
         crosses zero where the constraint forces switch (1: the row is not there)"
    )
}
