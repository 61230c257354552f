//! The importer's sensors: what each reads resolves to the named joint,
//! actuator, frame or subtree, in document order; sensordata's layout is
//! MuJoCo's; and every sensor nudyn refuses or MuJoCo's compiler rejects is
//! named with its element, line and reason (the messages MuJoCo 4.0 gives
//! where it rejects the file too). tests/python/test_sensors.py checks the
//! values against MuJoCo.

use nudyn::mjcf::parse_mjcf;
use nudyn::model::{Model, SensorSource};
use nudyn::vehicle::{FrameObject, SensorKind, SensorTarget};

/// A hinge arm with a welded tool (several geoms: inertial axes from
/// MuJoCo's eigen-decomposition), a site, an actuator, and the given sensors.
fn scene(sensors: &str) -> String {
    format!(
        r#"<mujoco>
  <worldbody>
    <site name="anchor"/>
    <body name="arm">
      <joint name="hinge" axis="0 1 0"/>
      <geom type="box" size="0.1 0.2 0.3" pos="0.2 0 0"/>
      <geom type="sphere" size="0.1" pos="0 0.3 0"/>
      <site name="tip" pos="0.4 0 0"/>
      <body name="ball_link" pos="0.5 0 0">
        <joint name="ball" type="ball"/>
        <geom type="sphere" size="0.1"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor name="drive" joint="hinge"/></actuator>
  <sensor>
{sensors}
  </sensor>
</mujoco>"#
    )
}

fn refused(sensors: &str) -> String {
    match parse_mjcf(&scene(sensors)) {
        Err(error) => error.to_string(),
        Ok(imported) => match Model::compile(&imported.vehicle) {
            Err(error) => error.to_string(),
            Ok(_) => panic!("accepted: {sensors}"),
        },
    }
}

#[test]
fn sensors_resolve_in_document_order_with_mujocos_layout() {
    let sensors = r#"
    <jointpos name="angle" joint="hinge"/>
    <ballquat joint="ball"/>
    <framepos objtype="site" objname="tip" reftype="xbody" refname="world"/>
    <subtreecom body="arm"/>
    <actuatorfrc actuator="drive"/>
    <clock/>"#;
    let vehicle = parse_mjcf(&scene(sensors)).unwrap().vehicle;
    let kinds: Vec<SensorKind> = vehicle.sensors.iter().map(|s| s.kind).collect();
    use SensorKind::*;
    assert_eq!(kinds, [JointPos, BallQuat, FramePos, SubtreeCom, ActuatorFrc, Clock]);
    assert_eq!(vehicle.sensors[0].name.as_deref(), Some("angle"));
    assert_eq!(vehicle.sensors[0].target, SensorTarget::Joint("hinge".into()));
    assert_eq!(
        vehicle.sensors[2].target,
        SensorTarget::Frame { object: FrameObject::Site(1), reference: Some(FrameObject::XBody(None)) }
    );
    assert_eq!(vehicle.sensors[3].target, SensorTarget::Subtree(Some(0)));
    assert_eq!(vehicle.sensors[4].target, SensorTarget::Actuator(0));

    let model = Model::compile(&vehicle).unwrap();
    let addresses: Vec<usize> = model.sensors.iter().map(|s| s.adr).collect();
    assert_eq!(addresses, [0, 1, 5, 8, 11, 12]);
    assert_eq!(model.workspace().sensordata.len(), 13);
    assert_eq!(model.sensors[1].source, SensorSource::Joint { dof: 1, qpos: 1 });
    assert_eq!(model.sensors[3].source, SensorSource::Subtree { first: 0, end: 2 });
    assert_eq!(model.sensors[2].target, "site 'tip' in the frame of body 'world'");
}

