//! Sites at the nodes of a flexible body (docs/flexible.md, "Sites at
//! nodes"): a site within 1 µm of a node moves with that node's
//! deformation, and the frame sensors on it read the node's motion.
//! Fixture: tests/fixtures/flex/bench_sensors.xml (sites "middle" and
//! "middle_turned" at bench.json's node "middle", "beside" at no node).
//!
//! Checked: the node site's position and orientation against the bench's frame
//! (read by the site "beside") displaced by the modal file's shapes at the
//! node; its velocities and accelerations against central differences of
//! its position, orientation and velocities along an RK4 trajectory; the
//! turned site's gyro, velocimeter and accelerometer as the node site's world
//! readings in its axes.

use std::path::Path;

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use nudyn::integrate::{Input, Method, Settings, Simulation};
use nudyn::mjcf::load_mjcf;
use nudyn::model::{Model, NodeSite, SensorSource};

use crate::common::Rng;

fn fixture() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/flex/bench_sensors.xml")
}

/// sensordata at (θ, ν), ε = 0.
fn sensors(model: &Model, theta: &[f64], nu: &[f64]) -> Vec<f64> {
    let mut ws = model.workspace();
    ws.set_configuration(model, theta).unwrap();
    ws.set_nu(model, nu).unwrap();
    let zero = vec![0.0; model.nv];
    ws.compute_sensors(model, &zero, &[], 0.0).unwrap();
    ws.sensordata.as_slice().to_vec()
}

fn v3(s: &[f64], at: usize) -> Vector3<f64> {
    Vector3::new(s[at], s[at + 1], s[at + 2])
}

fn quat(s: &[f64], at: usize) -> UnitQuaternion<f64> {
    UnitQuaternion::new_unchecked(Quaternion::new(s[at], s[at + 1], s[at + 2], s[at + 3]))
}

// sensordata's layout (the fixture's sensors in order).
const POS: usize = 0;
const QUAT: usize = 3;
const LINVEL: usize = 7;
const ANGVEL: usize = 10;
const LINACC: usize = 13;
const ANGACC: usize = 16;
const TURNED_QUAT: usize = 19;
const GYRO: usize = 23;
const VELOCIMETER: usize = 26;
const ACCELEROMETER: usize = 29;
const BESIDE_POS: usize = 32;
const BESIDE_QUAT: usize = 35;

