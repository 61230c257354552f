//! Actuators on sites at the nodes of a flexible body (docs/flexible.md,
//! "Sites at nodes"): the wrench goes to the node, on its deformed pose, so
//! its generalized force is the node Jacobian's transpose times the wrench,
//! on the rigid dofs and on the modes.
//!
//! Checked two ways that share no code with the passes:
//! - against the dense reference (`common`: the nodes as rigid bodies,
//!   their Jacobians written out), on random trees with sites at nodes,
//!   with and without reference sites: moment arms, length, velocity, T,
//!   ε = m⁻¹T and ν̇ of the actuated vehicle; also with child bodies at
//!   nodes (docs/flexible.md, "Child bodies at nodes") carrying sites and
//!   motors, whose wrenches reach the modes through their nodes;
//! - by virtual work on the fixture `tests/fixtures/flex/bench_thruster.xml`:
//!   T·δθ = F·δp + N·δφ for the site's pose moved along random tangent
//!   directions δθ (central differences), F and N the gear's force and
//!   torque in the site's turned axes; and the actuator sensors read the
//!   same length, velocity and force.

use std::path::Path;

use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, UnitQuaternion};
use nudyn::mjcf::load_mjcf;
use nudyn::model::Model;
use nudyn::vehicle::{Actuator, Site, Transmission, Vehicle};

use crate::common::{
    self, Kinematics, Rng, TreeOptions, V3, kinematics, node_at, point_jacobian, random_theta, random_vehicle, rel_err,
};

/// A site's world rotation and origin, its Jacobians (3×nv) and the rigid
/// dofs that move it; a site at a node takes the node's.
struct SiteMotion {
    rot: Matrix3<f64>,
    pos: V3,
    jw: DMatrix<f64>,
    jv: DMatrix<f64>,
    dofs: Vec<usize>,
    /// The modal coordinates of the nodes that carry its body (their ν
    /// entry and the node's origin), which move it as they move the node.
    carried_by: Vec<(usize, V3)>,
}

fn site_motion(vehicle: &Vehicle, k: &Kinematics, theta: &[f64], site: usize) -> SiteMotion {
    let (_, nv) = common::nq_nv(vehicle);
    let s = &vehicle.sites[site];
    let local = s.quat.to_rotation_matrix().into_inner();
    let Some(b) = s.body else {
        return SiteMotion {
            rot: local,
            pos: s.pos,
            jw: DMatrix::zeros(3, nv),
            jv: DMatrix::zeros(3, nv),
            dofs: Vec::new(),
            carried_by: Vec::new(),
        };
    };
    let modal = vehicle.flexible.iter().find(|f| f.body == vehicle.bodies[b].name && !f.modes.is_empty());
    let carried_by = k.node_twists[b].iter().map(|&(d, _, _, at)| (d, at)).collect();
    // The sites below are put exactly at nodes, or well away from them.
    match modal.and_then(|m| m.nodes.iter().position(|n| n.position == s.pos)) {
        Some(j) => {
            let node = node_at(vehicle, theta, b, j);
            let dofs = k.body_dofs[b].clone();
            SiteMotion { rot: node.rot * local, pos: node.pos, jw: node.jw, jv: node.jv, dofs, carried_by }
        }
        None => {
            let pos = k.body_pos[b] + k.body_rot[b] * s.pos;
            let (jw, jv) = point_jacobian(k, b, &pos, nv);
            SiteMotion { rot: k.body_rot[b] * local, pos, jw, jv, dofs: k.body_dofs[b].clone(), carried_by }
        }
    }
}

/// A site transmission's length and moment arms (nv), as MuJoCo defines
/// them, from the sites' Jacobians: Jᵀ(R g) at the site; with a reference
/// site (J_s − J_r)ᵀ(R_r g) with the rigid dofs that move both cleared, and
/// the modes of a node from which both hang.
fn dense_transmission(vehicle: &Vehicle, theta: &[f64], actuator: &Actuator) -> (f64, DVector<f64>) {
    let k = kinematics(vehicle, theta);
    let g = &actuator.gear;
    let (translation, rotation) = (V3::new(g[0], g[1], g[2]), V3::new(g[3], g[4], g[5]));
    let Transmission::Site { site, refsite } = &actuator.transmission else { unreachable!("sites only") };
    let at = site_motion(vehicle, &k, theta, *site);
    match refsite {
        None => (0.0, at.jv.transpose() * (at.rot * translation) + at.jw.transpose() * (at.rot * rotation)),
        Some(reference) => {
            let from = site_motion(vehicle, &k, theta, *reference);
            let mut arms = (&at.jv - &from.jv).transpose() * (from.rot * translation)
                + (&at.jw - &from.jw).transpose() * (from.rot * rotation);
            for d in at.dofs.iter().filter(|d| from.dofs.contains(d)) {
                arms[*d] = 0.0;
            }
            // So are the modes of a node that carries both (through child bodies).
            for (d, _) in at.carried_by.iter().filter(|c| from.carried_by.contains(c)) {
                arms[*d] = 0.0;
            }
            let turn =
                UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(from.rot.transpose() * at.rot));
            let length =
                (from.rot.transpose() * (at.pos - from.pos)).dot(&translation) + turn.scaled_axis().dot(&rotation);
            (length, arms)
        }
    }
}