#[test]
fn force_and_torque_sensors_read_the_subtree_of_their_sites_body() {
    let sensors = r#"<force site="tip"/><torque site="anchor"/>"#;
    let model = Model::compile(&parse_mjcf(&scene(sensors)).unwrap().vehicle).unwrap();
    let range = |k: usize| match model.sensors[k].source {
        SensorSource::Interaction { first, end, .. } => (first, end),
        ref other => panic!("{other:?}"),
    };
    // The arm's subtree holds the ball link too; a site on the world reads every body.
    assert_eq!(range(0), (0, 2));
    assert_eq!(range(1), (0, 2));
    assert_eq!(model.sensors[0].target, "body 'arm' at site 'tip'");
    assert_eq!(model.sensors[1].target, "the world body at site 'anchor'");
    assert_eq!(model.body_masses.len(), 2);
    assert_eq!(model.workspace().body_wrench.len(), 2);
}

#[test]
fn a_vehicle_without_sensors_keeps_no_sensor_data() {
    let model = Model::compile(&parse_mjcf(&scene("")).unwrap().vehicle).unwrap();
    assert!(model.sensors.is_empty() && model.body_masses.is_empty() && model.link_tree_quats.is_empty());
    assert_eq!(model.workspace().sensordata.len(), 0);
}