#[test]
fn a_site_at_a_node_rides_the_node_and_its_sensors_read_the_nodes_motion() {
    let model = Model::compile(&load_mjcf(&fixture()).unwrap().vehicle).unwrap();
    let [flexible] = model.flexible.as_slice() else { panic!() };
    let node = flexible.modal.node("middle").unwrap();
    let carried_by = |sensor: usize| match &model.sensors[sensor].source {
        SensorSource::Frame { object, .. } => object.node,
        other => panic!("{other:?}"),
    };
    let at_node = Some(NodeSite { flexible: 0, node });
    // framepos of "middle", framequat of "middle_turned", framepos of "beside".
    assert_eq!((carried_by(0), carried_by(6), carried_by(10)), (at_node, at_node, None));

    let mut rng = Rng::new(49);
    for case in 0..4 {
        let mut theta = model.qpos0.clone();
        let q = UnitQuaternion::from_scaled_axis(rng.vec3(1.0));
        theta[3..7].copy_from_slice(&[q.w, q.i, q.j, q.k]);
        theta[7] = rng.uniform(-1.0, 1.0);
        for k in 0..3 {
            theta[8 + k] = rng.uniform(-0.1, 0.1);
        }
        let nu = rng.vec(model.nv, 0.8);
        let here = sensors(&model, &theta, &nu);

        // Position and orientation: the bench's frame (read at "beside"),
        // displaced and turned by the node's shapes.
        let eta = &theta[8..11];
        let modes = &flexible.modal.modes;
        let displacement: Vector3<f64> = (0..3).map(|k| modes[k].translation[node] * eta[k]).sum();
        let turn: Vector3<f64> = (0..3).map(|k| modes[k].rotation[node] * eta[k]).sum();
        let frame = quat(&here, BESIDE_QUAT);
        let expected_pos = v3(&here, BESIDE_POS) + frame * (Vector3::new(-0.2, -0.1, 0.0) + displacement);
        assert!((v3(&here, POS) - expected_pos).norm() < 1e-12, "case {case}: position");
        let expected_quat = frame * UnitQuaternion::from_scaled_axis(turn);
        assert!(quat(&here, QUAT).angle_to(&expected_quat) < 1e-12, "case {case}: orientation");
        // "middle_turned" keeps its turn relative to "middle" (as at η = 0).
        let mut undeformed = theta.clone();
        undeformed[8..11].fill(0.0);
        let rest = sensors(&model, &undeformed, &nu);
        let site_turn = quat(&rest, QUAT).inverse() * quat(&rest, TURNED_QUAT);
        assert!(site_turn.angle() > 0.3, "case {case}: the site is turned");
        let turned = quat(&here, TURNED_QUAT);
        assert!(turned.angle_to(&(expected_quat * site_turn)) < 1e-12, "case {case}: turned site");

        // Rates: central differences along an RK4 trajectory, steps h and h/2
        // about t = h, extrapolated (Richardson): the modes turn at up to 57 rad/s.
        let h = 5e-4;
        let mut sim = Simulation::new(
            &model,
            Method::Rk4,
            Settings { tolerance: 1e-6, max_step: 1e-5, energy_projection: false },
        );
        sim.state.theta.copy_from_slice(&theta);
        sim.state.nu.copy_from_slice(&nu);
        sim.initialize(&model).unwrap();
        let zero = vec![0.0; model.nv];
        let input = Input { eps: &zero, eps_rate: &zero, ctrl: &[], ctrl_rate: &[] };
        let mut samples = vec![here.clone()];
        for k in 1..=4 {
            sim.advance_to(&model, k as f64 * h / 2.0, input).unwrap();
            samples.push(sensors(&model, &sim.state.theta, &sim.state.nu));
        }
        let middle = &samples[2];
        let difference = |f: &dyn Fn(&[f64]) -> Vector3<f64>| {
            let wide = (f(&samples[4]) - f(&samples[0])) / (2.0 * h);
            let narrow = (f(&samples[3]) - f(&samples[1])) / h;
            (narrow * 4.0 - wide) / 3.0
        };
        let rate = |at: usize| difference(&|s: &[f64]| v3(s, at));
        let close = |what: &str, a: Vector3<f64>, b: Vector3<f64>| {
            let err = (a - b).norm() / b.norm().max(1.0);
            assert!(err < 1e-6, "case {case}: {what} {a:?} against differences {b:?} ({err:e})");
        };
        close("framelinvel", v3(middle, LINVEL), rate(POS));
        close("framelinacc", v3(middle, LINACC), rate(LINVEL));
        close("frameangacc", v3(middle, ANGACC), rate(ANGVEL));
        // ω = 2 q̇ q⁻¹ (world), q̇ by the same differences of q's components.
        let component = |c: usize| difference(&|s: &[f64]| Vector3::new(s[QUAT + c], 0.0, 0.0)).x;
        let q_rate = Quaternion::new(component(0), component(1), component(2), component(3));
        let omega = (q_rate * quat(middle, QUAT).into_inner().conjugate()).vector() * 2.0;
        close("frameangvel", v3(middle, ANGVEL), omega.into_owned());
        let axes = quat(middle, TURNED_QUAT).inverse();
        close("gyro", v3(middle, GYRO), axes * v3(middle, ANGVEL));
        close("velocimeter", v3(middle, VELOCIMETER), axes * v3(middle, LINVEL));
        close("accelerometer", v3(middle, ACCELEROMETER), axes * v3(middle, LINACC));
    }
}

/// A child body at a node (docs/flexible.md, "Child bodies at nodes";
/// fixture tests/fixtures/flex/bench_child.xml): the frame sensors on a site
/// of the panel that hangs from the node "middle" on a hinge read the node's
/// frame (the site "middle", placed by the node's own code) carried on
/// through the hinge, by the rigid-body relations: orientation q_m·rot(a, φ),
/// ω_m + q_m a φ̇, α_m + q_m a φ̈ + ω_m × q_m a φ̇, and the site's point
/// velocity and acceleration about the node's origin.
#[test]
fn a_child_at_a_node_rides_the_node_and_its_sensors_read_its_motion() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/flex/bench_child.xml");
    let model = Model::compile(&load_mjcf(&path).unwrap().vehicle).unwrap();
    assert_eq!(model.flexible[0].node_children.len(), 1);
    let (yoke_q, yoke_v) = (8, 7);
    let axis = Vector3::new(0.0, 1.0, 0.0);
    let on_panel = Vector3::new(0.3, 0.05, -0.02);
    let mut rng = Rng::new(50);
    for case in 0..4 {
        let mut theta = model.qpos0.clone();
        let q = UnitQuaternion::from_scaled_axis(rng.vec3(1.0));
        theta[3..7].copy_from_slice(&[q.w, q.i, q.j, q.k]);
        theta[7] = rng.uniform(-1.0, 1.0);
        theta[yoke_q] = rng.uniform(-1.0, 1.0);
        for k in 0..3 {
            theta[9 + k] = rng.uniform(-0.1, 0.1);
        }
        let nu = rng.vec(model.nv, 0.8);
        let mut ws = model.workspace();
        ws.set_configuration(&model, &theta).unwrap();
        ws.set_nu(&model, &nu).unwrap();
        let zero = vec![0.0; model.nv];
        ws.compute_sensors(&model, &zero, &[], 0.0).unwrap();
        let s = ws.sensordata.as_slice();
        let (rate, acceleration) = (ws.qvel[yoke_v], ws.qacc[yoke_v]);
        assert!(rate.abs() > 1e-3 && acceleration.abs() > 1e-3, "case {case}: the hinge moves");
        let (node_pos, node_quat) = (v3(s, 19), quat(s, 22));
        let (node_vel, node_omega, node_acc, node_alpha) = (v3(s, 26), v3(s, 29), v3(s, 32), v3(s, 35));
        let expected_quat = node_quat * UnitQuaternion::from_scaled_axis(axis * theta[yoke_q]);
        assert!(quat(s, 3).angle_to(&expected_quat) < 1e-12, "case {case}: orientation");
        let arm = expected_quat * on_panel;
        let close = |what: &str, a: Vector3<f64>, b: Vector3<f64>| {
            let err = (a - b).norm() / b.norm().max(1.0);
            assert!(err < 1e-12, "case {case}: {what} {a:?} against {b:?} ({err:e})");
        };
        close("framepos", v3(s, 0), node_pos + arm);
        let hinge = node_quat * axis;
        let omega = node_omega + hinge * rate;
        close("frameangvel", v3(s, 10), omega);
        close("framelinvel", v3(s, 7), node_vel + omega.cross(&arm));
        let alpha = node_alpha + hinge * acceleration + node_omega.cross(&(hinge * rate));
        close("frameangacc", v3(s, 16), alpha);
        close("framelinacc", v3(s, 13), node_acc + alpha.cross(&arm) + omega.cross(&omega.cross(&arm)));
    }
}

