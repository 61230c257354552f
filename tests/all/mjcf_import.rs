//! The MJCF importer against hand-computed expectations: fixture files under
//! `tests/fixtures/mjcf/`, a table of malformed inputs, and the warnings for
//! ignored elements.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};
use std::path::PathBuf;

use nalgebra::{Quaternion, UnitQuaternion};
use nudyn::math::{Mat3, Quat, Vec3};
use nudyn::mjcf::{Imported, MjcfError, load_mjcf, parse_mjcf};
use nudyn::model::Model;
use nudyn::vehicle::{Body, Joint, JointKind, MassProperties, Vehicle};

const TOL: f64 = 1e-12;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/mjcf").join(name)
}

fn load(name: &str) -> Imported {
    load_mjcf(&fixture(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn body<'a>(vehicle: &'a Vehicle, name: &str) -> &'a Body {
    vehicle.bodies.iter().find(|b| b.name == name).unwrap_or_else(|| panic!("no body {name}"))
}

fn joint<'a>(vehicle: &'a Vehicle, name: &str) -> &'a Joint {
    vehicle.bodies.iter().flat_map(|b| &b.joints).find(|j| j.name == name).unwrap_or_else(|| panic!("no joint {name}"))
}

fn inertia(body: &Body) -> &MassProperties {
    body.inertia.as_ref().unwrap_or_else(|| panic!("{} is massless", body.name))
}

fn assert_close(what: &str, actual: f64, expected: f64) {
    assert!((actual - expected).abs() <= TOL * expected.abs().max(1.0), "{what}: {actual} != {expected}");
}

fn assert_vec(what: &str, actual: &Vec3, expected: Vec3) {
    assert!((actual - expected).amax() <= TOL * expected.amax().max(1.0), "{what}: {actual} != {expected}");
}

fn assert_mat(what: &str, actual: &Mat3, expected: Mat3) {
    assert!((actual - expected).amax() <= TOL * expected.amax().max(1.0), "{what}: {actual} != {expected}");
}

/// Compares quaternion coordinates, sign included (the importer keeps MuJoCo's).
fn assert_quat(what: &str, actual: &Quat, expected: Quat) {
    assert!((actual.coords - expected.coords).amax() <= TOL, "{what}: {:?} != {:?}", actual.coords, expected.coords);
}

fn wxyz(w: f64, x: f64, y: f64, z: f64) -> Quat {
    UnitQuaternion::new_normalize(Quaternion::new(w, x, y, z))
}

/// Rotation by `angle` about a coordinate axis.
fn about(axis: Vec3, angle: f64) -> Quat {
    Quat::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle)
}

/// Solid box with half sizes a, b, c: m (b² + c²) / 3, ...
fn box_moments(mass: f64, a: f64, b: f64, c: f64) -> Vec3 {
    Vec3::new(mass * (b * b + c * c) / 3.0, mass * (a * a + c * c) / 3.0, mass * (a * a + b * b) / 3.0)
}

/// Solid cylinder of radius r and half length h along z.
fn cylinder_moments(mass: f64, r: f64, h: f64) -> Vec3 {
    let transverse = mass * (3.0 * r * r + 4.0 * h * h) / 12.0;
    Vec3::new(transverse, transverse, mass * r * r / 2.0)
}

/// Solid capsule of radius r and cylinder half length h along z: a cylinder
/// plus two hemispheres, the masses split by volume. A hemisphere's centre
/// of mass lies 3r/8 from its flat face, which lies h from the centre.
fn capsule_moments(mass: f64, r: f64, h: f64) -> Vec3 {
    let cylinder_volume = PI * r * r * 2.0 * h;
    let sphere_volume = 4.0 / 3.0 * PI * r * r * r;
    let sphere_mass = mass * sphere_volume / (cylinder_volume + sphere_volume);
    let cylinder = cylinder_moments(mass - sphere_mass, r, h);
    // Two half spheres about the capsule's centre: the sphere's own moment,
    // plus the parallel-axis shift from the flat face (at h) in two steps
    // that leave the hemisphere's own offset (3r/8) in place.
    let shift = sphere_mass * (h * h + 2.0 * h * 3.0 * r / 8.0);
    let sphere = 2.0 * sphere_mass * r * r / 5.0;
    Vec3::new(cylinder.x + sphere + shift, cylinder.y + sphere + shift, cylinder.z + sphere)
}

fn diag(v: Vec3) -> Mat3 {
    Mat3::from_diagonal(&v)
}

#[test]
fn box_arm_bodies_joints_and_box_inertia() {
    let Imported { vehicle, warnings, .. } = load("box_arm.xml");
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(vehicle.name, "box_arm");
    assert_vec("gravity", &vehicle.gravity, Vec3::new(0.0, 0.0, -9.81));
    assert_eq!(vehicle.bodies.len(), 2);

    let base = body(&vehicle, "base");
    assert_eq!((base.parent, base.line), (None, 4));
    assert_vec("base.pos", &base.pos, Vec3::new(0.0, 0.0, 1.0));
    assert_quat("base.quat", &base.quat, Quat::identity());
    let m = inertia(base);
    assert_close("base.mass", m.mass, 6.0);
    assert_vec("base.com", &m.com, Vec3::zeros());
    assert_mat("base.inertia", &m.inertia, diag(box_moments(6.0, 0.1, 0.2, 0.3)));

    let shoulder = joint(&vehicle, "shoulder");
    assert_eq!((shoulder.kind, shoulder.line), (JointKind::Hinge, 5));
    assert_vec("shoulder.pos", &shoulder.pos, Vec3::new(0.0, 0.0, 0.1));
    assert_vec("shoulder.axis", &shoulder.axis, Vec3::y());
    assert_close("shoulder.ref (30°)", shoulder.reference, PI / 6.0);
    assert_close("shoulder.springref (-45°)", shoulder.springref, -FRAC_PI_4);
    assert_eq!((shoulder.stiffness, shoulder.damping, shoulder.armature), (2.0, 0.5, 0.01));

    let slider = body(&vehicle, "slider");
    assert_eq!(slider.parent, Some(0));
    assert_vec("slider.pos", &slider.pos, Vec3::new(0.5, 0.0, 0.0));
    let rail = joint(&vehicle, "rail");
    assert_eq!(rail.kind, JointKind::Slide);
    assert_vec("rail.axis", &rail.axis, Vec3::x());
    // Slide positions are lengths: no angle conversion.
    assert_eq!((rail.reference, rail.springref), (0.25, 0.1));
    let sphere_mass = 500.0 * 4.0 / 3.0 * PI * 0.1f64.powi(3);
    let m = inertia(slider);
    assert_close("slider.mass", m.mass, sphere_mass);
    assert_vec("slider.com", &m.com, Vec3::new(0.0, 0.0, 0.2));
    assert_mat("slider.inertia", &m.inertia, Mat3::identity() * 0.4 * sphere_mass * 0.01);
}

#[test]
fn every_orientation_form() {
    let vehicle = load("orientations.xml").vehicle;
    let half = FRAC_PI_4;
    let cases = [
        ("by_quat", wxyz(1.0, 0.0, 0.0, 1.0)),
        ("by_axisangle", wxyz(half.cos(), 0.0, 0.0, half.sin())),
        // Lowercase xyz: rotate about x, then about the rotated y.
        ("by_euler", about(Vec3::x(), FRAC_PI_2) * about(Vec3::y(), FRAC_PI_2)),
        // x = (0 1 0); y = (-1 1 0) minus its x part = (-1 0 0); z = x × y = (0 0 1).
        ("by_xyaxes", about(Vec3::z(), FRAC_PI_2)),
        // The minimal rotation taking z to x is a quarter turn about y.
        ("by_zaxis", wxyz(half.cos(), 0.0, half.sin(), 0.0)),
        // Taking z to -z: MuJoCo turns half a turn about x.
        ("by_zaxis_down", wxyz(0.0, 1.0, 0.0, 0.0)),
    ];
    for (name, expected) in cases {
        assert_quat(name, &body(&vehicle, name).quat, expected);
    }
}

