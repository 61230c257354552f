//! The O(N) actuators (docs/DYNAMICS.md §5) against a dense reference built
//! from the vehicle description (`common`): each actuator's moment arms
//! written out with world Jacobians as MuJoCo's XML reference defines the
//! transmissions, T = Σ arms · force, and ε = m⁻¹T with m the dense upper
//! factor of M. Nothing here uses the passes under test.

use crate::common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use crate::common::{
    Kinematics, Rng, TreeOptions, V3, kinematics, point_jacobian, random_theta, random_vehicle, rel_err,
};
use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, UnitQuaternion};
use nudyn::model::Model;
use nudyn::vehicle::{Actuator, JointKind, Site, Transmission, Vehicle};

/// A random tree with sites on its bodies and on the world, a motor on
/// every joint (`joint` or `jointinparent`), and motors on sites with and
/// without reference sites, all with random gears.
fn actuated_vehicle(rng: &mut Rng, free_base: bool) -> Vehicle {
    let mut vehicle = random_vehicle(rng, TreeOptions { bodies: 7, free_base, passive: false, chain: false });
    let bodies = vehicle.bodies.len();
    for k in 0..3 * bodies + 2 {
        // The last two sites are on the world body.
        let body = (k < 3 * bodies).then_some(k / 3);
        vehicle.sites.push(Site {
            name: Some(format!("s{k}")),
            body,
            pos: rng.vec3(0.4),
            quat: rng.unit_quat(),
            line: 0,
        });
    }
    let gear = |rng: &mut Rng| std::array::from_fn(|_| rng.uniform(-2.0, 2.0));
    let joints: Vec<String> = vehicle.bodies.iter().flat_map(|b| &b.joints).map(|j| j.name.clone()).collect();
    for joint in joints {
        let in_parent = rng.below(2) == 0;
        let g = gear(rng);
        vehicle.actuators.push(common::motor(Transmission::Joint { joint, in_parent }, g));
    }
    let sites = vehicle.sites.len();
    for k in 0..12 {
        let site = rng.below(sites);
        let refsite = (k >= 4).then(|| rng.below(sites));
        let mut g = gear(rng);
        // Purely translational and purely rotational gears too.
        match k % 3 {
            1 => g[3..].fill(0.0),
            2 => g[..3].fill(0.0),
            _ => {}
        }
        vehicle.actuators.push(common::motor(Transmission::Site { site, refsite }, g));
    }
    vehicle
}

/// A site's world rotation and position.
fn site_pose(vehicle: &Vehicle, k: &Kinematics, site: usize) -> (Matrix3<f64>, V3) {
    let s = &vehicle.sites[site];
    let local = s.quat.to_rotation_matrix().into_inner();
    match s.body {
        Some(b) => (k.body_rot[b] * local, k.body_pos[b] + k.body_rot[b] * s.pos),
        None => (local, s.pos),
    }
}

/// Angular and linear Jacobians of a site's origin (zero on the world).
fn site_jacobian(vehicle: &Vehicle, k: &Kinematics, site: usize, nv: usize) -> (DMatrix<f64>, DMatrix<f64>) {
    match vehicle.sites[site].body {
        Some(b) => point_jacobian(k, b, &site_pose(vehicle, k, site).1, nv),
        None => (DMatrix::zeros(3, nv), DMatrix::zeros(3, nv)),
    }
}

/// The dofs that move a site (none for a world site).
fn site_dofs<'a>(vehicle: &Vehicle, k: &'a Kinematics, site: usize) -> &'a [usize] {
    vehicle.sites[site].body.map_or(&[], |b| k.body_dofs[b].as_slice())
}

/// The rotation vector of a rotation, its angle in [0, π].
fn rotation_vector(rotation: &Matrix3<f64>) -> V3 {
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*rotation)).scaled_axis()
}

