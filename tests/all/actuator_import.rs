//! The importer's actuators and sites against MuJoCo 4.0's documented rules:
//! the fixtures under `tests/fixtures/actuators/` read into the general
//! actuators the XML reference's shortcut tables give, default classes as
//! its Modeling chapter says, and every refused or malformed actuator named
//! with its element and line. (tests/python/test_actuators.py checks the
//! same fixtures against MuJoCo itself.)

use std::f64::consts::PI;
use std::path::PathBuf;

use nudyn::mjcf::{Imported, MjcfError, load_mjcf, parse_mjcf};
use nudyn::model::{Model, ModelError};
use nudyn::vehicle::{Actuator, ActuatorKind, BiasType, GainType, Transmission, Vehicle};

fn load(name: &str) -> Imported {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/actuators").join(name);
    load_mjcf(&path).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn actuator<'a>(vehicle: &'a Vehicle, name: &str) -> &'a Actuator {
    vehicle.actuators.iter().find(|a| a.name.as_deref() == Some(name)).unwrap_or_else(|| panic!("no actuator {name}"))
}

/// The gain and bias laws: (gain type, gainprm[0..3], bias type, biasprm[0..3]).
fn law(a: &Actuator) -> (GainType, [f64; 3], BiasType, [f64; 3]) {
    (a.gain_type, a.gain, a.bias_type, a.bias)
}

fn joint(name: &str, in_parent: bool) -> Transmission {
    Transmission::Joint { joint: name.to_string(), in_parent }
}

fn site_index(vehicle: &Vehicle, name: &str) -> usize {
    vehicle.sites.iter().position(|s| s.name.as_deref() == Some(name)).unwrap()
}

#[test]
fn every_kind_reads_into_its_general_actuator() {
    let Imported { vehicle, .. } = load("kinds.xml");
    assert_eq!(vehicle.actuators.len(), 20);
    let (fixed, affine) = (GainType::Fixed, GainType::Affine);
    let (none, biased) = (BiasType::None, BiasType::Affine);

    let thrust = actuator(&vehicle, "thrust");
    assert_eq!(thrust.kind, ActuatorKind::Motor);
    let thruster = site_index(&vehicle, "thruster");
    assert_eq!(thrust.transmission, Transmission::Site { site: thruster, refsite: None });
    assert_eq!(thrust.gear, [0.0, 0.0, -1.0, 0.0, 0.0, 0.0]);
    assert_eq!(law(thrust), (fixed, [1.0, 0.0, 0.0], none, [0.0; 3]));
    assert_eq!((thrust.ctrl_range, thrust.force_range), (Some([0.0, 2.0]), None));

    let wheel = actuator(&vehicle, "wheel");
    assert_eq!((wheel.transmission.clone(), wheel.gear[0]), (joint("wheel_spin", false), 3.0));
    assert_eq!((wheel.ctrl_range, wheel.force_range), (None, Some([-0.5, 0.5])));

    // damper: gain (0, 0, −kv), no bias, ctrl always limited.
    let brake = actuator(&vehicle, "wheel_brake");
    assert_eq!(law(brake), (affine, [0.0, 0.0, -0.7], none, [0.0; 3]));
    assert_eq!(brake.ctrl_range, Some([0.0, 1.5]));

    // position: gain kp, bias (0, −kp, −kv), a damping ratio kept positive
    // for the compiler; inheritrange 0.9 of the joint's −80°..100°.
    let servo = actuator(&vehicle, "shoulder_servo");
    assert_eq!(law(servo), (fixed, [40.0, 0.0, 0.0], biased, [0.0, -40.0, 0.8]));
    let [low, high] = servo.ctrl_range.unwrap();
    let (mean, radius) = (10.0 * PI / 180.0, 0.9 * 90.0 * PI / 180.0);
    assert!((low - (mean - radius)).abs() < 1e-15 && (high - (mean + radius)).abs() < 1e-15, "{low} {high}");

    // velocity: gain kv, bias (0, 0, −kv).
    let rate = actuator(&vehicle, "shoulder_rate");
    assert_eq!(law(rate), (fixed, [5.0, 0.0, 0.0], biased, [0.0, 0.0, -5.0]));
    assert_eq!(rate.ctrl_range, Some([-1.0, 1.0]));

    let general = actuator(&vehicle, "shoulder_affine");
    assert_eq!(law(general), (affine, [1.0, 0.5, -0.3], biased, [0.2, -1.0, 0.1]));
    assert_eq!((general.gear[0], general.force_range), (1.5, Some([-2.0, 3.0])));

    assert_eq!(actuator(&vehicle, "wrist_torque").transmission, joint("wrist", false));
    assert_eq!(actuator(&vehicle, "wrist_parent").transmission, joint("wrist", true));
    assert_eq!(actuator(&vehicle, "bus_parent").transmission, joint("bus_free", true));
    assert_eq!(actuator(&vehicle, "bus_parent").gear, [-0.4, 0.3, 1.0, 0.5, -0.6, 0.2]);
    assert_eq!(actuator(&vehicle, "slide_rate").transmission, joint("slide", true));

    let reach = actuator(&vehicle, "reach");
    let (tip, elbow) = (site_index(&vehicle, "tool_tip"), site_index(&vehicle, "elbow_site"));
    assert_eq!(reach.transmission, Transmission::Site { site: tip, refsite: Some(elbow) });
    assert_eq!(vehicle.sites[site_index(&vehicle, "origin")].body, None, "a site of the world body");

    // ctrllimited="false" wins over a range; "auto" with a decreasing range is no limit.
    assert_eq!(actuator(&vehicle, "slide").ctrl_range, None);
    assert_eq!(vehicle.actuators[18].name, None);
    assert_eq!(vehicle.actuators[18].ctrl_range, None);
    // The joint's limit on the total actuator force.
    let shoulder = vehicle.bodies.iter().flat_map(|b| &b.joints).find(|j| j.name == "shoulder").unwrap();
    assert_eq!(shoulder.actuator_force_range, Some([-6.0, 6.0]));
}