#[test]
fn orientations_with_huge_or_tiny_numbers_keep_their_direction() {
    // MuJoCo's own compiler squares these and overflows to a zero rotation.
    let xml = "<mujoco><worldbody>\
               <body name=\"huge_quat\" quat=\"1e300 0 0 1e300\"><geom size=\"1\"/></body>\
               <body name=\"tiny_quat\" quat=\"1e-12 0 0 1e-12\"><geom size=\"1\"/></body>\
               <body name=\"huge_zaxis\" zaxis=\"1e200 0 0\"><geom size=\"1\"/></body>\
               <body name=\"huge_axisangle\" axisangle=\"0 0 1e300 90\"><geom size=\"1\"/></body>\
               </worldbody></mujoco>";
    let vehicle = parse_mjcf(xml).unwrap().vehicle;
    let quarter_about_z = about(Vec3::z(), FRAC_PI_2);
    assert_quat("huge_quat", &body(&vehicle, "huge_quat").quat, quarter_about_z);
    assert_quat("tiny_quat", &body(&vehicle, "tiny_quat").quat, quarter_about_z);
    assert_quat("huge_zaxis", &body(&vehicle, "huge_zaxis").quat, about(Vec3::y(), FRAC_PI_2));
    assert_quat("huge_axisangle", &body(&vehicle, "huge_axisangle").quat, quarter_about_z);
}

#[test]
fn radians_and_mixed_euler_sequence() {
    let vehicle = load("euler_radian.xml").vehicle;
    let turned = body(&vehicle, "turned");
    // eulerseq="zYx": z moving (right), Y fixed (left), x moving (right).
    let expected = about(Vec3::y(), -0.5) * about(Vec3::z(), 0.3) * about(Vec3::x(), 1.2);
    assert_quat("turned.quat", &turned.quat, expected);
    let hinge = joint(&vehicle, "hinge");
    assert_eq!((hinge.reference, hinge.springref), (0.7, -0.2));
    // The box turned a quarter turn about x: its y and z moments swap.
    let mass = 1000.0 * 8.0 * 0.1 * 0.2 * 0.3;
    let moments = box_moments(mass, 0.1, 0.2, 0.3);
    let m = inertia(turned);
    assert_close("mass", m.mass, mass);
    assert_mat("inertia", &m.inertia, diag(Vec3::new(moments.x, moments.z, moments.y)));
}

#[test]
fn geom_shapes_fromto_and_sums() {
    let vehicle = load("geoms.xml").vehicle;

    let m = inertia(body(&vehicle, "capsule"));
    assert_close("capsule.mass", m.mass, 2.0);
    assert_mat("capsule.inertia", &m.inertia, diag(capsule_moments(2.0, 0.05, 0.2)));

    let mass = 2000.0 * PI * 0.05 * 0.05 * 0.4;
    let m = inertia(body(&vehicle, "cylinder"));
    assert_close("cylinder.mass", m.mass, mass);
    assert_mat("cylinder.inertia", &m.inertia, diag(cylinder_moments(mass, 0.05, 0.2)));

    let m = inertia(body(&vehicle, "ellipsoid"));
    let (a, b, c) = (0.01, 0.04, 0.09);
    assert_mat("ellipsoid.inertia", &m.inertia, diag(Vec3::new(b + c, a + c, a + b) * 3.0 / 5.0));

    // fromto along x: centre halfway, the capsule's own z axis along body x.
    let m = inertia(body(&vehicle, "rod"));
    let moments = capsule_moments(1.0, 0.05, 0.2);
    assert_vec("rod.com", &m.com, Vec3::new(0.2, 0.0, 0.0));
    assert_mat("rod.inertia", &m.inertia, diag(Vec3::new(moments.z, moments.x, moments.y)));

    // A box given by fromto keeps its first size for x and y; z is half the length.
    let m = inertia(body(&vehicle, "beam"));
    assert_vec("beam.com", &m.com, Vec3::new(0.0, 0.0, 0.5));
    assert_mat("beam.inertia", &m.inertia, diag(box_moments(1.0, 0.1, 0.1, 0.5)));

    // Two spheres (1 kg at x = -0.5, 3 kg at x = 0.5); the group-3 box is
    // outside inertiagrouprange="0 2".
    let m = inertia(body(&vehicle, "dumbbell"));
    let own = 2.0 / 5.0 * 4.0 * 0.01;
    let com = (-0.5 * 1.0 + 0.5 * 3.0) / 4.0;
    let transfer = 1.0 * (-0.5 - com) * (-0.5 - com) + 3.0 * (0.5 - com) * (0.5 - com);
    assert_close("dumbbell.mass", m.mass, 4.0);
    assert_vec("dumbbell.com", &m.com, Vec3::new(com, 0.0, 0.0));
    assert_mat("dumbbell.inertia", &m.inertia, diag(Vec3::new(own, own + transfer, own + transfer)));

    // A geom without mass is left out, so the box alone is the body: its frame
    // and moments as they are (a quarter turn about z swaps x and y).
    let m = inertia(body(&vehicle, "weightless_geom"));
    let moments = box_moments(6.0, 0.1, 0.2, 0.3);
    assert_close("weightless_geom.mass", m.mass, 6.0);
    assert_vec("weightless_geom.com", &m.com, Vec3::new(-1.0, 0.0, 0.0));
    assert_mat("weightless_geom.inertia", &m.inertia, diag(Vec3::new(moments.y, moments.x, moments.z)));
}

#[test]
fn default_classes_inherit_and_override() {
    let vehicle = load("defaults.xml").vehicle;
    let plain = joint(&vehicle, "plain_joint");
    assert_eq!((plain.kind, plain.damping, plain.stiffness), (JointKind::Hinge, 1.0, 3.0));
    assert_vec("plain.axis", &plain.axis, Vec3::z());
    let box_mass = 100.0 * 8.0 * 0.1 * 0.2 * 0.3;
    let m = inertia(body(&vehicle, "plain"));
    assert_close("plain.mass", m.mass, box_mass);
    assert_mat("plain.inertia", &m.inertia, diag(box_moments(box_mass, 0.1, 0.2, 0.3)));

    // childclass="arm": damping and axis from "arm", stiffness from "main".
    let elbow = joint(&vehicle, "elbow");
    assert_eq!((elbow.damping, elbow.stiffness), (2.0, 3.0));
    assert_vec("elbow.axis", &elbow.axis, Vec3::y());
    // The geom's own quat replaces the class's euler.
    assert_mat("upper.inertia", &inertia(body(&vehicle, "upper")).inertia, diag(box_moments(box_mass, 0.1, 0.2, 0.3)));

    // "lower" inherits childclass "arm" from its parent; class= overrides it.
    let main = joint(&vehicle, "lower_main");
    assert_eq!((main.kind, main.damping, main.armature), (JointKind::Hinge, 1.0, 0.0));
    assert_vec("lower_main.axis", &main.axis, Vec3::z());
    let wrist = joint(&vehicle, "lower_wrist");
    assert_eq!((wrist.kind, wrist.damping, wrist.stiffness, wrist.armature), (JointKind::Slide, 2.0, 3.0, 5.0));
    assert_vec("lower_wrist.axis", &wrist.axis, Vec3::y());
    // size="0.4" replaces only the first size: (0.4, 0.2, 0.3); the euler
    // "0 0 90" from "arm" swaps x and y.
    let mass = 100.0 * 8.0 * 0.4 * 0.2 * 0.3;
    let moments = box_moments(mass, 0.4, 0.2, 0.3);
    let m = inertia(body(&vehicle, "lower"));
    assert_close("lower.mass", m.mass, mass);
    assert_mat("lower.inertia", &m.inertia, diag(Vec3::new(moments.y, moments.x, moments.z)));
}

#[test]
fn a_nested_class_inherits_settings_written_after_it() {
    let vehicle = load("default_order.xml").vehicle;
    assert_eq!(joint(&vehicle, "hinge").damping, 3.0);
    // A sphere of radius 0.2 (the inner size) at density 500 (the outer density).
    let volume = 4.0 / 3.0 * PI * 0.2f64.powi(3);
    assert_close("ball.mass", inertia(body(&vehicle, "ball")).mass, 500.0 * volume);
}