/// An actuator's length and moment arms (nv), written out densely.
fn dense_transmission(vehicle: &Vehicle, k: &Kinematics, theta: &[f64], actuator: &Actuator) -> (f64, DVector<f64>) {
    let (_, nv) = common::nq_nv(vehicle);
    let mut arms = DVector::zeros(nv);
    let g = &actuator.gear;
    let (translation, rotation) = (V3::new(g[0], g[1], g[2]), V3::new(g[3], g[4], g[5]));
    match &actuator.transmission {
        Transmission::Joint { joint, in_parent } => {
            // θ and dof addresses in MuJoCo's order.
            let (mut qpos, mut dof) = (0, 0);
            let mut found = None;
            for j in vehicle.bodies.iter().flat_map(|b| &b.joints) {
                if &j.name == joint {
                    found = Some(j.kind);
                    break;
                }
                (qpos, dof) = (qpos + j.kind.nq(), dof + j.kind.nv());
            }
            let quat = |adr: usize| {
                UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                    theta[adr],
                    theta[adr + 1],
                    theta[adr + 2],
                    theta[adr + 3],
                ))
            };
            match found.expect("the joint exists") {
                JointKind::Hinge | JointKind::Slide => {
                    arms[dof] = g[0];
                    (theta[qpos] * g[0], arms)
                }
                JointKind::Ball => {
                    let q = quat(qpos);
                    // A parent-frame axis in the child frame.
                    let axis = if *in_parent { q.inverse() * translation } else { translation };
                    arms.rows_mut(dof, 3).copy_from(&axis);
                    (q.scaled_axis().dot(&axis), arms)
                }
                JointKind::Free => {
                    let q = quat(qpos + 3);
                    let axis = if *in_parent { q.inverse() * rotation } else { rotation };
                    arms.rows_mut(dof, 3).copy_from(&translation);
                    arms.rows_mut(dof + 3, 3).copy_from(&axis);
                    (0.0, arms)
                }
            }
        }
        Transmission::Tendon { .. } => unreachable!("the random vehicles have no tendons"),
        Transmission::Site { site, refsite: None } => {
            let (r, _) = site_pose(vehicle, k, *site);
            let (jw, jv) = site_jacobian(vehicle, k, *site, nv);
            arms += jv.transpose() * (r * translation) + jw.transpose() * (r * rotation);
            (0.0, arms)
        }
        Transmission::Site { site, refsite: Some(reference) } => {
            let ((rs, ps), (rr, pr)) = (site_pose(vehicle, k, *site), site_pose(vehicle, k, *reference));
            let (jw_s, jv_s) = site_jacobian(vehicle, k, *site, nv);
            let (jw_r, jv_r) = site_jacobian(vehicle, k, *reference, nv);
            arms += (jv_s - jv_r).transpose() * (rr * translation) + (jw_s - jw_r).transpose() * (rr * rotation);
            // Dofs that move both sites move them together: MuJoCo clears them.
            for d in site_dofs(vehicle, k, *site) {
                if site_dofs(vehicle, k, *reference).contains(d) {
                    arms[*d] = 0.0;
                }
            }
            let length =
                (rr.transpose() * (ps - pr)).dot(&translation) + rotation_vector(&(rr.transpose() * rs)).dot(&rotation);
            (length, arms)
        }
    }
}

#[test]
fn actuator_forces_and_their_eps_equal_the_dense_references() {
    let mut rng = Rng::new(2024);
    for trial in 0..12 {
        let vehicle = actuated_vehicle(&mut rng, trial % 2 == 0);
        let model = Model::compile(&vehicle).unwrap();
        let mut ws = model.workspace();
        let theta = random_theta(&mut rng, &vehicle);
        let qvel = rng.vec(model.nv, 1.5);
        let ctrl = rng.vec(model.actuators.len(), 2.0);
        ws.set_configuration(&model, &theta).unwrap();
        ws.set_qvel(&model, &qvel).unwrap();
        ws.compute_actuation(&model, &ctrl).unwrap();

        let k = kinematics(&vehicle, &theta);
        let mut torque = DVector::zeros(model.nv);
        let mut row = vec![0.0; model.nv];
        for (a, actuator) in vehicle.actuators.iter().enumerate() {
            let (length, arms) = dense_transmission(&vehicle, &k, &theta, actuator);
            let velocity = arms.dot(&DVector::from_column_slice(&qvel));
            let what = format!("trial {trial}, actuator {a} ({:?})", actuator.transmission);
            assert!(
                (ws.actuator_length[a] - length).abs() < 1e-12,
                "{what}: length {} vs {length}",
                ws.actuator_length[a]
            );
            assert!((ws.actuator_velocity[a] - velocity).abs() < 1e-11 * (1.0 + velocity.abs()), "{what}: velocity");
            assert_eq!(ws.actuator_force[a], ctrl[a], "{what}: a unit-gain motor's force is its ctrl");
            torque += &arms * ctrl[a];
            let mut single = model.workspace();
            single.set_configuration(&model, &theta).unwrap();
            single.set_qvel(&model, &qvel).unwrap();
            single.actuator_moment(&model, a, &mut row).unwrap();
            assert!(rel_err(&row, arms.as_slice()) < 1e-12, "{what}: moment arms {row:?} vs {arms}");
        }
        assert!(rel_err(ws.qfrc_actuator.as_slice(), torque.as_slice()) < 1e-12, "trial {trial}: T");
        let m = common::upper_factor(&common::mass_matrix(&vehicle, &theta));
        let eps = m.solve_upper_triangular(&torque).unwrap();
        assert!(rel_err(ws.eps_actuator.as_slice(), eps.as_slice()) < 1e-10, "trial {trial}: eps = m⁻¹T");
    }
}