#[test]
fn defaults_follow_mujoco_4_rules() {
    let Imported { vehicle, .. } = load("defaults.xml");
    let (fixed, none, biased) = (GainType::Fixed, BiasType::None, BiasType::Affine);
    // Thrusters: gear and ctrlrange from the class; a partial gear keeps the rest.
    let [aft, fore] = [&vehicle.actuators[0], &vehicle.actuators[1]];
    assert_eq!((aft.gear, aft.ctrl_range), ([0.0, 0.0, -1.0, 0.0, 0.0, 0.0], Some([0.0, 5.0])));
    assert_eq!(fore.gear, [0.0, 1.0, -1.0, 0.0, 0.0, 0.0]);
    // Sites: the class "thruster" places "aft", "fore" asks for "main".
    let [aft_site, fore_site] = [&vehicle.sites[0], &vehicle.sites[1]];
    assert_eq!((aft_site.pos.x, fore_site.pos.z), (0.3, 0.1));
    let down = aft_site.quat * nalgebra::Vector3::z();
    assert!((down - nalgebra::Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-15, "zaxis from the class: {down}");

    // In its class a position default makes position servos, and general
    // takes it raw; a motor stays a motor with the class's ctrlrange and gear.
    assert_eq!(law(actuator(&vehicle, "p1")), (fixed, [10.0, 0.0, 0.0], biased, [0.0, -10.0, -2.0]));
    let m1 = actuator(&vehicle, "m1");
    assert_eq!(
        (law(m1), m1.ctrl_range, m1.gear[0]),
        ((fixed, [1.0, 0.0, 0.0], none, [0.0; 3]), Some([-1.0, 1.0]), 2.0)
    );
    assert_eq!(law(actuator(&vehicle, "g1")), law(actuator(&vehicle, "p1")));
    // The child class's velocity default gives velocity its kv; position takes
    // kp from the parent's position default (and kv from the element).
    assert_eq!(law(actuator(&vehicle, "v2")), (fixed, [3.0, 0.0, 0.0], biased, [0.0, 0.0, -3.0]));
    assert_eq!(law(actuator(&vehicle, "p2")), (fixed, [10.0, 0.0, 0.0], biased, [0.0, -10.0, -0.5]));
    assert_eq!(law(actuator(&vehicle, "g2")), law(actuator(&vehicle, "v2")));
    // A fixed-gain general default lends position its raw parameters and
    // velocity its gain; motor ignores it.
    assert_eq!(law(actuator(&vehicle, "p3")), (fixed, [400.0, 0.0, 0.0], biased, [0.0, -400.0, -7.0]));
    assert_eq!(law(actuator(&vehicle, "v3")), (fixed, [400.0, 0.0, 0.0], biased, [0.0, 0.0, -400.0]));
    assert_eq!(law(actuator(&vehicle, "m3")), (fixed, [1.0, 0.0, 0.0], none, [0.0; 3]));
    assert_eq!(actuator(&vehicle, "m3").force_range, Some([-50.0, 50.0]));
    assert_eq!(actuator(&vehicle, "d4").gain, [0.0, 0.0, -4.0]);
    assert_eq!(
        (actuator(&vehicle, "d5").gain, actuator(&vehicle, "d5").ctrl_range),
        ([0.0, 0.0, -1.0], Some([0.0, 2.0]))
    );
}

#[test]
fn options_switch_clamping_groups_and_actuation() {
    let Imported { vehicle, .. } = load("switches.xml");
    assert!(vehicle.actuation.enabled && !vehicle.actuation.clamp_ctrl);
    let disabled: Vec<bool> = vehicle.actuators.iter().map(|a| a.group_disabled).collect();
    assert_eq!(disabled, [false, true, true, false, false]);
    // autolimits off: limits only where *limited says so.
    assert_eq!(actuator(&vehicle, "unclamped").ctrl_range, Some([-0.5, 0.5]));
    assert_eq!(actuator(&vehicle, "off_but_clamped").force_range, Some([0.25, 1.0]));
    let Imported { vehicle, .. } = load("no_actuation.xml");
    assert!(!vehicle.actuation.enabled);
}

#[test]
fn dampratio_is_the_damping_of_the_reflected_inertia() {
    // A rod on a hinge about its end: I = m l²/3 about the hinge, gear g
    // reflects I/g²; kv = 2 ζ √(kp I / g²).
    let xml = r#"<mujoco><option gravity="0 0 0"/><worldbody><body>
        <joint name="h" axis="0 1 0" armature="0.25"/>
        <inertial pos="0.5 0 0" mass="3" diaginertia="0.001 0.001 0.001"/>
      </body></worldbody>
      <actuator><position joint="h" kp="40" dampratio="0.7" gear="2"/></actuator></mujoco>"#;
    let model = Model::compile(&parse_mjcf(xml).unwrap().vehicle).unwrap();
    let inertia = 0.001 + 3.0 * 0.5 * 0.5 + 0.25;
    let kv = 2.0 * 0.7 * (40.0 * inertia / 4.0_f64).sqrt();
    assert!((model.actuators[0].bias[2] + kv).abs() < 1e-14, "{} vs {}", model.actuators[0].bias[2], -kv);

    let negative = xml.replace(r#"kp="40""#, r#"kp="-40""#);
    let error = Model::compile(&parse_mjcf(&negative).unwrap().vehicle).unwrap_err();
    assert!(matches!(error, ModelError::Actuator { line: 5, .. }), "{error:?}");
    assert_eq!(error.to_string(), "position 0 (line 5): dampratio needs kp >= 0, found kp = -40");
}

/// An actuator file that must be refused: which variant, element and line.
struct Refused {
    what: &'static str,
    actuators: &'static str,
    variant: fn(&MjcfError) -> bool,
    element: &'static str,
    reason: &'static str,
}

fn unsupported(e: &MjcfError) -> bool {
    matches!(e, MjcfError::Unsupported { .. })
}

fn invalid(e: &MjcfError) -> bool {
    matches!(e, MjcfError::Invalid { .. })
}

#[rustfmt::skip]
const REFUSED: &[Refused] = &[
    Refused { what: "muscle", variant: unsupported, element: "<muscle>", reason: "muscle",
        actuators: r#"<muscle joint="h"/>"# },
    Refused { what: "adhesion", variant: unsupported, element: "<adhesion>", reason: "contacts",
        actuators: r#"<adhesion body="b"/>"# },
    Refused { what: "pid", variant: unsupported, element: "<pid>", reason: "pid",
        actuators: r#"<pid joint="h"/>"# },
    Refused { what: "orientation", variant: unsupported, element: "<orientation>", reason: "orientation",
        actuators: r#"<orientation joint="b"/>"# },
    Refused { what: "dcmotor", variant: unsupported, element: "<dcmotor>", reason: "dcmotor",
        actuators: r#"<dcmotor joint="h"/>"# },
    Refused { what: "plugin", variant: unsupported, element: "<plugin>", reason: "plugins",
        actuators: r#"<plugin joint="h" plugin="p"/>"# },
    Refused { what: "unknown tendon", variant: invalid, element: "<motor>", reason: "unknown tendon 't'",
        actuators: r#"<motor tendon="t"/>"# },
    Refused { what: "slider-crank", variant: unsupported, element: "<motor>", reason: "slider-crank",
        actuators: r#"<motor cranksite="s" slidersite="s" cranklength="1"/>"# },
    Refused { what: "body transmission", variant: unsupported, element: "<general>", reason: "contacts",
        actuators: r#"<general body="b"/>"# },
    Refused { what: "muscle dynamics", variant: unsupported, element: "<general name=\"f\">", reason: "dyntype \"muscle\"",
        actuators: r#"<general name="f" joint="h" dyntype="muscle"/>"# },
    Refused { what: "user dynamics", variant: unsupported, element: "<general>", reason: "dyntype \"user\"",
        actuators: r#"<general joint="h" dyntype="user"/>"# },
    Refused { what: "actdim 0 with activation", variant: invalid, element: "<general>", reason: "actdim 0",
        actuators: r#"<general joint="h" dyntype="filter" actdim="0"/>"# },
    Refused { what: "muscle gain", variant: unsupported, element: "<general>", reason: "gaintype \"muscle\"",
        actuators: r#"<general joint="h" gaintype="muscle"/>"# },
    Refused { what: "user bias", variant: unsupported, element: "<general>", reason: "biastype \"user\"",
        actuators: r#"<general joint="h" biastype="user"/>"# },
    Refused { what: "delay", variant: unsupported, element: "<motor>", reason: "ctrl history",
        actuators: r#"<motor joint="h" delay="0.01" nsample="2"/>"# },
    Refused { what: "actuator armature", variant: unsupported, element: "<motor>", reason: "armature",
        actuators: r#"<motor joint="h" armature="0.1"/>"# },
    Refused { what: "actuator damping", variant: unsupported, element: "<velocity>", reason: "damping",
        actuators: r#"<velocity joint="h" damping="0.1"/>"# },
    Refused { what: "site fitted to a mesh", variant: unsupported, element: "<motor>", reason: "mesh",
        actuators: r#"<motor site="fitted"/>"# },
    Refused { what: "no target", variant: invalid, element: "<motor name=\"lost\">", reason: "missing transmission target",
        actuators: r#"<motor name="lost"/>"# },
    Refused { what: "two targets", variant: |e| matches!(e, MjcfError::ConflictingAttributes { .. }), element: "<motor>", reason: "'joint' and 'site'",
        actuators: r#"<motor joint="h" site="s"/>"# },
    Refused { what: "unknown joint", variant: invalid, element: "<motor>", reason: "unknown transmission target 'elbow'",
        actuators: r#"<motor joint="elbow"/>"# },
    Refused { what: "unknown refsite", variant: invalid, element: "<motor>", reason: "unknown refsite 'nowhere'",
        actuators: r#"<motor site="s" refsite="nowhere"/>"# },
    Refused { what: "refsite without a site", variant: invalid, element: "<motor>", reason: "refsite can only be used with site",
        actuators: r#"<motor joint="h" refsite="s"/>"# },
    Refused { what: "duplicate name", variant: |e| matches!(e, MjcfError::DuplicateName { .. }), element: "<velocity name=\"twice\">", reason: "actuator name \"twice\"",
        actuators: "<motor name=\"twice\" joint=\"h\"/>\n<velocity name=\"twice\" joint=\"h\"/>" },
    Refused { what: "kv and dampratio", variant: invalid, element: "<position>", reason: "kv and dampratio",
        actuators: r#"<position joint="h" kv="1" dampratio="1"/>"# },
    Refused { what: "negative kv", variant: invalid, element: "<position>", reason: "kv cannot be negative",
        actuators: r#"<position joint="h" kv="-1"/>"# },
    Refused { what: "negative damper ctrl", variant: invalid, element: "<damper>", reason: "cannot be negative",
        actuators: r#"<damper joint="h" ctrlrange="-1 1"/>"# },
    Refused { what: "damper without ctrlrange", variant: invalid, element: "<damper>", reason: "'ctrlrange'",
        actuators: r#"<damper joint="h" kv="1"/>"# },
    Refused { what: "decreasing limited ctrlrange", variant: invalid, element: "<motor>", reason: "'ctrlrange' 1 -1",
        actuators: r#"<motor joint="h" ctrllimited="true" ctrlrange="1 -1"/>"# },
    Refused { what: "actrange without activation", variant: invalid, element: "<general>", reason: "actrange",
        actuators: r#"<general joint="h" actrange="0 1"/>"# },
    Refused { what: "actdim 1 without activation", variant: invalid, element: "<general>", reason: "actdim 1",
        actuators: r#"<general joint="h" actdim="1"/>"# },
    Refused { what: "inheritrange on a site", variant: invalid, element: "<position>", reason: "inheritrange",
        actuators: r#"<position site="s" inheritrange="1"/>"# },
    Refused { what: "inheritrange of a ball joint", variant: invalid, element: "<position>", reason: "hinge and slide",
        actuators: r#"<position joint="b" inheritrange="1"/>"# },
    Refused { what: "inheritrange without a range", variant: invalid, element: "<position>", reason: "no range",
        actuators: r#"<position joint="free_spin" inheritrange="1"/>"# },
    Refused { what: "ctrlrange and inheritrange", variant: invalid, element: "<position>", reason: "cannot both",
        actuators: r#"<position joint="h" ctrlrange="0 1" inheritrange="1"/>"# },
    Refused { what: "actrange and inheritrange", variant: invalid, element: "<intvelocity>", reason: "actrange and inheritrange cannot both",
        actuators: r#"<intvelocity joint="h" actrange="0 1" inheritrange="1"/>"# },
    Refused { what: "intvelocity kv and dampratio", variant: invalid, element: "<intvelocity>", reason: "kv and dampratio",
        actuators: r#"<intvelocity joint="h" kv="1" dampratio="1"/>"# },
    Refused { what: "intvelocity with a filter", variant: |e| matches!(e, MjcfError::UnknownAttribute { .. }), element: "<intvelocity>", reason: "'timeconst'",
        actuators: r#"<intvelocity joint="h" timeconst="1"/>"# },
    Refused { what: "cylinder bias of two", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<cylinder>", reason: "bias",
        actuators: r#"<cylinder joint="h" bias="1 2"/>"# },
    Refused { what: "inheritrange of a filter", variant: invalid, element: "<general>", reason: "only available for position and intvelocity",
        actuators: r#"<general joint="h" gainprm="2" biastype="affine" biasprm="0 -2 0" dyntype="filter" inheritrange="1"/>"# },
    Refused { what: "unknown attribute", variant: |e| matches!(e, MjcfError::UnknownAttribute { .. }), element: "<motor>", reason: "'kp'",
        actuators: r#"<motor joint="h" kp="1"/>"# },
    Refused { what: "unknown element", variant: |e| matches!(e, MjcfError::UnknownElement { .. }), element: "<servo>", reason: "unknown element",
        actuators: r#"<servo joint="h"/>"# },
];

/// A vehicle with a limited hinge "h", an unlimited hinge "free_spin", a
/// ball "b", sites "s" and "fitted" (on a mesh); the actuator section starts
/// at line 12.
fn vehicle_with(actuators: &str) -> String {
    format!(
        r#"<mujoco>
<asset><mesh name="m" vertex="0 0 0 1 0 0 0 1 0 0 0 1"/></asset>
<worldbody>
<body name="b">
<joint name="h" range="-1 1"/><joint name="free_spin" axis="1 0 0"/><joint name="b" type="ball"/>
<geom size="0.1"/>
<site name="s"/>
<site name="fitted" type="box" mesh="m"/>
</body>
</worldbody>
<actuator>
{actuators}
</actuator>
</mujoco>"#
    )
}

#[test]
fn refused_actuators_name_element_line_and_reason() {
    for case in REFUSED {
        let error = match parse_mjcf(&vehicle_with(case.actuators)) {
            Ok(_) => panic!("{}: accepted", case.what),
            Err(error) => error,
        };
        let message = error.to_string();
        let line = 12 + case.actuators.lines().count() as u32 - 1;
        assert!((case.variant)(&error), "{}: unexpected variant {error:?}", case.what);
        assert!(message.starts_with(&format!("line {line}: {}", case.element)), "{}: {message}", case.what);
        assert!(message.contains(case.reason), "{}: {message:?} does not say {:?}", case.what, case.reason);
    }
}

#[test]
fn unsupported_actuator_defaults_and_autolimits_are_refused() {
    let muscle = "<mujoco>\n<default>\n<muscle/>\n</default>\n<worldbody/>\n</mujoco>";
    let error = parse_mjcf(muscle).unwrap_err();
    assert!(error.to_string().starts_with("line 3: <muscle>: not supported: muscle actuators"), "{error}");

    let xml = vehicle_with(r#"<motor joint="h" ctrlrange="-2 2"/>"#)
        .replace("<mujoco>", "<mujoco><compiler autolimits=\"false\"/>")
        .replace(r#"range="-1 1""#, r#"limited="true" range="-1 1""#);
    let error = parse_mjcf(&xml).unwrap_err();
    assert!(error.to_string().contains("'ctrlrange' without 'ctrllimited'"), "{error}");

    let twice = "<mujoco>\n<default>\n<motor/>\n<motor gear=\"2\"/>\n</default>\n<worldbody/>\n</mujoco>";
    assert!(matches!(parse_mjcf(twice).unwrap_err(), MjcfError::Repeated { line: 4, .. }));
}

#[test]
fn sites_are_read_with_their_frames() {
    let xml = r#"<mujoco><worldbody>
      <site name="w" pos="1 2 3"/>
      <body pos="0 0 1"><joint/><geom size="0.1"/>
        <site name="a" type="cylinder" size="0.1" fromto="0 0 0 0 0 -2"/>
        <site name="b" pos="0.5 0 0" axisangle="0 0 1 90"/>
      </body></worldbody></mujoco>"#;
    let vehicle = parse_mjcf(xml).unwrap().vehicle;
    let [w, a, b] = [&vehicle.sites[0], &vehicle.sites[1], &vehicle.sites[2]];
    assert_eq!((w.body, a.body, b.body), (None, Some(0), Some(0)));
    // fromto: centred between the points, z from the second towards the first.
    assert_eq!(a.pos, nalgebra::Vector3::new(0.0, 0.0, -1.0));
    assert!((a.quat * nalgebra::Vector3::z() - nalgebra::Vector3::z()).norm() < 1e-15);
    assert!((b.quat * nalgebra::Vector3::x() - nalgebra::Vector3::y()).norm() < 1e-15);

    let duplicate = xml.replace(r#"name="b""#, r#"name="a""#);
    let error = parse_mjcf(&duplicate).unwrap_err();
    assert!(matches!(error, MjcfError::DuplicateName { kind: "site", line: 5, .. }), "{error:?}");
    let sphere = xml.replace(r#"type="cylinder" "#, "");
    assert!(
        parse_mjcf(&sphere).unwrap_err().to_string().contains("requires a capsule, cylinder, ellipsoid or box site")
    );
}

/// Activation dynamics read as MuJoCo 4.0 reads them: dyntype, dynprm[0],
/// actrange when actlimited, actearly; a position servo's timeconst makes a
/// filterexact; a class's general default lends dyntype and actearly to
/// general, and a shortcut's table clears actearly.
#[test]
fn activation_dynamics_are_read_with_their_ranges_and_actearly() {
    use nudyn::vehicle::{Activation, ActivationKind};
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/activation/filtered_arm.xml");
    let Imported { vehicle, .. } = load_mjcf(&path).unwrap();
    let activation = |name: &str| actuator(&vehicle, name).activation;
    let state = |kind, time_constant, range, early| Some(Activation { kind, time_constant, range, early });
    assert_eq!(activation("shoulder_int"), state(ActivationKind::Integrator, 1.0, Some([-0.6, 0.6]), true));
    assert_eq!(activation("elbow_lag"), state(ActivationKind::Filter, 0.05, None, false));
    assert_eq!(activation("roll_servo"), state(ActivationKind::FilterExact, 0.08, None, false));
    assert_eq!(activation("reach_early"), state(ActivationKind::FilterExact, 0.03, Some([-0.5, 0.5]), true));
    assert_eq!(activation("yaw"), None);
    let model = Model::compile(&vehicle).unwrap();
    assert_eq!(model.activation_count(), 5);

    let inherited = parse_mjcf(
        r#"<mujoco><default><default class="lag"><general dyntype="filter" dynprm="0.2" actearly="true"/></default></default>
        <worldbody><body><joint name="h"/><geom size="0.1" mass="1"/></body></worldbody>
        <actuator><general name="a" class="lag" joint="h"/><motor name="m" class="lag" joint="h"/>
        <position name="p" class="lag" joint="h" timeconst="0.1"/></actuator></mujoco>"#,
    )
    .unwrap();
    assert_eq!(actuator(&inherited.vehicle, "a").activation, state(ActivationKind::Filter, 0.2, None, true));
    // A motor's table has no activation, whatever its class's general says.
    assert_eq!(actuator(&inherited.vehicle, "m").activation, None);
    // A shortcut's table clears actearly (MuJoCo 4.0 gives actuator_actearly 0 here).
    assert_eq!(actuator(&inherited.vehicle, "p").activation, state(ActivationKind::FilterExact, 0.1, None, false));
}

/// `<intvelocity>` and `<cylinder>` read into MuJoCo 4.0's general actuators
/// with an integrator and a filter (test_actuators.py and test_activation.py
/// compare the same fixture with MuJoCo itself): gains and bias from the
/// element, from their class, or lent by a `<general>` default; the
/// integrator's range its joint's under `inheritrange`; a cylinder's gain
/// its area, π/4 d² from a diameter.
#[test]
fn intvelocity_and_cylinder_read_into_integrator_and_filter_actuators() {
    use nudyn::vehicle::{Activation, ActivationKind};
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/activation/shortcut_servos.xml");
    let Imported { vehicle, .. } = load_mjcf(&path).unwrap();
    let state = |kind, time_constant, range| Some(Activation { kind, time_constant, range, early: false });
    let (fixed, affine) = (GainType::Fixed, BiasType::Affine);

    let shoulder = actuator(&vehicle, "shoulder_int");
    assert_eq!(shoulder.kind, ActuatorKind::IntVelocity);
    // biasprm[2] holds the damping ratio until the compiler resolves it.
    assert_eq!(law(shoulder), (fixed, [30.0, 0.0, 0.0], affine, [0.0, -30.0, 0.7]));
    assert_eq!(shoulder.activation, state(ActivationKind::Integrator, 1.0, Some([-1.2, 0.8])));
    assert_eq!(shoulder.ctrl_range, Some([-1.0, 1.0]));

    let elbow = actuator(&vehicle, "elbow_int");
    assert_eq!(law(elbow), (fixed, [12.0, 0.0, 0.0], affine, [0.0, -12.0, 0.7]));
    assert_eq!(elbow.activation, state(ActivationKind::Integrator, 1.0, Some([-0.4, 0.4])));

    let ram = actuator(&vehicle, "ram");
    assert_eq!(ram.kind, ActuatorKind::Cylinder);
    assert_eq!(law(ram), (fixed, [PI / 4.0 * 0.25, 0.0, 0.0], affine, [0.5, -20.0, -2.0]));
    assert_eq!(ram.activation, state(ActivationKind::Filter, 0.15, None));
    assert_eq!(ram.ctrl_range, Some([0.0, 30.0]));

    let elbow_ram = actuator(&vehicle, "elbow_ram");
    assert_eq!(law(elbow_ram), (fixed, [0.05, 0.0, 0.0], affine, [0.0, -1.0, -0.1]));
    assert_eq!(elbow_ram.activation, state(ActivationKind::Filter, 0.05, None));
    assert_eq!(Model::compile(&vehicle).unwrap().activation_count(), 4);
}