#[test]
fn explicit_inertial() {
    let vehicle = load("inertial.xml").vehicle;
    let m = inertia(body(&vehicle, "rotated"));
    assert_close("rotated.mass", m.mass, 4.0);
    assert_vec("rotated.com", &m.com, Vec3::new(0.1, 0.2, 0.3));
    // diag(1 2 3) turned a quarter turn about z; the box geom does not count.
    assert_mat("rotated.inertia", &m.inertia, diag(Vec3::new(2.0, 1.0, 3.0)));

    let m = inertia(body(&vehicle, "full"));
    assert_close("full.mass", m.mass, 2.0);
    assert_vec("full.com", &m.com, Vec3::new(0.0, 0.0, -0.5));
    assert_mat("full.inertia", &m.inertia, Mat3::new(2.0, 0.1, -0.2, 0.1, 3.0, 0.3, -0.2, 0.3, 4.0));

    // No inertial and no geoms: massless, though its welded child has mass.
    let hollow = body(&vehicle, "hollow");
    assert!(hollow.inertia.is_none() && hollow.joints.is_empty());
    let welded = body(&vehicle, "welded");
    assert_eq!(welded.parent, Some(2));
    assert_close("welded.mass", inertia(welded).mass, 1000.0 * 4.0 / 3.0 * PI * 0.125);
}

#[test]
fn inertia_from_geom_true_overrides_inertial() {
    let vehicle = load("inertia_from_geom.xml").vehicle;
    let m = inertia(body(&vehicle, "overridden"));
    assert_close("mass", m.mass, 8.0);
    assert_mat("inertia", &m.inertia, diag(box_moments(8.0, 0.1, 0.1, 0.1)));
}

#[test]
fn compiler_bounds_and_balance() {
    let vehicle = load("bounds.xml").vehicle;
    let m = inertia(body(&vehicle, "light"));
    assert_close("light.mass (boundmass)", m.mass, 0.5);
    assert_mat("light.inertia (boundinertia)", &m.inertia, diag(Vec3::new(1.0, 1.0, 0.25)));
    // 1 + 1 < 3: balanceinertia sets all three to their mean.
    let m = inertia(body(&vehicle, "unbalanced"));
    assert_mat("unbalanced.inertia", &m.inertia, Mat3::identity() * 5.0 / 3.0);
    // MuJoCo puts the bound mass of a body without geoms or inertial at the
    // body's position in its parent, taken as a point in the body frame.
    let m = inertia(body(&vehicle, "empty"));
    assert_close("empty.mass", m.mass, 0.5);
    assert_vec("empty.com", &m.com, Vec3::new(1.0, 2.0, 3.0));
    assert_mat("empty.inertia", &m.inertia, Mat3::identity() * 0.25);
}

#[test]
fn disabled_gravity_springs_and_dampers() {
    let vehicle = load("flags.xml").vehicle;
    assert_eq!(vehicle.gravity, Vec3::zeros());
    let j = &body(&vehicle, "pendulum").joints[0];
    assert_eq!((j.stiffness, j.damping, j.armature), (0.0, 0.0, 0.5));

    let vehicle = load("lunar_gravity.xml").vehicle;
    assert_eq!(vehicle.name, "vehicle");
    assert_eq!(vehicle.gravity, Vec3::new(0.0, 0.0, -1.62));
    assert_eq!(vehicle.bodies[0].name, "body0");
    assert_eq!(vehicle.bodies[0].joints[0].name, "body0_joint0");
}

#[test]
fn free_ball_and_multiple_joints() {
    let vehicle = load("joints.xml").vehicle;
    let names: Vec<&str> = vehicle.bodies.iter().map(|b| b.name.as_str()).collect();
    assert_eq!(names, ["floater", "drifter", "shoulder", "body3", "pedestal"]);
    let parents: Vec<Option<usize>> = vehicle.bodies.iter().map(|b| b.parent).collect();
    assert_eq!(parents, [None, None, Some(1), Some(2), None]);

    // <freejoint> takes no defaults; <joint type="free"> does.
    let float = joint(&vehicle, "float");
    assert_eq!((float.kind, float.damping, float.armature), (JointKind::Free, 0.0, 0.0));
    assert_quat("floater.quat", &body(&vehicle, "floater").quat, about(Vec3::z(), FRAC_PI_4));
    let drift = joint(&vehicle, "drifter_joint0");
    assert_eq!((drift.kind, drift.damping, drift.armature), (JointKind::Free, 0.3, 0.2));

    let ball = joint(&vehicle, "ball");
    assert_eq!((ball.kind, ball.reference), (JointKind::Ball, 0.0));
    assert_vec("ball.pos", &ball.pos, Vec3::new(0.0, 0.0, -0.1));
    assert_eq!(joint(&vehicle, "extend").kind, JointKind::Slide);

    let unnamed = body(&vehicle, "body3");
    let joint_names: Vec<&str> = unnamed.joints.iter().map(|j| j.name.as_str()).collect();
    assert_eq!(joint_names, ["body3_joint0", "body3_joint1"]);
    assert_close("body3_joint1.ref", unnamed.joints[1].reference, FRAC_PI_2);
    assert_vec("body3_joint1.axis", &unnamed.joints[1].axis, Vec3::y());

    // A body without joints directly in <worldbody> stays, welded to the world.
    let pedestal = body(&vehicle, "pedestal");
    assert!(pedestal.joints.is_empty());
    let mass = 1000.0 * PI * 0.09 * 0.2;
    assert_mat("pedestal.inertia", &inertia(pedestal).inertia, diag(cylinder_moments(mass, 0.3, 0.1)));
}

#[test]
fn satellite() {
    let vehicle = load("satellite.xml").vehicle;
    assert_eq!(vehicle.gravity, Vec3::zeros());
    let kinds: Vec<(&str, JointKind)> =
        vehicle.bodies.iter().flat_map(|b| &b.joints).map(|j| (j.name.as_str(), j.kind)).collect();
    assert_eq!(
        kinds,
        [
            ("bus_free", JointKind::Free),
            ("deploy_left", JointKind::Hinge),
            ("deploy_right", JointKind::Hinge),
            ("arm_yaw", JointKind::Hinge),
            ("arm_pitch", JointKind::Hinge),
            ("elbow", JointKind::Hinge),
            ("wrist", JointKind::Ball),
        ]
    );
    // The bus's <inertial> wins over its box geom.
    let bus = inertia(body(&vehicle, "bus"));
    assert_close("bus.mass", bus.mass, 250.0);
    assert_mat("bus.inertia", &bus.inertia, Mat3::new(40.0, 0.5, -0.3, 0.5, 42.0, 0.2, -0.3, 0.2, 35.0));

    let deploy = joint(&vehicle, "deploy_right");
    assert_eq!((deploy.stiffness, deploy.damping, deploy.armature), (0.2, 0.1, 0.01));
    assert_close("deploy_right.ref", deploy.reference, FRAC_PI_2);
    assert_quat("array_right.quat", &body(&vehicle, "array_right").quat, about(Vec3::z(), PI));
    assert_close("array_right.mass", inertia(body(&vehicle, "array_right")).mass, 4.0);

    // The hand: a cylinder along x (zaxis="1 0 0") and a box, summed.
    let hand = inertia(body(&vehicle, "hand"));
    let (m1, x1, m2, x2) = (1.5, 0.05, 0.3, 0.13);
    let com = (m1 * x1 + m2 * x2) / (m1 + m2);
    let cylinder = cylinder_moments(m1, 0.06, 0.05);
    let cube = box_moments(m2, 0.02, 0.05, 0.03);
    let transfer = m1 * (x1 - com).powi(2) + m2 * (x2 - com).powi(2);
    let expected = Vec3::new(cylinder.z + cube.x, cylinder.x + cube.y + transfer, cylinder.y + cube.z + transfer);
    assert_close("hand.mass", hand.mass, m1 + m2);
    assert_vec("hand.com", &hand.com, Vec3::new(com, 0.0, 0.0));
    assert_mat("hand.inertia", &hand.inertia, diag(expected));
}