#[test]
fn actuation_needs_the_velocities_and_nu_controls() {
    let mut rng = Rng::new(7);
    let vehicle = actuated_vehicle(&mut rng, true);
    let model = Model::compile(&vehicle).unwrap();
    let mut ws = model.workspace();
    let theta = random_theta(&mut rng, &vehicle);
    ws.set_configuration(&model, &theta).unwrap();
    let ctrl = vec![0.0; model.actuators.len()];
    assert!(ws.compute_actuation(&model, &ctrl).is_err(), "before the velocities");
    ws.set_qvel(&model, &vec![0.0; model.nv]).unwrap();
    assert!(ws.compute_actuation(&model, &ctrl[1..]).is_err(), "one ctrl short");
    let mut nan = ctrl.clone();
    nan[2] = f64::NAN;
    let error = ws.compute_actuation(&model, &nan).unwrap_err();
    assert_eq!(error.to_string(), "ctrl[3] is not finite (NaN)");
    ws.compute_actuation(&model, &ctrl).unwrap();
    assert!(ws.qfrc_actuator.iter().chain(ws.eps_actuator.iter()).all(|x| *x == 0.0));
}

/// Counts the allocations of the current thread while `COUNTING` is set
/// (the test harness runs tests on several threads).
struct CountingAllocator;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.with(|n| n.set(n.get() + 1));
        }
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

#[test]
fn actuation_does_not_allocate() {
    let mut rng = Rng::new(11);
    let vehicle = actuated_vehicle(&mut rng, true);
    let model = Model::compile(&vehicle).unwrap();
    let mut ws = model.workspace();
    let theta = random_theta(&mut rng, &vehicle);
    let (qvel, ctrl) = (rng.vec(model.nv, 1.0), rng.vec(model.actuators.len(), 1.0));
    ws.set_configuration(&model, &theta).unwrap();
    ws.set_qvel(&model, &qvel).unwrap();
    COUNTING.with(|c| c.set(true));
    let result = ws.compute_actuation(&model, &ctrl);
    COUNTING.with(|c| c.set(false));
    result.unwrap();
    assert_eq!(ALLOCATIONS.with(Cell::get), 0, "compute_actuation allocated");
}

/// Actuators on sites at a flexible body's nodes (their modal forces) too.
#[test]
fn actuation_at_nodes_does_not_allocate() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/flex/bench_thruster.xml");
    let vehicle = nudyn::mjcf::load_mjcf(&path).unwrap().vehicle;
    let model = Model::compile(&vehicle).unwrap();
    let mut ws = model.workspace();
    let mut rng = Rng::new(12);
    ws.set_configuration(&model, &random_theta(&mut rng, &vehicle)).unwrap();
    ws.set_qvel(&model, &rng.vec(model.nv, 1.0)).unwrap();
    let ctrl = rng.vec(model.actuators.len(), 1.0);
    COUNTING.with(|c| c.set(true));
    let result = ws.compute_actuation(&model, &ctrl);
    COUNTING.with(|c| c.set(false));
    result.unwrap();
    assert_eq!(ALLOCATIONS.with(Cell::get), 0, "compute_actuation allocated");
}