/// A body welded at a node (docs/flexible.md, "Bodies welded at nodes";
/// fixture tests/fixtures/flex/bench_welded.xml): the frame sensors on a
/// site of the star tracker welded at the node "middle", and on the
/// tracker's own frame, read the node's frame (the site "middle", placed by
/// the node's own code) carried rigidly: orientation q_m·q_b·q_s, position
/// p_m + q_m·(q_b s), the node's ω and α, and the point's velocity and
/// acceleration about the node's origin. Gravity on (the accelerations
/// read −g as the world's).
#[test]
fn a_body_welded_at_a_node_rides_the_node_and_its_sensors_read_its_motion() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/flex/bench_welded.xml");
    let vehicle = load_mjcf(&path).unwrap().vehicle;
    let model = Model::compile(&vehicle).unwrap();
    let flexible = &model.flexible[0];
    assert_eq!((flexible.node_children.len(), flexible.welded.len()), (1, flexible.rotating.len()));
    let tracker = vehicle.bodies.iter().find(|b| b.name == "tracker").unwrap().quat;
    let site = vehicle.sites.iter().find(|s| s.name.as_deref() == Some("boresight")).unwrap();
    let (site_pos, site_quat) = (site.pos, site.quat);
    let mut rng = Rng::new(51);
    for case in 0..4 {
        let mut theta = model.qpos0.clone();
        let q = UnitQuaternion::from_scaled_axis(rng.vec3(1.0));
        theta[3..7].copy_from_slice(&[q.w, q.i, q.j, q.k]);
        for coordinate in &mut theta[7..] {
            *coordinate = rng.uniform(-0.1, 0.1);
        }
        let nu = rng.vec(model.nv, 0.8);
        let mut ws = model.workspace();
        ws.set_configuration(&model, &theta).unwrap();
        ws.set_nu(&model, &nu).unwrap();
        let zero = vec![0.0; model.nv];
        ws.compute_sensors(&model, &zero, &[1.5], 0.0).unwrap();
        let s = ws.sensordata.as_slice();
        let (node_pos, node_quat) = (v3(s, 19), quat(s, 22));
        let (node_vel, node_omega, node_acc, node_alpha) = (v3(s, 26), v3(s, 29), v3(s, 32), v3(s, 35));
        assert!(node_alpha.norm() > 1e-2, "case {case}: the node accelerates");
        let body_quat = node_quat * tracker;
        assert!(quat(s, 41).angle_to(&body_quat) < 1e-12, "case {case}: the tracker's orientation");
        assert!(quat(s, 3).angle_to(&(body_quat * site_quat)) < 1e-12, "case {case}: the site's orientation");
        let arm = body_quat * site_pos;
        let close = |what: &str, a: Vector3<f64>, b: Vector3<f64>| {
            let err = (a - b).norm() / b.norm().max(1.0);
            assert!(err < 1e-12, "case {case}: {what} {a:?} against {b:?} ({err:e})");
        };
        close("the tracker's framepos", v3(s, 38), node_pos);
        close("framepos", v3(s, 0), node_pos + arm);
        close("frameangvel", v3(s, 10), node_omega);
        close("framelinvel", v3(s, 7), node_vel + node_omega.cross(&arm));
        close("frameangacc", v3(s, 16), node_alpha);
        let linacc = node_acc + node_alpha.cross(&arm) + node_omega.cross(&node_omega.cross(&arm));
        close("framelinacc", v3(s, 13), linacc);
    }
}