#[test]
fn ignored_elements_warn_once_each() {
    let Imported { vehicle, warnings, .. } = load("ignored.xml");
    assert_eq!(vehicle.bodies.len(), 1);
    let shown: Vec<String> = warnings.iter().map(ToString::to_string).collect();
    let ignored = |line: u32, element: &str| format!("line {line}: <{element}>: ignored (no effect on the dynamics)");
    let expected = [
        ignored(3, "lengthrange"),
        ignored(5, "size"),
        ignored(6, "statistic"),
        ignored(7, "visual"),
        ignored(14, "texture name=\"grid\""),
        ignored(17, "light name=\"sun\""),
        "line 18: <geom name=\"floor\">: ignored: fixed to the world, it moves no mass, and nudyn models no contacts \
         (MuJoCo would make contacts with it)"
            .to_string(),
        ignored(19, "camera name=\"overview\""),
        ignored(24, "camera name=\"eye\""),
        "line 27: <contact>: ignored: nudyn models no contacts".to_string(),
        ignored(40, "custom"),
        ignored(43, "extension"),
    ];
    assert_eq!(shown, expected);
    let camera = &warnings[7];
    assert_eq!((camera.line, camera.element.as_str()), (19, "camera name=\"overview\""));
    // Sites, actuators and sensors are read, not ignored.
    assert_eq!(vehicle.sites.len(), 1);
    assert_eq!(vehicle.actuators.len(), 1);
    assert_eq!(vehicle.sensors.len(), 1);
}

#[test]
fn settotalmass_scales_and_warns() {
    let xml = r#"<mujoco>
  <compiler settotalmass="10"/>
  <worldbody>
    <body><joint/><geom size="0.1" mass="1"/><body><geom size="0.1" mass="3"/></body></body>
  </worldbody>
</mujoco>"#;
    let Imported { vehicle, warnings, .. } = parse_mjcf(xml).unwrap();
    let masses: Vec<f64> = vehicle.bodies.iter().map(|b| inertia(b).mass).collect();
    assert_eq!(masses, [2.5, 7.5]);
    assert_close("scaled moment", inertia(&vehicle.bodies[0]).inertia[(0, 0)], 2.5 * 0.4 * 0.01);
    assert_eq!(warnings.len(), 1);
    assert!(warnings[0].to_string().starts_with("line 2: <compiler>: settotalmass is deprecated"));
}

#[test]
fn io_error_names_the_path() {
    let path = fixture("no_such_file.xml");
    let error = load_mjcf(&path).unwrap_err();
    assert!(matches!(error, MjcfError::Io { .. }));
    assert!(error.to_string().contains("no_such_file.xml"), "{error}");
}

/// A file that must be rejected: which variant, which element, which line.
struct Malformed {
    what: &'static str,
    xml: &'static str,
    variant: fn(&MjcfError) -> bool,
    element: &'static str,
    line: u32,
}