fn motor(site: usize, refsite: Option<usize>, gear: [f64; 6]) -> Actuator {
    common::motor(Transmission::Site { site, refsite }, gear)
}

/// A random tree with flexible bodies, a site at every node of each (turned
/// at random) and one on every rigid body, and motors on sites at nodes:
/// alone, against a reference site on another body or the world, and
/// against another node of the same body. With `children_at_nodes`, child
/// bodies hang from nodes, and the site of each has a motor of its own too;
/// with `welded`, bodies welded at nodes (some carrying children with
/// joints) have sites and motors alone on them as well.
fn actuated_at_nodes(rng: &mut Rng, free_base: bool, passive: bool, children_at_nodes: bool, welded: bool) -> Vehicle {
    let bodies = 2 + rng.below(4);
    let mut vehicle = random_vehicle(rng, TreeOptions { bodies, free_base, passive, chain: false });
    common::make_flexible(rng, &mut vehicle, passive);
    if children_at_nodes {
        common::attach_children_to_nodes(rng, &mut vehicle);
    }
    let welded_bodies = if welded { common::weld_bodies_to_nodes(rng, &mut vehicle) } else { Vec::new() };
    let mut node_sites: Vec<Vec<usize>> = Vec::new();
    for modal in vehicle.flexible.clone() {
        let body = vehicle.bodies.iter().position(|b| b.name == modal.body).unwrap();
        let mut here = Vec::new();
        for node in &modal.nodes {
            here.push(vehicle.sites.len());
            vehicle.sites.push(Site {
                name: None,
                body: Some(body),
                pos: node.position,
                quat: rng.unit_quat(),
                line: 0,
            });
        }
        node_sites.push(here);
    }
    // A site on every body, away from every node, and one on the world.
    let mut elsewhere = Vec::new();
    for body in (0..vehicle.bodies.len()).map(Some).chain([None]) {
        let pos = V3::new(0.9, 0.8, 0.7) + rng.vec3(0.05);
        elsewhere.push(vehicle.sites.len());
        vehicle.sites.push(Site { name: None, body, pos, quat: rng.unit_quat(), line: 0 });
    }
    let gear = |rng: &mut Rng| std::array::from_fn(|_| rng.uniform(-2.0, 2.0));
    if children_at_nodes {
        // A motor alone on the site of each body that hangs from a node.
        let at_node = |body: usize| {
            let parent = vehicle.bodies[body].parent.map(|p| &vehicle.bodies[p].name);
            let modal = vehicle.flexible.iter().find(|f| Some(&f.body) == parent);
            modal.is_some_and(|m| m.nodes.iter().any(|n| n.position == vehicle.bodies[body].pos))
        };
        let carried: Vec<usize> = (0..vehicle.bodies.len()).filter(|&b| at_node(b)).map(|b| elsewhere[b]).collect();
        assert!(!carried.is_empty());
        for site in carried {
            vehicle.actuators.push(motor(site, None, gear(rng)));
        }
    }
    for &body in &welded_bodies {
        vehicle.actuators.push(motor(elsewhere[body], None, gear(rng)));
    }
    for sites in &node_sites {
        for (n, &site) in sites.iter().enumerate() {
            vehicle.actuators.push(motor(site, None, gear(rng)));
            let other = elsewhere[rng.below(elsewhere.len())];
            vehicle.actuators.push(motor(site, Some(other), gear(rng)));
            vehicle.actuators.push(motor(other, Some(site), gear(rng)));
            let neighbour = sites[(n + 1) % sites.len()];
            vehicle.actuators.push(motor(site, Some(neighbour), gear(rng)));
        }
    }
    vehicle
}

#[test]
fn actuators_at_nodes_act_through_the_nodes_jacobians() {
    check_against_the_dense_reference(4949, false, false);
}

/// With children at nodes: their sites' wrenches go through the nodes to
/// the modes (and their velocities are the nodes' carried on).
#[test]
fn actuators_on_children_at_nodes_act_through_the_nodes_jacobians() {
    check_against_the_dense_reference(4950, true, false);
}

/// With bodies welded at nodes (docs/flexible.md, "Bodies welded at
/// nodes"): their sites ride the nodes, off the nodes' origins.
#[test]
fn actuators_on_bodies_welded_at_nodes_act_through_the_nodes_jacobians() {
    check_against_the_dense_reference(4951, true, true);
}