#[test]
fn sensor_types_nudyn_does_not_compute_are_refused_by_name_and_line() {
    for (element, why) in [
        (r#"<touch site="tip"/>"#, "contacts or geometry"),
        (r#"<rangefinder site="tip"/>"#, "contacts or geometry"),
        (r#"<camprojection site="tip" camera="c"/>"#, "not computed"),
        (r#"<tendonpos tendon="t"/>"#, "unknown tendon 't'"),
        (r#"<e_kinetic/>"#, "energy sensors"),
        (r#"<user dim="1"/>"#, "user and plugin"),
    ] {
        let message = refused(element);
        let tag = element[1..].split([' ', '/']).next().unwrap();
        assert!(message.contains("line 17") && message.contains(tag) && message.contains(why), "{element}: {message}");
    }
    let unknown = refused("<thermometer/>");
    assert!(unknown.contains("thermometer") && unknown.contains("line 17"), "{unknown}");
}

#[test]
fn frames_nudyn_does_not_keep_are_refused() {
    let geom = refused(r#"<framepos objtype="geom" objname="g"/>"#);
    assert!(geom.contains("objtype \"geom\"") && geom.contains("put a site"), "{geom}");
    let camera = refused(r#"<framequat objtype="site" objname="tip" reftype="camera" refname="c"/>"#);
    assert!(camera.contains("reftype \"camera\""), "{camera}");
    // The arm's inertial axes come from MuJoCo's eigen-decomposition, which
    // nudyn reproduces: sensors on them are computed (their values are
    // MuJoCo's in tests/python/test_mesh_inertia.py, and
    // tests/fixtures/sensors/eigen_axes.xml compares them with MuJoCo's).
    for sensor in [
        r#"<framexaxis objtype="body" objname="arm"/>"#,
        r#"<framepos name="p" objtype="site" objname="tip" reftype="body" refname="arm"/>"#,
        r#"<framepos objtype="body" objname="arm"/>"#,
    ] {
        let vehicle = parse_mjcf(&scene(sensor)).unwrap().vehicle;
        assert!(Model::compile(&vehicle).is_ok(), "{sensor}");
    }
}

#[test]
fn what_mujocos_compiler_rejects_is_rejected_with_its_reason() {
    for (element, expected) in [
        (r#"<jointpos joint="ball"/>"#, "joint must be slide or hinge in sensor"),
        (r#"<ballquat joint="hinge"/>"#, "joint must be ball in sensor"),
        (r#"<jointpos joint="nope"/>"#, "unknown joint 'nope' in sensor"),
        (r#"<jointlimitfrc joint="hinge"/>"#, "joint must be limited in sensor"),
        (r#"<jointlimitpos joint="nope"/>"#, "unknown joint 'nope' in sensor"),
        (r#"<gyro site="nope"/>"#, "unknown site 'nope' for sensor"),
        (r#"<force site="nope"/>"#, "unknown site 'nope' for sensor"),
        (r#"<torque/>"#, "site"),
        (r#"<force site="tip" objtype="site"/>"#, "objtype"),
        (r#"<actuatorfrc actuator="nope"/>"#, "unknown actuator 'nope' in sensor"),
        (r#"<subtreecom body="nope"/>"#, "unknown body 'nope' in sensor"),
        (r#"<framequat objtype="site" objname="tip" cutoff="1"/>"#, "cutoff applied to axis or quaternion"),
        (r#"<jointpos joint="hinge" cutoff="-1"/>"#, "negative cutoff"),
        (r#"<jointpos joint="hinge" noise="-1"/>"#, "negative noise"),
        (
            r#"<framepos objtype="site" objname="tip" reftype="site"/>"#,
            "'reftype', 'refname' must be specified together",
        ),
        (r#"<framepos objname="tip"/>"#, "objtype"),
        (r#"<gyro/>"#, "site"),
        (r#"<framelinacc objtype="site" objname="tip" reftype="site" refname="anchor"/>"#, "reftype"),
        (r#"<jointpos joint="hinge" delay="0.1"/>"#, "history"),
        (r#"<jointpos joint="hinge" interval="0.01 0"/>"#, "history"),
        (r#"<framepos objtype="thing" objname="tip"/>"#, "body, xbody, geom, site or camera"),
    ] {
        let message = refused(element);
        assert!(message.contains("line 17") && message.contains(expected), "{element}: {message}");
    }
    let twice = refused("<jointpos name=\"a\" joint=\"hinge\"/>\n<jointvel name=\"a\" joint=\"hinge\"/>");
    assert!(twice.contains("line 18") && twice.contains("\"a\"") && twice.contains("line 17"), "{twice}");
    assert!(parse_mjcf(&scene("<clock/>")).is_ok());
    // The arm's inertial axes are MuJoCo's, so its z axis is measured.
    assert!(
        Model::compile(&parse_mjcf(&scene(r#"<framezaxis objtype="body" objname="arm"/>"#)).unwrap().vehicle).is_ok()
    );
}

#[test]
fn the_sensor_flag_leaves_sensordata_at_zero_as_mujoco_does() {
    let sensors = r#"<jointpos joint="hinge"/><framepos objtype="site" objname="tip"/><clock/>"#;
    let read = |xml: String| {
        let model = Model::compile(&parse_mjcf(&xml).unwrap().vehicle).unwrap();
        let mut ws = model.workspace();
        let mut theta = model.qpos0.clone();
        theta[0] = 0.4;
        ws.set_configuration(&model, &theta).unwrap();
        ws.set_qvel(&model, &vec![0.3; model.nv]).unwrap();
        ws.compute_sensors(&model, &vec![0.0; model.nv], &vec![0.0; model.actuators.len()], 2.0).unwrap();
        (model.sensors.len(), ws.sensordata.iter().copied().collect::<Vec<f64>>())
    };
    let (count, on) = read(scene(sensors));
    assert!(count == 3 && on.iter().filter(|v| **v != 0.0).count() >= 3, "{on:?}");
    let disabled = scene(sensors).replace("<mujoco>", r#"<mujoco><option><flag sensor="disable"/></option>"#);
    let (count, off) = read(disabled);
    // The layout stays (sensordata keeps its entries), the values stay 0.
    assert_eq!((count, off.len()), (3, on.len()));
    assert!(off.iter().all(|v| *v == 0.0), "{off:?}");
}

/// Independent of MuJoCo: an arm turning about a vertical axis, at rest
/// under gravity, hangs on its base, whose force sensor then reads the
/// weight it carries straight up and whose torque sensor that weight's
/// moment about the site; a free-falling body reads nothing.
#[test]
fn force_and_torque_sensors_read_the_weight_a_body_carries() {
    let xml = r#"<mujoco><worldbody>
      <body name="base" pos="0 0 1">
        <joint name="turn" axis="0 0 1"/>
        <inertial pos="0.1 0 0" mass="2" diaginertia="0.1 0.1 0.1"/>
        <site name="root" pos="0 0 0.1"/>
        <body name="arm" pos="0.5 0 0"><inertial pos="0.2 0.1 0" mass="3" diaginertia="0.1 0.1 0.1"/></body>
      </body>
      <body name="drifter" pos="3 0 0"><freejoint/><inertial pos="0 0 0" mass="5" diaginertia="1 1 1"/>
        <site name="on_drifter" pos="0.2 0 0"/></body>
    </worldbody>
    <sensor><force site="root"/><torque site="root"/><force site="on_drifter"/><torque site="on_drifter"/></sensor>
    </mujoco>"#;
    let model = Model::compile(&parse_mjcf(xml).unwrap().vehicle).unwrap();
    let mut ws = model.workspace();
    ws.set_configuration(&model, &model.qpos0).unwrap();
    ws.set_qvel(&model, &vec![0.0; model.nv]).unwrap();
    ws.compute_sensors(&model, &vec![0.0; model.nv], &[], 0.0).unwrap();
    let s = ws.sensordata.as_slice();
    let weight = 5.0 * 9.81;
    // The bodies' centre of mass relative to the site: (2·0.1 + 3·0.7, 3·0.1, −0.1)/5.
    let arm = [(2.0 * 0.1 + 3.0 * 0.7) / 5.0, 3.0 * 0.1 / 5.0, -0.1];
    let expected = [0.0, 0.0, weight, arm[1] * weight, -arm[0] * weight, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    for (k, (value, expected)) in s.iter().zip(expected).enumerate() {
        assert!((value - expected).abs() < 1e-12, "sensordata[{k}] = {value}, expected {expected}");
    }
}

/// A free base with a two-link arm, a spatial tendon from the base to the
/// second link with the given attributes, and a force sensor on `site`.
fn tendon_scene(tendon: &str, site: &str) -> String {
    format!(
        r#"<mujoco>
  <worldbody>
    <body name="base">
      <freejoint/>
      <geom type="box" size="0.3 0.3 0.3"/>
      <site name="anchor" pos="0.3 0 0.1"/>
      <body name="upper" pos="0.4 0 0">
        <joint axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.03"/>
        <site name="elbow_site" pos="0 0 0"/>
        <site name="upper_mid" pos="0.2 0 0.03"/>
        <body name="lower" pos="0.4 0 0">
          <joint axis="0 1 0"/>
          <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
          <site name="wrist" pos="0 0 0"/>
          <site name="lower_mid" pos="0.15 0 0.03"/>
        </body>
      </body>
    </body>
  </worldbody>
  <tendon>
    <spatial name="cable" {tendon}><site site="anchor"/><site site="upper_mid"/><site site="lower_mid"/></spatial>
  </tendon>
  <sensor><force site="{site}"/></sensor>
</mujoco>"#
    )
}

#[test]
fn a_force_sensor_whose_subtree_a_pulling_spatial_tendon_crosses_compiles() {
    // MuJoCo 4.0 counts the tendon's forces at its path points, and so does
    // nudyn (tests/python/test_force_torque.py compares them with MuJoCo);
    // this file was refused before.
    let compiled = |tendon: &str, site: &str| Model::compile(&parse_mjcf(&tendon_scene(tendon, site)).unwrap().vehicle);
    for tendon in [
        r#"stiffness="40""#,
        r#"damping="2""#,
        r#"frictionloss="1""#,
        r#"range="0 2" limited="true""#,
        r#"armature="0.1""#,
    ] {
        for site in ["elbow_site", "wrist", "anchor"] {
            assert!(compiled(tendon, site).is_ok(), "{tendon} {site}");
        }
    }
}