#[rustfmt::skip]
const MALFORMED: &[Malformed] = &[
    Malformed { what: "not a number", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<joint name=\"j\">", line: 4,
        xml: "<mujoco>\n<worldbody>\n<body>\n<joint name=\"j\" damping=\"fast\"/>\n<geom size=\"1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "too few numbers", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<joint name=\"j2\">", line: 5,
        xml: "<mujoco>\n<worldbody>\n<body>\n<geom size=\"1\"/>\n<joint name=\"j2\" axis=\"0 1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "too many numbers", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<body>", line: 3,
        xml: "<mujoco>\n<worldbody>\n<body pos=\"1 2 3 4\">\n<geom size=\"1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "NaN", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<geom>", line: 4,
        xml: "<mujoco>\n<worldbody>\n<body>\n<geom size=\"nan\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "infinite mass", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<inertial>", line: 4,
        xml: "<mujoco>\n<worldbody>\n<body>\n<inertial pos=\"0 0 0\" mass=\"inf\" diaginertia=\"1 1 1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "negative mass", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<inertial>", line: 4,
        xml: "<mujoco>\n<worldbody>\n<body>\n<inertial pos=\"0 0 0\" mass=\"-1\" diaginertia=\"1 1 1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "negative geom mass", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<geom name=\"g\">", line: 5,
        xml: "<mujoco>\n<worldbody>\n<body>\n<joint/>\n<geom name=\"g\" size=\"1\" mass=\"-2\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "negative size", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<geom>", line: 5,
        xml: "<mujoco>\n<worldbody>\n<body>\n<joint/>\n<geom type=\"box\" size=\"1 -1 1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "two orientations", variant: |e| matches!(e, MjcfError::ConflictingAttributes { .. }), element: "<body name=\"b\">", line: 3,
        xml: "<mujoco>\n<worldbody>\n<body name=\"b\" quat=\"1 0 0 0\" euler=\"0 0 1\">\n<geom size=\"1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "quaternion MuJoCo takes for the identity", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<body>", line: 3,
        xml: "<mujoco>\n<worldbody>\n<body quat=\"1e-16 1e-16 0 0\">\n<geom size=\"1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "zero quaternion", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<geom>", line: 4,
        xml: "<mujoco>\n<worldbody>\n<body>\n<geom size=\"1\" quat=\"0 0 0 0\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "unknown attribute", variant: |e| matches!(e, MjcfError::UnknownAttribute { .. }), element: "<joint>", line: 4,
        xml: "<mujoco>\n<worldbody>\n<body>\n<joint dampnig=\"1\"/>\n<geom size=\"1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "unknown keyword", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<joint>", line: 4,
        xml: "<mujoco>\n<worldbody>\n<body>\n<joint type=\"hing\"/>\n<geom size=\"1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "unknown element in a body", variant: |e| matches!(e, MjcfError::UnknownElement { .. }), element: "<motor>", line: 5,
        xml: "<mujoco>\n<worldbody>\n<body>\n<geom size=\"1\"/>\n<motor/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "unknown section", variant: |e| matches!(e, MjcfError::UnknownElement { .. }), element: "<physics>", line: 2,
        xml: "<mujoco>\n<physics/>\n<worldbody/>\n</mujoco>" },
    Malformed { what: "tendon wrapping with a side site", variant: |e| matches!(e, MjcfError::Unsupported { .. }), element: "<geom>", line: 11,
        xml: "<mujoco>\n<worldbody>\n<body>\n<joint name=\"a\"/>\n<geom name=\"g\" size=\"1\"/><site name=\"s\"/>\n</body>\n<site name=\"w\"/>\n</worldbody>\n<tendon>\n<spatial name=\"t\"><site site=\"s\"/>\n<geom geom=\"g\" sidesite=\"w\"/><site site=\"w\"/></spatial>\n</tendon>\n</mujoco>" },
    Malformed { what: "sleep policy on a moving child", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<body>", line: 5,
        xml: "<mujoco>\n<worldbody>\n<body name=\"a\">\n<freejoint/><geom size=\"1\"/>\n<body sleep=\"never\">\n<joint/><geom size=\"1\"/>\n</body>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "sleep policy on a static body", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<body>", line: 3,
        xml: "<mujoco>\n<worldbody>\n<body sleep=\"init\">\n<geom size=\"1\"/>\n<body>\n<joint/><geom size=\"1\"/>\n</body>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "fuse=true", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<body>", line: 3,
        xml: "<mujoco>\n<worldbody>\n<body fuse=\"true\">\n<freejoint/><geom size=\"1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "tendon equality on a missing tendon", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<tendon>", line: 8,
        xml: "<mujoco>\n<worldbody>\n<body name=\"a\">\n<freejoint/><geom size=\"1\"/>\n</body>\n</worldbody>\n<equality>\n<tendon tendon1=\"t\"/>\n</equality>\n</mujoco>" },
    Malformed { what: "weld of a body with itself", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<weld>", line: 8,
        xml: "<mujoco>\n<worldbody>\n<body name=\"a\">\n<freejoint/><geom size=\"1\"/>\n</body>\n</worldbody>\n<equality>\n<weld body1=\"a\" body2=\"a\"/>\n</equality>\n</mujoco>" },
    Malformed { what: "connect to a missing body", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<connect>", line: 8,
        xml: "<mujoco>\n<worldbody>\n<body name=\"a\">\n<freejoint/><geom size=\"1\"/>\n</body>\n</worldbody>\n<equality>\n<connect body1=\"a\" body2=\"b\" anchor=\"0 0 0\"/>\n</equality>\n</mujoco>" },
    Malformed { what: "connect without anchor", variant: |e| matches!(e, MjcfError::MissingAttribute { .. }), element: "<connect>", line: 8,
        xml: "<mujoco>\n<worldbody>\n<body name=\"a\">\n<freejoint/><geom size=\"1\"/>\n</body>\n</worldbody>\n<equality>\n<connect body1=\"a\"/>\n</equality>\n</mujoco>" },
    Malformed { what: "weld of sites with an anchor", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<weld>", line: 8,
        xml: "<mujoco>\n<worldbody>\n<body name=\"a\">\n<freejoint/><geom size=\"1\"/><site name=\"s\"/>\n</body>\n<site name=\"w\"/>\n</worldbody><equality>\n<weld site1=\"s\" site2=\"w\" anchor=\"0 0 1\"/>\n</equality>\n</mujoco>" },
    Malformed { what: "weld of sites with a relative pose", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<weld name=\"hold\">", line: 8,
        xml: "<mujoco>\n<worldbody>\n<body name=\"a\">\n<freejoint/><geom size=\"1\"/><site name=\"s\"/>\n</body>\n<site name=\"w\"/>\n</worldbody><equality>\n<weld name=\"hold\" site1=\"s\" site2=\"w\" relpose=\"0 0 0 1 0 0 0\"/>\n</equality>\n</mujoco>" },
    Malformed { what: "connect of sites with an anchor", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<connect>", line: 8,
        xml: "<mujoco>\n<worldbody>\n<body name=\"a\">\n<freejoint/><geom size=\"1\"/><site name=\"s\"/>\n</body>\n<site name=\"w\"/>\n</worldbody><equality>\n<connect site1=\"s\" site2=\"w\" anchor=\"0 0 1\"/>\n</equality>\n</mujoco>" },
    Malformed { what: "joint coupling of a joint with itself", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<joint name=\"same\">", line: 8,
        xml: "<mujoco>\n<worldbody>\n<body name=\"a\">\n<joint name=\"h\"/><geom size=\"1\"/>\n</body>\n</worldbody>\n<equality>\n<joint name=\"same\" joint1=\"h\" joint2=\"h\"/>\n</equality>\n</mujoco>" },
    Malformed { what: "joint coupling of a ball joint", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<joint>", line: 8,
        xml: "<mujoco>\n<worldbody>\n<body name=\"a\">\n<joint name=\"b\" type=\"ball\"/><geom size=\"1\"/>\n</body>\n</worldbody>\n<equality>\n<joint joint1=\"b\"/>\n</equality>\n</mujoco>" },
    Malformed { what: "free joint in a nested body", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<freejoint>", line: 6,
        xml: "<mujoco>\n<worldbody>\n<body>\n<geom size=\"1\"/>\n<body>\n<freejoint/>\n<geom size=\"1\"/>\n</body>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "free joint with another joint", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<joint>", line: 5,
        xml: "<mujoco>\n<worldbody>\n<body>\n<geom size=\"1\"/>\n<joint type=\"free\"/>\n<joint/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "ball followed by hinge", variant: |e| matches!(e, MjcfError::Unsupported { .. }), element: "<joint name=\"h\">", line: 6,
        xml: "<mujoco>\n<worldbody>\n<body>\n<geom size=\"1\"/>\n<joint type=\"ball\"/>\n<joint name=\"h\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "mesh of three vertices", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<mesh name=\"m\">", line: 3,
        xml: "<mujoco>\n<asset>\n<mesh name=\"m\" vertex=\"0 0 0 1 0 0 0 1 0\"/>\n</asset>\n<worldbody>\n<body>\n<joint/>\n<geom name=\"hull\" type=\"mesh\" mesh=\"m\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "shell inertia on a mesh geom", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<geom>", line: 8,
        xml: "<mujoco>\n<asset>\n<mesh name=\"m\" vertex=\"0 0 0 1 0 0 0 1 0 0 0 1\"/>\n</asset>\n<worldbody>\n<body>\n<joint/>\n<geom type=\"mesh\" mesh=\"m\" shellinertia=\"true\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "missing worldbody", variant: |e| matches!(e, MjcfError::MissingWorldbody { .. }), element: "<mujoco>", line: 2,
        xml: "<?xml version=\"1.0\"?>\n<mujoco model=\"m\">\n<option timestep=\"0.01\"/>\n</mujoco>" },
    Malformed { what: "wrong root", variant: |e| matches!(e, MjcfError::WrongRoot { .. }), element: "<robot name=\"r\">", line: 1,
        xml: "<robot name=\"r\"><link name=\"l\"/></robot>" },
    Malformed { what: "unknown class", variant: |e| matches!(e, MjcfError::UnknownClass { .. }), element: "<geom>", line: 4,
        xml: "<mujoco>\n<worldbody>\n<body>\n<geom class=\"heavy\" size=\"1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "unknown childclass", variant: |e| matches!(e, MjcfError::UnknownClass { .. }), element: "<body name=\"b\">", line: 3,
        xml: "<mujoco>\n<worldbody>\n<body name=\"b\" childclass=\"arm\">\n<geom size=\"1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "duplicate body name", variant: |e| matches!(e, MjcfError::DuplicateName { .. }), element: "<body name=\"b\">", line: 6,
        xml: "<mujoco>\n<worldbody>\n<body name=\"b\">\n<geom size=\"1\"/>\n</body>\n<body name=\"b\">\n<geom size=\"1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "mocap body with a joint", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<body name=\"target\">", line: 3,
        xml: "<mujoco>\n<worldbody>\n<body name=\"target\" mocap=\"true\">\n<joint/>\n<geom size=\"1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "gravity compensation not a number", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<body>", line: 3,
        xml: "<mujoco>\n<worldbody>\n<body gravcomp=\"full\">\n<joint/>\n<geom size=\"1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "actuatorgravcomp not a boolean", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<joint>", line: 4,
        xml: "<mujoco>\n<worldbody>\n<body>\n<joint actuatorgravcomp=\"yes\"/>\n<geom size=\"1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "replicate without count", variant: |e| matches!(e, MjcfError::MissingAttribute { .. }), element: "<replicate>", line: 4,
        xml: "<mujoco>\n<worldbody>\n<body>\n<replicate offset=\"1 0 0\">\n<body><joint/><geom size=\"1\"/></body>\n</replicate>\n<geom size=\"1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "replicate of no copies", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<replicate>", line: 3,
        xml: "<mujoco>\n<worldbody>\n<replicate count=\"0\">\n<body><joint/><geom size=\"1\"/></body>\n</replicate>\n</worldbody>\n</mujoco>" },
    Malformed { what: "replicate of absurdly many copies", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<replicate>", line: 3,
        xml: "<mujoco>\n<worldbody>\n<replicate count=\"100000000\" offset=\"1 0 0\">\n<body><joint/><geom size=\"1\"/></body>\n</replicate>\n</worldbody>\n</mujoco>" },
    Malformed { what: "nested replicates of too many copies", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<replicate>", line: 4,
        xml: "<mujoco>\n<worldbody>\n<replicate count=\"400\" offset=\"1 0 0\">\n<replicate count=\"400\" offset=\"0 1 0\">\n<body><joint/><geom size=\"1\"/></body>\n</replicate>\n</replicate>\n</worldbody>\n</mujoco>" },
    Malformed { what: "replicate with a mass", variant: |e| matches!(e, MjcfError::UnknownAttribute { .. }), element: "<replicate>", line: 3,
        xml: "<mujoco>\n<worldbody>\n<replicate count=\"2\" mass=\"1\">\n<body><joint/><geom size=\"1\"/></body>\n</replicate>\n</worldbody>\n</mujoco>" },
    Malformed { what: "replicated name taken", variant: |e| matches!(e, MjcfError::DuplicateName { .. }), element: "<body name=\"arm\">", line: 5,
        xml: "<mujoco>\n<worldbody>\n<body name=\"arm_1\"><joint/><geom size=\"1\"/></body>\n<replicate count=\"2\" sep=\"_\">\n<body name=\"arm\"><joint/><geom size=\"1\"/></body>\n</replicate>\n</worldbody>\n</mujoco>" },
    Malformed { what: "o_solref with 3 numbers", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<option>", line: 2,
        xml: "<mujoco>\n<option o_solref=\"0.02 1 3\"/>\n<worldbody/>\n</mujoco>" },
    Malformed { what: "o_solimp with 6 numbers", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<option>", line: 3,
        xml: "<mujoco>\n<worldbody/>\n<option o_solimp=\"0.9 0.95 0.001 0.5 2 7\"/>\n</mujoco>" },
    Malformed { what: "o_friction with 6 numbers", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<option>", line: 2,
        xml: "<mujoco>\n<option o_friction=\"1 1 0.005 0.0001 0.0001 1\"/>\n<worldbody/>\n</mujoco>" },
    Malformed { what: "o_margin with 2 numbers", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<option>", line: 2,
        xml: "<mujoco>\n<option o_margin=\"0.1 0.2\"/>\n<worldbody/>\n</mujoco>" },
    Malformed { what: "solver iterations not an integer", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<option>", line: 2,
        xml: "<mujoco>\n<option iterations=\"1.5\"/>\n<worldbody/>\n</mujoco>" },
    Malformed { what: "geom friction with 4 numbers", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<geom>", line: 5,
        xml: "<mujoco>\n<worldbody>\n<body>\n<joint/>\n<geom size=\"1\" friction=\"1 0.005 0.0001 1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "geom solimp with 6 numbers", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<geom name=\"g\">", line: 5,
        xml: "<mujoco>\n<worldbody>\n<body>\n<joint/>\n<geom name=\"g\" size=\"1\" solimp=\"0.9 0.95 0.001 0.5 2 1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "geom rgba of 3 numbers", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<geom>", line: 3,
        xml: "<mujoco>\n<worldbody>\n<geom size=\"1\" rgba=\"1 0 0\"/>\n</worldbody>\n</mujoco>" },
    Malformed { what: "default geom solref with 3 numbers", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<geom>", line: 3,
        xml: "<mujoco>\n<default>\n<geom solref=\"0.02 1 1\"/>\n</default>\n<worldbody/>\n</mujoco>" },
    Malformed { what: "wind", variant: |e| matches!(e, MjcfError::Unsupported { .. }), element: "<option>", line: 2,
        xml: "<mujoco>\n<option wind=\"1 0 0\"/>\n<worldbody/>\n</mujoco>" },
    Malformed { what: "fluid density", variant: |e| matches!(e, MjcfError::Unsupported { .. }), element: "<option>", line: 3,
        xml: "<mujoco>\n<worldbody/>\n<option density=\"1.2\"/>\n</mujoco>" },
    Malformed { what: "sleeping bodies", variant: |e| matches!(e, MjcfError::Unsupported { .. }), element: "<flag>", line: 3,
        xml: "<mujoco>\n<option>\n<flag sleep=\"enable\"/>\n</option>\n<worldbody/>\n</mujoco>" },
    Malformed { what: "global coordinates", variant: |e| matches!(e, MjcfError::Unsupported { .. }), element: "<compiler>", line: 2,
        xml: "<mujoco>\n<compiler coordinate=\"global\"/>\n<worldbody/>\n</mujoco>" },
    Malformed { what: "bad euler sequence", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<compiler>", line: 2,
        xml: "<mujoco>\n<compiler eulerseq=\"xyw\"/>\n<worldbody/>\n</mujoco>" },
    Malformed { what: "frame with a mass", variant: |e| matches!(e, MjcfError::UnknownAttribute { .. }), element: "<frame>", line: 3,
        xml: "<mujoco>\n<worldbody>\n<frame pos=\"1 0 0\" mass=\"1\">\n<body><geom size=\"1\"/></body>\n</frame>\n</worldbody>\n</mujoco>" },
    Malformed { what: "include of a missing file", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<include>", line: 2,
        xml: "<mujoco>\n<include file=\"arm.xml\"/>\n<worldbody/>\n</mujoco>" },
    Malformed { what: "composite", variant: |e| matches!(e, MjcfError::Unsupported { .. }), element: "<composite>", line: 4,
        xml: "<mujoco>\n<worldbody>\n<body>\n<composite type=\"cable\" count=\"4 1 1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "flex", variant: |e| matches!(e, MjcfError::Unsupported { .. }), element: "<flex name=\"cloth\">", line: 4,
        xml: "<mujoco>\n<worldbody/>\n<deformable>\n<flex name=\"cloth\" dim=\"2\"/>\n</deformable>\n</mujoco>" },
    Malformed { what: "missing inertial mass", variant: |e| matches!(e, MjcfError::MissingAttribute { .. }), element: "<inertial>", line: 5,
        xml: "<mujoco>\n<worldbody>\n<body>\n<joint/>\n<inertial pos=\"0 0 0\" diaginertia=\"1 1 1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "two inertials", variant: |e| matches!(e, MjcfError::Repeated { .. }), element: "<inertial>", line: 5,
        xml: "<mujoco>\n<worldbody>\n<body>\n<inertial pos=\"0 0 0\" mass=\"1\" diaginertia=\"1 1 1\"/>\n<inertial pos=\"0 0 0\" mass=\"1\" diaginertia=\"1 1 1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "fullinertia and quat", variant: |e| matches!(e, MjcfError::ConflictingAttributes { .. }), element: "<inertial>", line: 4,
        xml: "<mujoco>\n<worldbody>\n<body>\n<inertial pos=\"0 0 0\" mass=\"1\" fullinertia=\"1 1 1 0 0 0\" quat=\"1 0 0 0\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "inertia not positive definite", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<inertial>", line: 4,
        xml: "<mujoco>\n<worldbody>\n<body>\n<inertial pos=\"0 0 0\" mass=\"1\" fullinertia=\"1 1 1 2 0 0\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "triangle inequality", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<body name=\"thin\">", line: 3,
        xml: "<mujoco>\n<worldbody>\n<body name=\"thin\">\n<joint/>\n<inertial pos=\"0 0 0\" mass=\"1\" diaginertia=\"1 1 3\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "massless moving body", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<body name=\"ghost\">", line: 3,
        xml: "<mujoco>\n<worldbody>\n<body name=\"ghost\">\n<joint/>\n<site/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "zero joint axis", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<joint>", line: 5,
        xml: "<mujoco>\n<worldbody>\n<body>\n<geom size=\"1\"/>\n<joint axis=\"0 0 0\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "fromto on a sphere", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<geom>", line: 5,
        xml: "<mujoco>\n<worldbody>\n<body>\n<joint/>\n<geom size=\"1\" fromto=\"0 0 0 0 0 1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "plane in a moving body", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<geom>", line: 6,
        xml: "<mujoco>\n<worldbody>\n<body>\n<joint/>\n<geom size=\"1\"/>\n<geom type=\"plane\" size=\"1 1 1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "springdamper not positive", variant: |e| matches!(e, MjcfError::BadValue { .. }), element: "<joint>", line: 5,
        xml: "<mujoco>\n<worldbody>\n<body>\n<geom size=\"1\"/>\n<joint springdamper=\"0.1 0\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "nonlinear stiffness", variant: |e| matches!(e, MjcfError::Unsupported { .. }), element: "<joint>", line: 5,
        xml: "<mujoco>\n<worldbody>\n<body>\n<geom size=\"1\"/>\n<joint stiffness=\"1 0.5\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "joint in the world body", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<joint>", line: 3,
        xml: "<mujoco>\n<worldbody>\n<joint/>\n</worldbody>\n</mujoco>" },
    Malformed { what: "range without limited or autolimits", variant: |e| matches!(e, MjcfError::Invalid { .. }), element: "<joint>", line: 6,
        xml: "<mujoco>\n<compiler autolimits=\"false\"/>\n<worldbody>\n<body>\n<geom size=\"1\"/>\n<joint range=\"-1 1\"/>\n</body>\n</worldbody>\n</mujoco>" },
    Malformed { what: "nested default without class", variant: |e| matches!(e, MjcfError::MissingAttribute { .. }), element: "<default>", line: 3,
        xml: "<mujoco>\n<default>\n<default>\n<joint damping=\"1\"/>\n</default>\n</default>\n<worldbody/>\n</mujoco>" },
];