fn check_against_the_dense_reference(seed: u64, children_at_nodes: bool, welded: bool) {
    let mut rng = Rng::new(seed);
    for trial in 0..16 {
        let (free_base, passive) = (trial % 2 == 0, trial % 4 < 2);
        let vehicle = actuated_at_nodes(&mut rng, free_base, passive, children_at_nodes, welded);
        let model = Model::compile(&vehicle).unwrap();
        let theta = random_theta(&mut rng, &vehicle);
        let qvel = rng.vec(model.nv, 1.5);
        let ctrl = rng.vec(model.actuators.len(), 2.0);
        let mut ws = model.workspace();
        ws.set_configuration(&model, &theta).unwrap();
        ws.set_qvel(&model, &qvel).unwrap();
        ws.compute_actuation(&model, &ctrl).unwrap();

        let mut torque = DVector::zeros(model.nv);
        let mut row = vec![0.0; model.nv];
        let mut moving_modes = 0;
        for (a, actuator) in vehicle.actuators.iter().enumerate() {
            let what = format!("trial {trial}, actuator {a} ({:?})", actuator.transmission);
            let (length, arms) = dense_transmission(&vehicle, &theta, actuator);
            // Every actuator moves the modes, but a pair of a node's site and
            // a site of the child on that node whose modes do not turn it.
            let modal_arms = arms.rows(model.nv - common::modal_count(&vehicle), common::modal_count(&vehicle)).norm();
            assert!(children_at_nodes || modal_arms > 1e-3, "{what}: no modal arms");
            moving_modes += usize::from(modal_arms > 1e-3);
            // The reference's node angular Jacobians are differences: 8.5e-11 at worst.
            let velocity = arms.dot(&DVector::from_column_slice(&qvel));
            assert!(
                (ws.actuator_length[a] - length).abs() < 1e-12,
                "{what}: length {} vs {length}",
                ws.actuator_length[a]
            );
            assert!(
                (ws.actuator_velocity[a] - velocity).abs() < 1e-9 * (1.0 + velocity.abs()),
                "{what}: velocity {} vs {velocity}",
                ws.actuator_velocity[a]
            );
            let mut single = model.workspace();
            single.set_configuration(&model, &theta).unwrap();
            single.set_qvel(&model, &qvel).unwrap();
            single.actuator_moment(&model, a, &mut row).unwrap();
            assert!(rel_err(&row, arms.as_slice()) < 1e-9, "{what}: moment arms {row:?} vs {arms}");
            torque += &arms * ctrl[a];
        }
        assert!(2 * moving_modes > vehicle.actuators.len(), "trial {trial}: {moving_modes} actuators move the modes");
        assert!(rel_err(ws.qfrc_actuator.as_slice(), torque.as_slice()) < 1e-9, "trial {trial}: T");
        let m = common::tree_factor(&vehicle, &common::mass_matrix(&vehicle, &theta));
        let eps = m.lu().solve(&torque).unwrap();
        assert!(rel_err(ws.eps_actuator.as_slice(), eps.as_slice()) < 1e-9, "trial {trial}: eps = m⁻¹T");
        // ν̇ of the actuated vehicle (through the passes) against the dense equations under T.
        let zero = vec![0.0; model.nv];
        ws.compute_nu_dot_actuated(&model, &zero, &ctrl).unwrap();
        let nu_dot = common::nu_dot_reference(&vehicle, &theta, &qvel, torque.as_slice());
        let err = rel_err(ws.nu_dot.as_slice(), nu_dot.as_slice());
        assert!(err < 1e-7, "trial {trial}: nu_dot ({err:e})");
    }
}

fn fixture() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/flex/bench_thruster.xml")
}

// sensordata's layout (the fixture's sensors in order).
const THRUSTER_POS: usize = 0;
const THRUSTER_VEL: usize = 1;
const THRUSTER_FRC: usize = 2;
const TORQUER_VEL: usize = 3;
const TORQUER_FRC: usize = 4;

