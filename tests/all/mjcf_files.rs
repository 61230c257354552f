//! Model files as their authors publish them: `<include>`d files, `<frame>`s,
//! mocap bodies and `<compiler fusestatic>`, read as MuJoCo 4.0 reads them.
//! The numbers (poses, inertias, qacc, sensordata) are compared with
//! MuJoCo's in tests/python through the fixtures; here, the structure and
//! the refusals.

use std::path::{Path, PathBuf};

use nudyn::mjcf::{Imported, MjcfError, keyframe, load_mjcf, parse_mjcf};
use nudyn::vehicle::Vehicle;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/mjcf").join(name)
}

fn load(name: &str) -> Imported {
    load_mjcf(&fixture(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The vehicle with every line set to 0, to compare models written differently.
fn without_lines(mut vehicle: Vehicle) -> Vehicle {
    for body in &mut vehicle.bodies {
        body.line = 0;
        body.joints.iter_mut().for_each(|j| j.line = 0);
    }
    vehicle.sites.iter_mut().for_each(|s| s.line = 0);
    vehicle.actuators.iter_mut().for_each(|a| a.line = 0);
    vehicle.sensors.iter_mut().for_each(|s| s.line = 0);
    vehicle.equalities.iter_mut().for_each(|e| e.line = 0);
    vehicle
}

/// includes.xml written as one file.
const INCLUDES_MERGED: &str = r#"<mujoco model="includes">
  <compiler angle="radian"/>
  <option gravity="0 0 0"/>
  <default>
    <joint damping="0.5"/>
    <default class="link">
      <geom type="capsule" size="0.05" density="2000"/>
    </default>
  </default>
  <worldbody>
    <body name="bus" pos="0.1 0 0">
      <freejoint/>
      <geom type="box" size="0.5 0.4 0.3" mass="100"/>
      <body name="link1" pos="0.5 0 0" euler="0 0 0.3" childclass="link">
        <joint name="shoulder" axis="0 0 1"/>
        <geom fromto="0 0 0 0.4 0 0"/>
        <camera name="arm_camera" pos="0.2 0 0.1"/>
        <body name="link2" pos="0.4 0 0">
          <joint name="wrist" axis="0 1 0"/>
          <geom fromto="0 0 0 0.3 0 0"/>
          <site name="tip" pos="0.3 0 0"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="shoulder_motor" joint="shoulder"/>
    <motor name="wrist_motor" joint="wrist" gear="2"/>
  </actuator>
  <equality>
    <joint name="coupling" joint1="wrist" joint2="shoulder" polycoef="0 0.5 0 0 0"/>
  </equality>
</mujoco>"#;

#[test]
fn included_files_merge_in_place_as_if_written_in_the_main_file() {
    let Imported { vehicle, warnings, .. } = load("includes.xml");
    let merged = parse_mjcf(INCLUDES_MERGED).unwrap().vehicle;
    assert_eq!(without_lines(vehicle.clone()), without_lines(merged));
    // Lines are those of each element's own file.
    let wrist = &vehicle.bodies[2];
    assert_eq!((wrist.name.as_str(), wrist.line, wrist.joints[0].line), ("link2", 2, 3));
    assert_eq!(vehicle.sites[0].line, 5);
    assert_eq!(vehicle.actuators[1].line, 4);
    assert_eq!(vehicle.equalities[0].line, 3);
    // A warning from an included file names it.
    let camera = warnings.iter().find(|w| w.element.contains("arm_camera")).unwrap();
    assert_eq!(camera.line, 5);
    assert!(camera.file.as_deref().is_some_and(|f| f.ends_with("include/arm.xml")), "{camera:?}");
    assert!(camera.to_string().contains("include/arm.xml: line 5: <camera name=\"arm_camera\">"), "{camera}");
}

/// The error for a file of include/bad/, unwrapped from the included file it
/// is in when `in_file` names one.
fn refusal(name: &str, in_file: Option<&str>) -> (MjcfError, String) {
    let error = load_mjcf(&fixture("include/bad").join(name)).unwrap_err();
    let shown = error.to_string();
    let inner = match (error, in_file) {
        (MjcfError::Included { path, error }, Some(file)) => {
            assert!(path.ends_with(file), "{shown}: not in {file}");
            *error
        }
        (error, None) => error,
        (error, Some(file)) => panic!("{error:?} does not say it is in {file}"),
    };
    (inner, shown)
}

fn assert_at(error: &MjcfError, line: u32, element: &str) {
    match error {
        MjcfError::Invalid { line: l, element: e, .. }
        | MjcfError::UnknownAttribute { line: l, element: e, .. }
        | MjcfError::DuplicateName { line: l, element: e, .. }
        | MjcfError::MissingAttribute { line: l, element: e, .. } => {
            assert_eq!((*l, e.as_str()), (line, element), "{error}")
        }
        other => panic!("unexpected {other:?}"),
    }
}

#[test]
fn an_include_cycle_is_refused_where_it_closes() {
    let (error, shown) = refusal("cycle.xml", Some("cycle_part.xml"));
    assert_at(&error, 3, "include");
    assert!(shown.contains("include cycle:") && shown.contains("cycle.xml includes"), "{shown}");
}

#[test]
fn a_missing_file_is_refused_with_the_places_looked_in() {
    let (error, shown) = refusal("missing.xml", Some("missing_part.xml"));
    assert_at(&error, 3, "include");
    assert!(shown.contains("cannot open 'nowhere.xml'"), "{shown}");
    let looked = Path::new("include").join("bad").join("nowhere.xml");
    assert!(shown.contains(&looked.display().to_string()), "{shown}");
}

#[test]
fn a_file_included_twice_is_refused_as_mujoco_refuses_it() {
    let (error, shown) = refusal("twice.xml", None);
    assert_at(&error, 4, "include");
    assert!(shown.contains("'part.xml' is already included at line 3"), "{shown}");
}

#[test]
fn an_include_with_children_or_without_elements_is_refused() {
    let (error, _) = refusal("children.xml", None);
    assert_at(&error, 3, "include");
    let (error, shown) = refusal("empty.xml", None);
    assert_at(&error, 3, "include");
    assert!(shown.contains("has no element below its root <mujoco>"), "{shown}");
}

#[test]
fn errors_in_an_included_file_name_it_and_its_line() {
    let (error, shown) = refusal("error_inside.xml", Some("typo_part.xml"));
    assert_at(&error, 3, "joint name=\"j\"");
    assert!(shown.ends_with("typo_part.xml: line 3: <joint name=\"j\">: unknown attribute 'axiz'"), "{shown}");

    let (error, shown) = refusal("malformed.xml", Some("malformed_part.xml"));
    assert!(matches!(error, MjcfError::Xml { line: 4, .. }), "{shown}");

    // A name used in two files says where the first is.
    let (error, shown) = refusal("duplicate.xml", Some("part.xml"));
    assert_at(&error, 2, "body name=\"part\"");
    assert!(shown.contains("body name \"part\" is already used at line 3 of"), "{shown}");
}

#[test]
fn mesh_files_are_found_where_mujoco_looks_for_them() {
    // In meshdir, below the model's directory (cargo runs the tests in the
    // package's), which wins over assetdir: the tetrahedron is read there,
    // and its mass is its volume (det[v2-v1, v3-v1, v4-v1] / 6, of the
    // single-precision vertices MuJoCo keeps) at 1000 kg/m³.
    let xml = |assetdir: &str, meshdir: &str| {
        format!(
            r#"<mujoco><compiler assetdir="{assetdir}" meshdir="{meshdir}"/>
            <asset><mesh file="rock.obj"/></asset>
            <worldbody><body><freejoint/><geom type="mesh" mesh="rock"/></body></worldbody></mujoco>"#
        )
    };
    let vehicle = parse_mjcf(&xml("elsewhere", "tests/fixtures/mjcf/meshes")).unwrap().vehicle;
    let v = |x: f64| f64::from(x as f32);
    let volume = (v(1.2) * (v(0.9) * v(1.1) - v(0.1) * v(0.3)) - v(0.1) * (v(0.3) * v(1.1) - v(0.1) * v(0.4))) / 6.0;
    let mass = vehicle.bodies[0].inertia.as_ref().unwrap().mass;
    assert!((mass - 1000.0 * volume).abs() < 1e-10, "{mass}");
    // Not in meshdir: the error names the file looked for.
    let shown = parse_mjcf(&xml("tests/fixtures/mjcf/meshes", "elsewhere")).unwrap_err().to_string();
    assert!(shown.contains(&Path::new("elsewhere").join("rock.obj").display().to_string()), "{shown}");
    // Not there: beside the included file that names it.
    let (_, shown) = refusal("mesh.xml", None);
    let expected = Path::new("include/bad/sub").join("hull.stl");
    assert!(shown.contains(&expected.display().to_string()), "{shown}");
}

/// Poses compared to round-off (the numbers themselves are MuJoCo's in
/// tests/python through the fixtures).
fn assert_pose(what: &str, pos: &nudyn::math::Vec3, expected: [f64; 3]) {
    let expected = nudyn::math::Vec3::from(expected);
    assert!((pos - expected).amax() < 1e-12, "{what}: {pos} != {expected}");
}

#[test]
fn frames_place_their_children_and_vanish() {
    let xml = r#"<mujoco><compiler angle="radian"/>
        <default><default class="heavy"><geom density="8000"/></default></default>
        <worldbody>
          <frame pos="1 0 0" euler="0 0 1.5707963267948966">
            <site name="s" pos="1 0 0"/>
            <frame pos="0 0 1" childclass="heavy">
              <body name="b" pos="1 0 0">
                <joint name="j" pos="0 0 0" axis="1 0 0"/>
                <frame pos="0 0 2"><geom size="0.1"/></frame>
              </body>
            </frame>
          </frame>
        </worldbody></mujoco>"#;
    let vehicle = parse_mjcf(xml).unwrap().vehicle;
    // The frame turns x into y: the site at (1, 1, 0), the body at (1, 1, 1).
    assert_pose("site", &vehicle.sites[0].pos, [1.0, 1.0, 0.0]);
    let body = &vehicle.bodies[0];
    assert_pose("body", &body.pos, [1.0, 1.0, 1.0]);
    assert!((body.quat.angle() - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    // The body's own joint is in its frame; its geom is 2 up, of the frame's class.
    assert_pose("joint axis", &body.joints[0].axis, [1.0, 0.0, 0.0]);
    let mass = body.inertia.as_ref().unwrap();
    assert_pose("centre of mass", &mass.com, [0.0, 0.0, 2.0]);
    assert!((mass.mass - 8000.0 * 4.0 / 3.0 * std::f64::consts::PI * 1e-3).abs() < 1e-9);
}

#[test]
fn a_mocap_body_is_fixed_to_the_world_where_the_file_puts_it() {
    let Imported { vehicle, .. } = load("mocap.xml");
    let target = &vehicle.bodies[0];
    assert_eq!((target.name.as_str(), target.parent, target.joints.len()), ("target", None, 0));
    assert_pose("target", &target.pos, [1.0, 2.0, 3.0]);
    // Below another body, or with a joint, MuJoCo refuses it.
    let nested = r#"<mujoco><worldbody><body name="a"><freejoint/><geom size="1"/>
        <body name="m" mocap="true"><geom size="1"/></body></body></worldbody></mujoco>"#;
    let shown = parse_mjcf(nested).unwrap_err().to_string();
    assert!(shown.contains("line 2: <body name=\"m\">: mocap body 'm' is not a fixed child of world"), "{shown}");
}

#[test]
fn an_equality_constraint_is_read_and_a_weld_to_a_mocap_body_is_refused_as_such() {
    let with = |constraint: &str| {
        format!(
            r#"<mujoco><worldbody><body name="m" mocap="true"><geom size="1"/><site name="ms"/></body>
            <body name="a"><freejoint/><geom size="1"/></body>
            <body name="b"><joint name="j1"/><geom size="1"/><body><joint name="j2"/><geom size="1"/></body></body>
            </worldbody><equality>{constraint}</equality></mujoco>"#
        )
    };
    let coupled = parse_mjcf(&with(r#"<joint joint1="j1" joint2="j2"/>"#)).unwrap().vehicle;
    assert_eq!(coupled.equalities.len(), 1);
    for weld in [r#"<weld body1="a" body2="m"/>"#, r#"<weld site1="ms" site2="ms"/>"#] {
        let shown = parse_mjcf(&with(weld)).unwrap_err().to_string();
        assert!(shown.contains("<equality>/<weld> to mocap body 'm': nudyn takes no mocap poses"), "{shown}");
    }
}

#[test]
fn gravity_compensation_is_read_as_mujoco_reads_it() {
    // actuatorgravcomp from a default class and on the joint itself;
    // gravcomp on a body only (it has no default). MuJoCo's passive stage,
    // which computes the compensation, is skipped when both springs and
    // dampers are disabled: then there is none.
    let with = |flag: &str| {
        format!(
            r#"<mujoco><option>{flag}</option>
            <default><default class="servo"><joint actuatorgravcomp="true"/></default></default>
            <worldbody><body name="a" gravcomp="0.5"><freejoint/><geom size="1"/>
              <body name="b" gravcomp="-2"><joint name="b1" class="servo"/><joint name="b2" actuatorgravcomp="false" class="servo"/><geom size="1"/>
                <body name="c"><joint name="c" type="ball"/><geom size="1"/></body></body></body>
            </worldbody></mujoco>"#
        )
    };
    let vehicle = parse_mjcf(&with("")).unwrap().vehicle;
    let gravcomp: Vec<f64> = vehicle.bodies.iter().map(|b| b.gravcomp).collect();
    assert_eq!(gravcomp, [0.5, -2.0, 0.0]);
    let routed: Vec<(&str, bool)> =
        vehicle.bodies.iter().flat_map(|b| &b.joints).map(|j| (j.name.as_str(), j.actuator_gravcomp)).collect();
    assert_eq!(routed, [("a_joint0", false), ("b1", true), ("b2", false), ("c", false)]);
    for (flag, kept) in [
        (r#"<flag spring="disable"/>"#, true),
        (r#"<flag damper="disable"/>"#, true),
        (r#"<flag spring="disable" damper="disable"/>"#, false),
    ] {
        let vehicle = parse_mjcf(&with(flag)).unwrap().vehicle;
        assert_eq!(vehicle.bodies[0].gravcomp, if kept { 0.5 } else { 0.0 }, "{flag}");
    }
}

#[test]
fn a_ctrlrange_beside_inheritrange_zero_is_accepted_as_mujoco_accepts_it() {
    let with = |inheritrange: &str| {
        format!(
            r#"<mujoco><worldbody><body><joint name="j" range="-1 1"/><geom size="1"/></body></worldbody>
            <actuator><position joint="j" kp="10" ctrlrange="-0.5 0.5" inheritrange="{inheritrange}"/></actuator></mujoco>"#
        )
    };
    let vehicle = parse_mjcf(&with("0")).unwrap().vehicle;
    assert_eq!(vehicle.actuators[0].ctrl_range, Some([-0.5, 0.5]));
    let shown = parse_mjcf(&with("1")).unwrap_err().to_string();
    assert!(shown.ends_with("ctrlrange and inheritrange cannot both be defined"), "{shown}");
}

#[test]
fn keyframes_of_the_wrong_size_are_refused_as_mujoco_refuses_them() {
    assert!(load_mjcf(&fixture("mocap.xml")).is_ok());
    let xml = std::fs::read_to_string(fixture("mocap.xml")).unwrap();
    for (good, bad, message) in [
        ("qpos=\"0.1 0 0 1 1 0 0 0\"", "qpos=\"0.1 0 0 1\"", "invalid qpos size, expected 8, got 4"),
        ("qvel=\"0 0 0 0 0 0 0.1\"", "qvel=\"0\"", "invalid qvel size, expected 7, got 1"),
        ("mpos=\"1 2 3\"", "mpos=\"1 2 3 4 5 6\"", "invalid mpos size, expected 3, got 6"),
        ("mquat=\"1 0 0 0\"", "mquat=\"1 0 0 0\" ctrl=\"1\"", "invalid ctrl size, expected 0, got 1"),
        ("mquat=\"1 0 0 0\"", "mquat=\"1 0 0 0\" act=\"1\"", "invalid act size, expected 0, got 1"),
    ] {
        let shown = parse_mjcf(&xml.replace(good, bad)).unwrap_err().to_string();
        assert!(shown.ends_with(&format!("<key name=\"start\">: {message}")), "{shown}");
    }
}

#[test]
fn keyframes_are_kept_and_found_by_name_or_index() {
    let imported = load("mocap.xml");
    let [start] = imported.keyframes.as_slice() else { panic!("{:?}", imported.keyframes) };
    assert_eq!(start.name.as_deref(), Some("start"));
    assert_eq!(start.qpos.as_deref(), Some(&[0.1, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0][..]));
    assert_eq!(start.qvel.as_deref(), Some(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.1][..]));
    assert_eq!((start.act.as_ref(), start.ctrl.as_ref(), start.time), (None, None, 0.0));
    assert!(start.places_mocap_bodies);
    assert_eq!(start.line, 22);
    assert_eq!(keyframe::find(&imported.keyframes, "start").unwrap(), start);
    assert_eq!(keyframe::find(&imported.keyframes, "0").unwrap(), start);
    let missing = keyframe::find(&imported.keyframes, "home").unwrap_err().to_string();
    assert_eq!(missing, "the model has no keyframe \"home\" (its keyframes: \"start\")");
    // An unnamed key is found by its index; an empty vector counts as not given.
    let unnamed = parse_mjcf(
        r#"<mujoco><worldbody><body><joint/><geom size="1"/></body></worldbody>
        <keyframe><key time="2" qpos=""/><key qpos="0.5" qvel="1"/></keyframe></mujoco>"#,
    )
    .unwrap();
    let second = keyframe::find(&unnamed.keyframes, "1").unwrap();
    assert_eq!((second.qpos.as_deref(), second.qvel.as_deref()), (Some(&[0.5][..]), Some(&[1.0][..])));
    assert_eq!((unnamed.keyframes[0].qpos.as_ref(), unnamed.keyframes[0].time), (None, 2.0));
    assert!(!second.places_mocap_bodies);
    let none = keyframe::find(&unnamed.keyframes, "2").unwrap_err().to_string();
    assert!(none.ends_with("(its keyframes: 0, 1)"), "{none}");
}

#[test]
fn fusestatic_merges_bodies_without_joints_unless_something_names_them() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/sensors/fusestatic.xml");
    let vehicle = load_mjcf(&path).unwrap().vehicle;
    let names: Vec<&str> = vehicle.bodies.iter().map(|b| b.name.as_str()).collect();
    // The stand into the world, the panel and mast into the bus; the camera
    // mount stays (a sensor names it), and so do the boom and the unnamed
    // pod (force and torque sensors read their sites).
    assert_eq!(names, ["bus", "antenna", "camera_mount", "boom", "body7"]);
    assert_eq!(vehicle.bodies[1].parent, Some(0));
    let bus = vehicle.bodies[0].inertia.as_ref().unwrap();
    assert!((bus.mass - 55.5).abs() < 1e-12, "{}", bus.mass);
    // The panel's site moved to the bus, where it was.
    assert_eq!(vehicle.sites[0].body, Some(0));
    // Without fusestatic, every body stays.
    let xml = std::fs::read_to_string(&path).unwrap().replace("fusestatic=\"true\"", "fusestatic=\"false\"");
    assert_eq!(parse_mjcf(&xml).unwrap().vehicle.bodies.len(), 8);
    // A camera aiming at the panel keeps it.
    let aimed = xml.replace("fusestatic=\"false\"", "fusestatic=\"true\"").replace(
        "<body name=\"camera_mount\" pos=\"-0.5 0 0\">",
        "<body name=\"camera_mount\" pos=\"-0.5 0 0\"><camera mode=\"targetbody\" target=\"panel\"/>",
    );
    let kept: Vec<String> = parse_mjcf(&aimed).unwrap().vehicle.bodies.into_iter().map(|b| b.name).collect();
    assert_eq!(kept, ["bus", "panel", "antenna", "camera_mount", "boom", "body7"]);
}

#[test]
fn alignfree_moves_a_free_body_frame_to_its_inertial_frame() {
    let xml = r#"<mujoco><compiler alignfree="true"/><worldbody>
        <body name="b" pos="1 0 0"><freejoint/><geom size="0.1" pos="0.5 0 0"/><site name="s" pos="0.5 0 1"/></body>
        <body name="kept" pos="0 1 0"><freejoint align="false"/><geom size="0.1" pos="0.5 0 0"/></body>
        </worldbody></mujoco>"#;
    let vehicle = parse_mjcf(xml).unwrap().vehicle;
    let aligned = &vehicle.bodies[0];
    assert_pose("aligned body", &aligned.pos, [1.5, 0.0, 0.0]);
    assert_pose("its centre of mass", &aligned.inertia.as_ref().unwrap().com, [0.0, 0.0, 0.0]);
    assert_pose("its site", &vehicle.sites[0].pos, [0.0, 0.0, 1.0]);
    assert_pose("body left as written", &vehicle.bodies[1].pos, [0.0, 1.0, 0.0]);
}

#[test]
fn a_name_inside_a_replicate_copies_the_sensors_and_actuators_naming_it_as_written() {
    // MuJoCo 4.0 copies a sensor or actuator for each copy of what it names
    // (tests/python/test_replicate.py compares the copies with MuJoCo's).
    let with = |sections: &str| {
        format!(
            r#"<mujoco><worldbody><body name="bus"><freejoint/><geom size="1"/><site name="base"/>
            <replicate count="12" sep="_"><body name="arm"><joint/><geom size="1"/><site name="tip"/></body></replicate>
            <replicate count="2" sep="+"><body name="leg"><joint/><geom size="1"/><site name="foot"/></body></replicate>
            </body></worldbody>{sections}</mujoco>"#
        )
    };
    let vehicle =
        parse_mjcf(&with(r#"<sensor><framepos name="p" objtype="site" objname="tip"/></sensor>"#)).unwrap().vehicle;
    let names: Vec<&str> = vehicle.sensors.iter().filter_map(|s| s.name.as_deref()).collect();
    assert_eq!(names.len(), 12);
    assert_eq!(names[..3], ["p_00", "p_01", "p_02"]);
    let bodies: Vec<&str> = vehicle.bodies.iter().map(|b| b.name.as_str()).collect();
    assert_eq!(bodies[1..4], ["arm_00", "arm_01", "arm_02"]);

    // A tendon is not copied: refused, naming the copies.
    let tendon = r#"<tendon><spatial><site site="base"/><site site="tip"/></spatial></tendon>"#;
    let shown = parse_mjcf(&with(tendon)).unwrap_err().to_string();
    assert!(shown.contains("unknown site 'tip' for tendon: it is inside a <replicate>"), "{shown}");
    assert!(shown.contains("named 'tip_00' and so on"), "{shown}");
    assert!(shown.contains("not tendons and equalities"), "{shown}");

    // What MuJoCo drops (an actuator whose reference site lies outside the
    // replicate) or refuses (a sensor naming objects of two replicates side
    // by side) is refused.
    let outside = r#"<actuator><motor site="tip" refsite="base" gear="1 0 0 0 0 0"/></actuator>"#;
    let shown = parse_mjcf(&with(outside)).unwrap_err().to_string();
    assert!(shown.contains("refsite 'base' lies outside the <replicate> (line 2)"), "{shown}");
    assert!(shown.contains("MuJoCo 4.0 leaves such an actuator out"), "{shown}");
    let two = r#"<sensor><framepos objtype="site" objname="tip" reftype="site" refname="foot"/></sensor>"#;
    let shown = parse_mjcf(&with(two)).unwrap_err().to_string();
    assert!(shown.contains("two <replicate>s side by side (lines 2 and 3)"), "{shown}");
}

/// A scratch directory of this test binary's, emptied.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("mjcf-files-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn backslashes_in_file_names_are_separators_as_mujoco_reads_them() {
    // MuJoCo 4.0 on Linux turns every '\' of an asset's file name, of
    // meshdir and of an include's file into '/' before opening it, even
    // when a file of that literal name exists (found by trying it).
    let dir = scratch("backslash");
    let meshes = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/meshes");
    std::fs::create_dir_all(dir.join("sub/meshes")).unwrap();
    std::fs::create_dir_all(dir.join("parts")).unwrap();
    std::fs::copy(meshes.join("tetrahedron.stl"), dir.join("sub/meshes/tetrahedron.stl")).unwrap();
    // A decoy whose name holds the backslashes: not the one MuJoCo reads.
    std::fs::copy(meshes.join("cube.stl"), dir.join("sub\\meshes\\tetrahedron.stl")).unwrap();
    std::fs::write(
        dir.join("parts/arm.xml"),
        r#"<mujoco><body name="arm" pos="1 0 0"><joint/><geom size="0.1"/></body></mujoco>"#,
    )
    .unwrap();
    let model = |meshdir: &str, file: &str, include: &str| {
        let xml = format!(
            r#"<mujoco><compiler meshdir="{meshdir}"/><asset><mesh name="m" file="{file}"/></asset>
            <worldbody><body name="hull"><freejoint/><geom type="mesh" mesh="m"/></body>
            <include file="{include}"/></worldbody></mujoco>"#
        );
        let path = dir.join("model.xml");
        std::fs::write(&path, xml).unwrap();
        load_mjcf(&path).unwrap_or_else(|e| panic!("{meshdir} {file} {include}: {e}")).vehicle
    };
    let expected = without_lines(model("", "sub/meshes/tetrahedron.stl", "parts/arm.xml"));
    assert_eq!(without_lines(model("", r"sub\meshes\tetrahedron.stl", r"parts\arm.xml")), expected);
    assert_eq!(without_lines(model(r"sub\meshes", "tetrahedron.stl", "parts/arm.xml")), expected);
    assert_eq!(without_lines(model("sub", r"meshes\tetrahedron.stl", "parts/arm.xml")), expected);
    // The tetrahedron, not the decoy cube of edge 0.5 (125 kg at 1000 kg/m³).
    let mass = expected.bodies[0].inertia.as_ref().unwrap().mass;
    assert!(mass > 0.0 && (mass - 125.0).abs() > 1.0, "{mass}");
}