#[test]
fn malformed_inputs_are_rejected_with_element_and_line() {
    for case in MALFORMED {
        let error = match parse_mjcf(case.xml) {
            Ok(_) => panic!("{}: accepted", case.what),
            Err(error) => error,
        };
        let message = error.to_string();
        assert!((case.variant)(&error), "{}: unexpected variant {error:?}", case.what);
        assert!(message.contains(case.element), "{}: {message:?} does not name {}", case.what, case.element);
        assert!(
            message.starts_with(&format!("line {}: ", case.line)),
            "{}: {message:?} is not at line {}",
            case.what,
            case.line
        );
    }
    assert!(MALFORMED.len() >= 25);
}

#[test]
fn not_xml_at_all() {
    let error = parse_mjcf("this is not XML").unwrap_err();
    assert!(matches!(error, MjcfError::Xml { line: 1, .. }), "{error:?}");
    assert!(error.to_string().starts_with("line 1, column 1: not well-formed XML"), "{error}");

    let error = parse_mjcf("<mujoco>\n<worldbody>\n</mujoco>").unwrap_err();
    assert!(matches!(error, MjcfError::Xml { line: 3, .. }), "{error:?}");
}

#[test]
fn error_message_shows_expected_and_found() {
    let xml = "<mujoco>\n<worldbody>\n<body>\n<geom size=\"1\"/>\n<joint name=\"j2\" axis=\"0 1\"/>\n</body>\n</worldbody>\n</mujoco>";
    let error = parse_mjcf(xml).unwrap_err();
    assert_eq!(error.to_string(), "line 5: <joint name=\"j2\">: attribute 'axis' expects 3 numbers, found \"0 1\"");
}