#[test]
fn a_thruster_at_a_node_does_the_virtual_work_of_its_wrench_on_the_nodes_pose() {
    let vehicle = load_mjcf(&fixture()).unwrap().vehicle;
    let model = Model::compile(&vehicle).unwrap();
    let (tip, bench) = (vehicle.sites.iter().position(|s| s.name.as_deref() == Some("tip")).unwrap(), 1);
    let modal = &vehicle.flexible[0];
    let node = modal.node("tip").unwrap();
    let local = vehicle.sites[tip].quat;
    let gear = vehicle.actuators[0].gear;
    let (gear_force, gear_torque) = (V3::new(gear[0], gear[1], gear[2]), V3::new(gear[3], gear[4], gear[5]));
    let mut rng = Rng::new(4910);
    for case in 0..6 {
        let theta = random_theta(&mut rng, &vehicle);
        let (qvel, ctrl) = (rng.vec(model.nv, 1.0), [rng.uniform(-2.0, 2.0), rng.uniform(-2.0, 2.0)]);
        let mut ws = model.workspace();
        ws.set_configuration(&model, &theta).unwrap();
        ws.set_qvel(&model, &qvel).unwrap();
        let mut moment = vec![0.0; model.nv];
        ws.actuator_moment(&model, 0, &mut moment).unwrap();
        // The site's pose: the node's (the dense reference's kinematics), turned by the site's quat.
        let pose = |theta: &[f64]| {
            let at = node_at(&vehicle, theta, bench, node);
            (UnitQuaternion::from_matrix(&at.rot) * local, at.pos)
        };
        let (turn, _) = pose(&theta);
        let (force, torque) = (turn * gear_force, turn * gear_torque);
        // T·δθ = F·δp + N·δφ, δθ tangent (ν-sized), by central differences.
        let work = |direction: &[f64]| {
            let h = 1e-6;
            let ((ahead_turn, ahead), (behind_turn, behind)) = (
                pose(&common::integrate_pos(&vehicle, &theta, direction, h)),
                pose(&common::integrate_pos(&vehicle, &theta, direction, -h)),
            );
            let (dp, dphi) =
                ((ahead - behind) / (2.0 * h), (ahead_turn * behind_turn.inverse()).scaled_axis() / (2.0 * h));
            force.dot(&dp) + torque.dot(&dphi)
        };
        for d in 0..4 {
            let direction = if d == 0 { qvel.clone() } else { rng.vec(model.nv, 1.0) };
            let expected = work(&direction);
            let virtual_work: f64 = moment.iter().zip(&direction).map(|(t, v)| t * v).sum();
            assert!(
                (virtual_work - expected).abs() < 1e-8 * (1.0 + expected.abs()),
                "case {case}, direction {d}: T·δθ {virtual_work} vs the wrench's work {expected}"
            );
        }
        // The velocity is the power of a unit force: T·θ̇.
        let power = work(&qvel);
        ws.compute_sensors(&model, &vec![0.0; model.nv], &ctrl, 0.0).unwrap();
        let s = ws.sensordata.as_slice();
        assert!((s[THRUSTER_VEL] - power).abs() < 1e-8 * (1.0 + power.abs()), "case {case}: velocity");
        assert_eq!(s[THRUSTER_POS], 0.0, "a site transmission without refsite has length 0");
        assert_eq!((s[THRUSTER_FRC], s[TORQUER_FRC]), (ctrl[0], ctrl[1]));
        assert_eq!((s[THRUSTER_VEL], s[TORQUER_VEL]), (ws.actuator_velocity[0], ws.actuator_velocity[1]));
    }
}

/// A wrench input on a body welded at a node (docs/flexible.md, "Bodies
/// welded at nodes"; fixture tests/fixtures/flex/bench_welded.xml, the
/// star tracker): its six unit forces and torques along the world's axes at
/// the tracker's centre of mass act through the node, as the dense
/// reference's Jacobians of that point give them, modes included.
#[test]
fn a_wrench_input_on_a_body_welded_at_a_node_acts_through_the_node() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/flex/bench_welded.xml");
    let vehicle = load_mjcf(&path).unwrap().vehicle;
    let model = Model::compile_with_wrench_inputs(&vehicle, &["tracker".to_string()]).unwrap();
    let tracker = vehicle.bodies.iter().position(|b| b.name == "tracker").unwrap();
    let first = model.mjcf_actuator_count();
    let mut rng = Rng::new(4952);
    for case in 0..4 {
        let theta = random_theta(&mut rng, &vehicle);
        let mut ws = model.workspace();
        ws.set_configuration(&model, &theta).unwrap();
        ws.set_qvel(&model, &rng.vec(model.nv, 1.0)).unwrap();
        let k = kinematics(&vehicle, &theta);
        let centre = k.body_pos[tracker] + k.body_rot[tracker] * vehicle.bodies[tracker].inertial_pos;
        let (jw, jv) = point_jacobian(&k, tracker, &centre, model.nv);
        let modes = model.nv - common::modal_count(&vehicle)..model.nv;
        let mut row = vec![0.0; model.nv];
        for axis in 0..6 {
            ws.actuator_moment(&model, first + axis, &mut row).unwrap();
            let expected = if axis < 3 { jv.row(axis).transpose() } else { jw.row(axis - 3).transpose() };
            assert!(expected.rows(modes.start, modes.len()).norm() > 1e-3, "case {case}, axis {axis}: no modal arms");
            assert!(rel_err(&row, expected.as_slice()) < 1e-9, "case {case}, axis {axis}: {row:?} vs {expected}");
        }
    }
}