#[test]
fn bodies_fixed_to_the_world_get_their_mesh_mass_but_not_their_height_field_mass() {
    let Imported { vehicle, warnings, .. } = load("static_meshes.xml");
    let names: Vec<&str> = vehicle.bodies.iter().map(|b| b.name.as_str()).collect();
    assert_eq!(names, ["asteroid", "boulder", "fixture", "lander"]);
    let unknown: Vec<&str> = vehicle.bodies.iter().filter(|b| b.mass_unknown).map(|b| b.name.as_str()).collect();
    assert_eq!(unknown, ["fixture"]);
    // The rock's mass is computed (its value is checked against MuJoCo in
    // tests/python/test_mesh_inertia.py).
    assert!(body(&vehicle, "asteroid").inertia.as_ref().is_some_and(|m| m.mass > 0.0));
    // The fixture's box still has its mass; the lander is untouched.
    assert!(body(&vehicle, "fixture").inertia.as_ref().is_some_and(|m| m.mass > 0.0));
    assert_eq!(body(&vehicle, "lander").inertia.as_ref().unwrap().mass, 300.0);
    let shown: Vec<String> = warnings.iter().map(ToString::to_string).collect();
    let unknown_warnings = shown.iter().filter(|w| w.contains("its mass is not computed")).count();
    assert_eq!(unknown_warnings, 1, "{shown:#?}");
    // A subtree sensor may now count the asteroid, but not the height field's
    // uncomputed mass (the variants name the mesh file by its absolute path).
    let path = fixture("static_meshes.xml");
    let rock = path.with_file_name("meshes/rock.obj");
    let xml = std::fs::read_to_string(&path).unwrap().replace("meshes/rock.obj", rock.to_str().unwrap());
    let compile = |subtree: &str| {
        let variant = xml.replace(r#"<subtreecom body="lander"/>"#, &format!(r#"<subtreecom body="{subtree}"/>"#));
        Model::compile(&parse_mjcf(&variant).unwrap().vehicle)
    };
    assert!(compile("asteroid").is_ok());
    let refused = compile("fixture").unwrap_err().to_string();
    assert!(refused.contains("subtree of body 'fixture' holds body 'fixture'"), "{refused}");
    // A force sensor on the world body counts every body's weight: the
    // height field's uncomputed mass would count under gravity, not without.
    let on_the_world = |option: &str| {
        let variant = xml
            .replace("<worldbody>", &format!("{option}<worldbody><site name=\"origin\"/>"))
            .replace(r#"<subtreecom body="lander"/>"#, r#"<force site="origin"/>"#);
        Model::compile(&parse_mjcf(&variant).unwrap().vehicle)
    };
    let refused = on_the_world("").unwrap_err().to_string();
    assert!(
        refused.contains("subtree of the world body holds body 'fixture'") && refused.contains("weight"),
        "{refused}"
    );
    assert!(on_the_world(r#"<option gravity="0 0 0"/>"#).is_ok());
}

#[test]
fn a_missing_mesh_file_is_an_error_naming_the_file() {
    let moving = r#"<mujoco><asset><mesh name="hull" file="no/such/hull.stl"/></asset><worldbody>
        <body name="probe"><freejoint/><geom name="shell" type="mesh" mesh="hull"/></body></worldbody></mujoco>"#;
    let error = parse_mjcf(moving).unwrap_err();
    assert!(matches!(error, MjcfError::Invalid { .. }), "{error:?}");
    let message = error.to_string();
    assert!(message.contains(r#"<mesh name="hull">"#) && message.contains("no/such/hull.stl"), "{message}");
}

#[test]
fn unnamed_elements_cannot_be_named_and_do_not_take_a_file_s_names() {
    // Body 0 is unnamed; the file names body 1 "body0", the name nudyn
    // makes up for body 0. MuJoCo accepts it; so must nudyn.
    let xml = r#"<mujoco><worldbody>
<body><freejoint/><geom size="1"/>
<body name="body0"><joint name="body0_joint0"/><geom size="1"/></body>
<body><joint/><geom size="1"/></body>
</body></worldbody></mujoco>"#;
    let vehicle = parse_mjcf(xml).unwrap().vehicle;
    let names: Vec<&str> = vehicle.bodies.iter().map(|b| b.name.as_str()).collect();
    assert_eq!(names, ["body0_unnamed", "body0", "body2"]);
    let joints: Vec<&str> = vehicle.bodies.iter().flat_map(|b| &b.joints).map(|j| j.name.as_str()).collect();
    assert_eq!(joints, ["body0_joint0_unnamed", "body0_joint0", "body2_joint0"]);
    // A name nudyn made up is no name to refer to.
    let sensed = xml.replace("</mujoco>", r#"<sensor><jointpos joint="body2_joint0"/></sensor></mujoco>"#);
    let refused = parse_mjcf(&sensed).unwrap_err().to_string();
    assert!(refused.contains("unknown joint 'body2_joint0' in sensor"), "{refused}");
    let sensed = xml.replace("</mujoco>", r#"<sensor><subtreecom body="body2"/></sensor></mujoco>"#);
    let refused = parse_mjcf(&sensed).unwrap_err().to_string();
    assert!(refused.contains("unknown body 'body2' in sensor"), "{refused}");
}

/// MuJoCo's schema keeps a weld's or connect's sites apart from the
/// attributes of its body form; the refusal gives MuJoCo's reason.
#[test]
fn sites_take_no_anchor_or_relative_pose() {
    let xml = |equality: &str| {
        format!(
            "<mujoco><worldbody><body name=\"a\"><freejoint/><geom size=\"1\"/><site name=\"s\"/></body>\
             <site name=\"w\"/></worldbody><equality>{equality}</equality></mujoco>"
        )
    };
    let refused = |equality: &str| parse_mjcf(&xml(equality)).unwrap_err().to_string();
    let weld = refused(r#"<weld site1="s" site2="w" relpose="0 0 0 1 0 0 0"/>"#);
    assert!(
        weld.ends_with(
            "'relpose' cannot be given with sites: at most one of ('site1', 'site2'), \
             ('body1', 'body2', 'anchor', 'relpose') can be specified"
        ),
        "{weld}"
    );
    let connect = refused(r#"<connect site1="s" site2="w" anchor="1 0 0"/>"#);
    assert!(
        connect.ends_with("at most one of ('site1', 'site2'), ('body1', 'body2', 'anchor') can be specified"),
        "{connect}"
    );
    // The body form keeps both, and sites alone are fine.
    assert!(parse_mjcf(&xml(r#"<weld body1="a" anchor="0 0 1" relpose="0 0 0 1 0 0 0"/>"#)).is_ok());
    assert!(parse_mjcf(&xml(r#"<weld site1="s" site2="w"/>"#)).is_ok());
}

#[test]
fn replicates_up_to_the_bound_are_read() {
    // 200 × 150 copies of one body of 3 elements: 200 × 4 + 200 × 150 × 3
    // = 90 800 elements counted (the outer replicate's copies of the inner
    // one and of its body included), under the bound of 100 000.
    let xml = r#"<mujoco><worldbody><replicate count="200" offset="1 0 0"><replicate count="150" offset="0 1 0">
        <body><joint/><geom size="0.1"/></body></replicate></replicate></worldbody></mujoco>"#;
    assert_eq!(parse_mjcf(xml).unwrap().vehicle.bodies.len(), 30_000);
    let refused = parse_mjcf(&xml.replace("150", "200")).unwrap_err().to_string();
    assert!(refused.contains("past 100000 elements, the most nudyn reads"), "{refused}");
}

#[test]
fn meshes_nothing_needs_the_mass_of_are_never_read() {
    // The world body's geoms move no mass, a body with an <inertial> takes
    // no mass from its geoms, and an asset no geom names has no use: their
    // files (missing here) are never opened.
    let with_meshes = r#"<mujoco><asset>
        <mesh name="terrain" file="no/such/terrain.stl"/>
        <mesh name="fairing" file="no/such/fairing.obj"/>
        <mesh name="spare" file="no/such/spare.msh"/>
        </asset><worldbody>
        <geom name="ground" type="mesh" mesh="terrain"/>
        <body name="probe"><freejoint/><geom size="0.5"/>
          <body name="shield" pos="0 0 1"><joint axis="1 0 0"/>
            <inertial pos="0 0 0.1" mass="2" diaginertia="0.1 0.1 0.1"/>
            <geom type="mesh" mesh="fairing"/>
          </body>
        </body></worldbody></mujoco>"#;
    let without_meshes = r#"<mujoco><worldbody>
        <body name="probe"><freejoint/><geom size="0.5"/>
          <body name="shield" pos="0 0 1"><joint axis="1 0 0"/>
            <inertial pos="0 0 0.1" mass="2" diaginertia="0.1 0.1 0.1"/>
          </body>
        </body></worldbody></mujoco>"#;
    let Imported { vehicle, warnings, .. } = parse_mjcf(with_meshes).unwrap_or_else(|e| panic!("{e}"));
    let mut expected = parse_mjcf(without_meshes).unwrap().vehicle;
    // The bodies' lines differ with the asset lines.
    for (body, read) in expected.bodies.iter_mut().zip(&vehicle.bodies) {
        body.line = read.line;
        for (joint, read) in body.joints.iter_mut().zip(&read.joints) {
            joint.line = read.line;
        }
    }
    assert_eq!(vehicle, expected);
    let ground = warnings.iter().find(|w| w.element == "geom name=\"ground\"").expect("the world geom's warning");
    assert!(ground.message.contains("fixed to the world"), "{ground}");
    // A geom whose mass counts still needs its file.
    let needed = with_meshes.replace(r#"<inertial pos="0 0 0.1" mass="2" diaginertia="0.1 0.1 0.1"/>"#, "");
    let refused = parse_mjcf(&needed).unwrap_err().to_string();
    assert!(refused.contains("<mesh name=\"fairing\">") && refused.contains("cannot read mesh file"), "{refused}");
}

#[test]
fn a_primitive_fitted_to_a_mesh_reads_it_only_for_a_tendon_that_wraps_around_it() {
    // A named sphere fitted to a mesh whose mass does not count (the world
    // body's, and one in a body with an <inertial>): its file (missing here)
    // is opened only when a spatial tendon wraps around the sphere, which
    // needs its fitted radius and frame.
    let unwrapped = r#"<mujoco><asset><mesh name="hull" file="no/such/hull.stl"/></asset><worldbody>
        <geom name="dome" type="sphere" mesh="hull"/>
        <body name="arm"><joint axis="1 0 0"/>
          <inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/>
          <geom name="knob" type="sphere" mesh="hull"/>
          <site name="a" pos="0 0 2"/><site name="b" pos="0 2 0"/>
        </body></worldbody>
        <tendon><spatial><site site="a"/><site site="b"/></spatial></tendon></mujoco>"#;
    let imported = parse_mjcf(unwrapped).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(imported.vehicle.tendons.len(), 1);
    for wrapped in ["knob", "dome"] {
        let xml = unwrapped.replace(
            r#"<site site="a"/><site site="b"/>"#,
            &format!(r#"<site site="a"/><geom geom="{wrapped}"/><site site="b"/>"#),
        );
        let refused = parse_mjcf(&xml).unwrap_err().to_string();
        assert!(refused.contains("<mesh name=\"hull\">") && refused.contains("cannot read mesh file"), "{refused}");
    }
}

/// What `read` gives, or a panic if it blocks for 10 s.
fn within_seconds<T: Send + 'static>(read: impl FnOnce() -> T + Send + 'static) -> T {
    let (sender, receiver) = std::sync::mpsc::channel();
    std::thread::spawn(move || sender.send(read()));
    receiver.recv_timeout(std::time::Duration::from_secs(10)).expect("the import blocked")
}

#[test]
fn a_named_pipe_for_a_model_mesh_or_included_file_is_refused_not_waited_on() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("mjcf-import-fifo-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    for pipe in ["pipe.stl", "pipe.xml", "model_pipe.xml"] {
        let made = std::process::Command::new("mkfifo").arg(dir.join(pipe)).status().expect("mkfifo runs");
        assert!(made.success(), "mkfifo {pipe}");
    }
    let mesh = r#"<mujoco><asset><mesh name="m" file="pipe.stl"/></asset>
        <worldbody><body><freejoint/><geom type="mesh" mesh="m"/></body></worldbody></mujoco>"#;
    let include = r#"<mujoco><worldbody><include file="pipe.xml"/></worldbody></mujoco>"#;
    for (name, xml) in [("mesh.xml", mesh), ("include.xml", include)] {
        let path = dir.join(name);
        std::fs::write(&path, xml).unwrap();
        let shown = within_seconds(move || load_mjcf(&path).map(|_| ()).unwrap_err().to_string());
        assert!(shown.contains("pipe") && shown.contains("not a regular file"), "{name}: {shown}");
    }
    let pipe = dir.join("model_pipe.xml");
    let error = within_seconds(move || load_mjcf(&pipe).map(|_| ()).unwrap_err());
    assert!(matches!(error, MjcfError::Io { .. }), "{error:?}");
    assert!(with_sources(&error).contains("not a regular file"), "{error:?}");
}

/// The error with its sources, as the CLI shows it.
fn with_sources(error: &MjcfError) -> String {
    let mut shown = error.to_string();
    let mut source = std::error::Error::source(error);
    while let Some(cause) = source {
        shown.push_str(&format!(": {cause}"));
        source = cause.source();
    }
    shown
}

#[test]
fn a_loose_mujoco_solver_is_said_to_differ_from_nudyn_s_exact_one() {
    let xml = |option: &str| {
        format!(
            "<mujoco>\n<option {option}/>\n<worldbody><body><joint range=\"0 1\"/><geom size=\"1\"/></body>\
             </worldbody></mujoco>"
        )
    };
    let solver_warnings = |option: &str| -> Vec<String> {
        let warnings = parse_mjcf(&xml(option)).unwrap().warnings;
        warnings.iter().filter(|w| w.message.contains("solves the constraint problem")).map(|w| w.to_string()).collect()
    };
    assert_eq!(
        solver_warnings(r#"iterations="1""#),
        ["line 2: <option>: nudyn solves the constraint problem exactly; MuJoCo with iterations=1 will differ"]
    );
    let both = solver_warnings(r#"iterations="20" tolerance="0.001""#);
    assert!(
        both.len() == 1 && both[0].ends_with("MuJoCo with iterations=20 and tolerance=0.001 will differ"),
        "{both:?}"
    );
    // MuJoCo's defaults and tighter settings converge as nudyn does.
    assert!(solver_warnings(r#"iterations="100" tolerance="1e-8""#).is_empty());
    assert!(solver_warnings(r#"iterations="500" tolerance="1e-12""#).is_empty());
}
