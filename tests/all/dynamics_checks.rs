//! docs/DYNAMICS.md §7 checks 1–5: the O(N) passes against the independent
//! dense reference in `common`, on random trees with every joint type.

use crate::common;

use crate::common::{Rng, TreeOptions, random_theta, random_vehicle, rel_err};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use nudyn::dynamics::derivatives::{Derivatives, Direction, Output, Point, ThetaDirection};
use nudyn::dynamics::flexible::FIXED_MODES;
use nudyn::dynamics::subspace::Subspace;
use nudyn::dynamics::velocity::Given;
use nudyn::flex::{ModalBody, Mode, Node};
use nudyn::model::{Model, Shortcuts};
use nudyn::vehicle::{JointKind, Vehicle};
use nudyn::workspace::Workspace;
use proptest::prelude::*;

/// m built column by column from ν = m*θ̇ with unit θ̇.
fn factor_from_passes(model: &Model, ws: &mut Workspace, theta: &[f64]) -> DMatrix<f64> {
    ws.set_configuration(model, theta).unwrap();
    let mut m_star = DMatrix::zeros(model.nv, model.nv);
    for k in 0..model.nv {
        let mut e = vec![0.0; model.nv];
        e[k] = 1.0;
        ws.set_qvel(model, &e).unwrap();
        m_star.set_column(k, &ws.nu);
    }
    m_star.transpose()
}

/// Every check on one vehicle at one random state; returns a description
/// of the first failure.
fn check_vehicle(vehicle: &Vehicle, rng: &mut Rng) -> Result<(), String> {
    let model = Model::compile(vehicle).map_err(|e| e.to_string())?;
    let mut ws = model.workspace();
    let theta = random_theta(rng, vehicle);
    let qvel = rng.vec(model.nv, 1.5);
    let torque = rng.vec(model.nv, 3.0);
    let fail = |what: &str, err: f64, tol: f64| {
        if err <= tol { Ok(()) } else { Err(format!("{what}: error {err:.3e} > {tol:.0e}")) }
    };

    // The reference's Jacobians are exact for joints; a node's angular
    // columns are differences (to about 1e-12 of the node's rotation rate;
    // m m* = M to 1.6e-10 at worst in 10,000 random cases of each flexible
    // test, 2026-11-30).
    let reference = if common::modal_count(vehicle) == 0 { 1e-12 } else { 5e-10 };

    // 1. m m* = M, and m is the unique upper factor.
    let m_dense = common::mass_matrix(vehicle, &theta);
    let m = factor_from_passes(&model, &mut ws, &theta);
    fail("m m* = M", rel_err((&m * m.transpose()).as_slice(), m_dense.as_slice()), reference)?;
    // m is upper triangular in an order where every dof follows those that
    // carry it (the modes ahead of the children at their nodes: common::tree_order).
    // The reference's factor carries its M's error times M's conditioning:
    // 1.09e-10 on a random flexible tree (in tests/proptest-regressions).
    let factor = if common::modal_count(vehicle) == 0 { 1e-10 } else { 1e-9 };
    fail("m = upper factor of M", rel_err(m.as_slice(), common::tree_factor(vehicle, &m_dense).as_slice()), factor)?;

    // 2. θ̇ = ℓ*ν inverts ν = m*θ̇; ε = ℓT inverts T = mε; ε = m⁻¹T densely.
    ws.set_qvel(&model, &qvel).unwrap();
    let nu = ws.nu.clone();
    fail(
        "nu = m* qvel",
        rel_err(nu.as_slice(), (m.transpose() * DVector::from_column_slice(&qvel)).as_slice()),
        1e-12,
    )?;
    ws.set_nu(&model, nu.as_slice()).unwrap();
    fail("qvel = l* nu round trip", rel_err(ws.qvel.as_slice(), &qvel), 1e-12)?;
    let mut eps = vec![0.0; model.nv];
    ws.eps_from_forces(&model, &torque, None, &mut eps).unwrap();
    let eps_dense = m.clone().lu().solve(&DVector::from_column_slice(&torque)).unwrap();
    fail("eps = m^-1 T", rel_err(&eps, eps_dense.as_slice()), 1e-10)?;
    let mut torque_back = vec![0.0; model.nv];
    ws.torque_from_eps(&model, &eps, &mut torque_back).unwrap();
    fail("T = m eps round trip", rel_err(&torque_back, &torque), 1e-12)?;

    // 3. ν·C = 0.
    ws.set_nu(&model, nu.as_slice()).unwrap();
    ws.compute_nu_dot(&model, &eps).unwrap();
    let c = ws.coriolis.clone();
    // C is quadratic in ν: scale by |ν|·max(|C|, |ν|²) so round-off on a near-zero C cannot fail.
    let work = nu.dot(&c).abs() / (nu.norm() * c.norm().max(nu.norm_squared())).max(1e-300);
    fail("nu . C = 0", work, 1e-12)?;

    // 4. ν̇ = m*θ̈ + ṁ*θ̇ with θ̈ from the dense equations under the same torques.
    let nu_dot_ref = common::nu_dot_reference(vehicle, &theta, &qvel, &torque);
    // The reference's ṁ* differences factors of a mass matrix whose node
    // columns are themselves differences on a flexible tree: 2.9e-7 at worst
    // in 10,000 random cases of each flexible test (rigid trees 2.3e-9; θ̈,
    // without ṁ*, 1.4e-8), 2026-11-30.
    let nu_dot_tolerance = if common::modal_count(vehicle) == 0 { 1e-7 } else { 1e-6 };
    fail("nu_dot", rel_err(ws.nu_dot.as_slice(), nu_dot_ref.as_slice()), nu_dot_tolerance)?;
    // θ̈ from the outward pass after pass 3 against the dense M⁻¹(T + τ_passive − h).
    ws.compute_accelerations(&model).unwrap();
    let qacc_dense = common::forward_dynamics(vehicle, &theta, &qvel, &torque);
    // (As for ν̇, the dense solve loses digits on the 200-body chain.)
    fail("qacc", rel_err(ws.qacc.as_slice(), qacc_dense.as_slice()), 1e-7)?;
    // θ̈ without ν̇ (pass 3 without the factor's rates): the same θ̈.
    let qacc_after_nu_dot = ws.qacc.clone();
    ws.set_nu(&model, nu.as_slice()).unwrap();
    ws.compute_qacc(&model, &eps).unwrap();
    fail("qacc without the factor's rates", rel_err(ws.qacc.as_slice(), qacc_after_nu_dot.as_slice()), 1e-12)?;

    // 5. Momentum and |ν| are invariant with ε = 0 and no passive forces
    // (the momentum also with modal stiffness and damping):
    // checked on the instantaneous rates, by central differences along the motion.
    let free_base = vehicle.bodies[0].joints.first().is_some_and(|j| j.kind == nudyn::vehicle::JointKind::Free);
    if free_base
        && vehicle.gravity.norm() == 0.0
        && vehicle.bodies.iter().all(|b| b.joints.iter().all(|j| j.stiffness == 0.0 && j.damping == 0.0))
    {
        let p = ws.momentum(&model).unwrap();
        let p_ref = common::momentum(vehicle, &theta, &qvel);
        // On a flexible tree the reference's momentum sums its differenced
        // node columns over every body at a node: 1.017e-10 seen on a random
        // tree with children at nodes (2026-11-30), held as the factor is.
        let momentum = if common::modal_count(vehicle) == 0 { reference } else { 1e-9 };
        fail("momentum", rel_err(p.as_slice(), &p_ref), momentum)?;
        fail(
            "kinetic energy",
            (ws.kinetic_energy() - 0.5 * qvel_m(&m_dense, &qvel)).abs() / ws.kinetic_energy().max(1.0),
            reference,
        )?;
        let zero = vec![0.0; model.nv];
        ws.compute_nu_dot(&model, &zero).unwrap();
        let nu_dot = ws.nu_dot.clone();
        let qvel_now = ws.qvel.clone();
        // dp/dt along the motion (θ̇, ν̇), the momentum's derivative in dual
        // numbers (round-off: 4.2e-11 of |p| at most on random trees, in
        // tests/proptest-regressions): central differences of it lost up
        // to 1.3e-7 to fast spinning light links and stiff modes.
        let (no_forces, none) = (vec![0.0; model.nv], Vec::new());
        let point = Point {
            theta: &theta,
            velocity: nu.as_slice(),
            given: Given::Nu,
            eps: &no_forces,
            torque: &no_forces,
            ctrl: &none,
            act: &none,
            time: 0.0,
        };
        let along_the_motion = Direction {
            theta: qvel_now.as_slice(),
            theta_in: ThetaDirection::Tangent,
            velocity: nu_dot.as_slice(),
            eps: &no_forces,
            torque: &no_forces,
            ctrl: &none,
            act: &none,
        };
        let mut derivatives = Derivatives::new(&model);
        derivatives.run(&model, &point, &along_the_motion, &[Output::Momentum]).map_err(|e| e.to_string())?;
        let rate = DVector::from_iterator(6, derivatives.derivative(Output::Momentum));
        // Its parts through ν̇ and through θ cancel: round-off is relative
        // to them, about |p|·|ν̇|/|ν| (a strongly deformed one-body free
        // flexible tree, its mass matrix near singular, ν̇ ≈ 7e4 at |ν| ≈ 2:
        // 1.4e-8, 2.9e-9 of |p|; 2026-11-30).
        let scale = (p.norm() * (1.0 + nu_dot.norm() / nu.norm().max(1e-300))).max(1.0);
        fail("d/dt momentum = 0", rate.norm() / scale, 1e-9)?;
        // Modal stiffness and damping are internal forces: they keep the
        // momentum but exchange kinetic energy with strain energy.
        if common::modal_count(vehicle) == 0 {
            fail("d/dt |nu|^2 = 0", 2.0 * nu.dot(&nu_dot) / nu.norm_squared().max(1.0), 1e-12)?;
        }
    }
    Ok(())
}

fn qvel_m(m: &DMatrix<f64>, qvel: &[f64]) -> f64 {
    let u = DVector::from_column_slice(qvel);
    u.dot(&(m * &u))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn random_trees_without_passive_forces(seed in any::<u64>(), bodies in 1usize..9, free_base in any::<bool>()) {
        let mut rng = Rng::new(seed);
        let vehicle = random_vehicle(&mut rng, TreeOptions { bodies, free_base, passive: false, chain: false });
        if let Err(e) = check_vehicle(&vehicle, &mut rng) {
            prop_assert!(false, "{e}\n{vehicle:#?}");
        }
    }

    #[test]
    fn random_trees_with_gravity_springs_and_dampers(seed in any::<u64>(), bodies in 1usize..9, free_base in any::<bool>()) {
        let mut rng = Rng::new(seed);
        let vehicle = random_vehicle(&mut rng, TreeOptions { bodies, free_base, passive: true, chain: false });
        if let Err(e) = check_vehicle(&vehicle, &mut rng) {
            prop_assert!(false, "{e}\n{vehicle:#?}");
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, ..ProptestConfig::default() })]

    /// Flexible bodies' modes in the passes (docs/flexible.md) against the
    /// dense reference with the nodes as rigid bodies.
    #[test]
    fn random_trees_with_flexible_bodies(seed in any::<u64>(), bodies in 1usize..7, free_base in any::<bool>(), passive in any::<bool>()) {
        let mut rng = Rng::new(seed);
        let mut vehicle = random_vehicle(&mut rng, TreeOptions { bodies, free_base, passive, chain: false });
        common::make_flexible(&mut rng, &mut vehicle, passive);
        if let Err(e) = check_vehicle(&vehicle, &mut rng) {
            prop_assert!(false, "{e}\n{vehicle:#?}");
        }
    }

    /// Child bodies at nodes of flexible bodies (docs/flexible.md, "Child
    /// bodies at nodes") against the dense reference, where they hang from
    /// the nodes' frames.
    #[test]
    fn random_trees_with_children_at_nodes(seed in any::<u64>(), bodies in 1usize..7, free_base in any::<bool>(), passive in any::<bool>()) {
        let mut rng = Rng::new(seed);
        let mut vehicle = random_vehicle(&mut rng, TreeOptions { bodies, free_base, passive, chain: false });
        common::make_flexible(&mut rng, &mut vehicle, passive);
        prop_assert!(common::attach_children_to_nodes(&mut rng, &mut vehicle) > 0);
        let model = Model::compile(&vehicle).unwrap();
        prop_assert!(model.flexible.iter().any(|f| !f.node_children.is_empty()));
        if let Err(e) = check_vehicle(&vehicle, &mut rng) {
            prop_assert!(false, "{e}\n{vehicle:#?}");
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, ..ProptestConfig::default() })]

    /// Bodies welded at nodes of flexible bodies (docs/flexible.md, "Bodies
    /// welded at nodes"), some carrying children with joints, beside
    /// children with joints at nodes, against the dense reference, where
    /// they are rigid bodies fixed in the nodes' frames.
    #[test]
    fn random_trees_with_bodies_welded_at_nodes(seed in any::<u64>(), bodies in 1usize..6, free_base in any::<bool>(), passive in any::<bool>()) {
        let mut rng = Rng::new(seed);
        let mut vehicle = random_vehicle(&mut rng, TreeOptions { bodies, free_base, passive, chain: false });
        common::make_flexible(&mut rng, &mut vehicle, passive);
        if rng.below(2) == 0 {
            common::attach_children_to_nodes(&mut rng, &mut vehicle);
        }
        let welded = common::weld_bodies_to_nodes(&mut rng, &mut vehicle);
        let model = Model::compile(&vehicle).unwrap();
        prop_assert!(!welded.is_empty() && model.flexible.iter().any(|f| !f.welded.is_empty()));
        if let Err(e) = check_vehicle(&vehicle, &mut rng) {
            prop_assert!(false, "{e}\n{vehicle:#?}");
        }
    }
}

/// Flexible bodies with more modes than the blocks' fixed-size instances
/// (`flexible::FIXED_MODES`: the same arithmetic at a size known only at run
/// time), and bodies of point masses only (a constant factor, made with the
/// workspace), against the dense reference.
#[test]
fn flexible_bodies_with_many_modes_or_only_point_masses() {
    for seed in 0..12 {
        let mut rng = Rng::new(4900 + seed);
        let options = TreeOptions { bodies: 3, free_base: seed % 2 == 0, passive: true, chain: false };
        let mut vehicle = random_vehicle(&mut rng, options);
        common::make_flexible(&mut rng, &mut vehicle, true);
        let modes = if seed < 6 { FIXED_MODES + 1 + rng.below(3) } else { 1 + rng.below(FIXED_MODES) };
        let points_only = seed % 3 != 2;
        for f in 0..vehicle.flexible.len() {
            let modal = &mut vehicle.flexible[f];
            reshape_flexible_body(&mut rng, modal, modes, points_only);
            let inertia = modal.mass_properties();
            let body = vehicle.bodies.iter_mut().find(|b| b.name == vehicle.flexible[f].body).unwrap();
            body.inertia = Some(inertia);
        }
        let model = Model::compile(&vehicle).unwrap();
        assert!(model.flexible.iter().all(|f| f.mode_count() == modes && f.rotating.is_empty() == points_only));
        if let Err(e) = check_vehicle(&vehicle, &mut rng) {
            panic!("seed {seed} ({modes} modes, point masses only: {points_only}): {e}");
        }
    }
}

/// New nodes and `modes` random damped modes for `modal`: 4–6 point masses,
/// or three nodes with rotary inertia and two point masses.
fn reshape_flexible_body(rng: &mut Rng, modal: &mut ModalBody, modes: usize, points_only: bool) {
    let point: Vec<bool> =
        if points_only { vec![true; 4 + rng.below(3)] } else { vec![false, false, false, true, true] };
    modal.nodes = point
        .iter()
        .enumerate()
        .map(|(j, &point)| Node {
            name: format!("n{j}"),
            position: rng.vec3(0.5),
            mass: rng.uniform(0.2, 2.0),
            rotary_inertia: if point { Matrix3::zeros() } else { common::random_mass(rng).inertia * 0.3 },
        })
        .collect();
    modal.modes = (0..modes)
        .map(|c| Mode {
            angular_frequency: rng.uniform(1.0, 10.0) * (c + 1) as f64,
            damping_ratio: rng.uniform(0.0, 0.1),
            translation: point.iter().map(|_| rng.vec3(0.4)).collect(),
            rotation: point.iter().map(|&p| if p { Vector3::zeros() } else { rng.vec3(0.6) }).collect(),
        })
        .collect();
}

#[test]
fn chain_of_200_bodies_on_a_free_base() {
    let mut rng = Rng::new(200);
    let vehicle = random_vehicle(&mut rng, TreeOptions { bodies: 201, free_base: true, passive: false, chain: true });
    check_vehicle(&vehicle, &mut rng).unwrap();
}

#[test]
fn tree_of_220_bodies_with_passive_forces() {
    let mut rng = Rng::new(220);
    let vehicle = random_vehicle(&mut rng, TreeOptions { bodies: 220, free_base: true, passive: true, chain: false });
    check_vehicle(&vehicle, &mut rng).unwrap();
}

/// ν̇, θ̇ and the momentum with the shortcuts `Model::compile` found and
/// with none: skipping a term the vehicle does not have must not change a
/// number beyond round-off.
fn check_shortcuts_change_nothing(vehicle: &Vehicle, rng: &mut Rng) -> Result<Shortcuts, String> {
    let fast = Model::compile(vehicle).map_err(|e| e.to_string())?;
    let mut general = fast.clone();
    general.shortcuts = Shortcuts::none();
    let theta = random_theta(rng, vehicle);
    let nu = rng.vec(fast.nv, 1.5);
    let eps = rng.vec(fast.nv, 2.0);
    let mut results = Vec::new();
    for model in [&fast, &general] {
        let mut ws = model.workspace();
        nudyn::dynamics::forward(model, &mut ws, &theta, &nu, &eps).map_err(|e| e.to_string())?;
        let momentum = ws.momentum(model).map_err(|e| e.to_string())?;
        results.push((ws.nu_dot.clone(), ws.qvel.clone(), ws.coriolis.clone(), momentum));
    }
    let (a, b) = (&results[0], &results[1]);
    for (what, x, y) in [
        ("nu_dot", a.0.as_slice(), b.0.as_slice()),
        ("qvel", a.1.as_slice(), b.1.as_slice()),
        ("coriolis", a.2.as_slice(), b.2.as_slice()),
        ("momentum", a.3.as_slice(), b.3.as_slice()),
    ] {
        let err = rel_err(x, y);
        if err > 1e-15 {
            return Err(format!("{what} with shortcuts {:?} differs by {err:.3e}", fast.shortcuts));
        }
    }
    Ok(fast.shortcuts)
}

/// A free base carrying a chain of hinges and slides, with each of gravity,
/// springs, dampers and armature present or not: every combination of
/// shortcuts, each checked against the dense reference and against the
/// general path.
#[test]
fn every_combination_of_shortcuts_on_one_dof_chains() {
    let mut rng = Rng::new(7);
    for combination in 0..16u32 {
        let present = |bit: u32| combination & (1 << bit) != 0;
        let mut vehicle =
            random_vehicle(&mut rng, TreeOptions { bodies: 7, free_base: true, passive: true, chain: true });
        vehicle.gravity =
            if present(0) { nalgebra::Vector3::new(0.3, -0.2, -9.81) } else { nalgebra::Vector3::zeros() };
        for (b, body) in vehicle.bodies.iter_mut().enumerate() {
            for joint in &mut body.joints {
                if b > 0 {
                    // Only 1-dof joints past the base.
                    joint.kind = if joint.kind == nudyn::vehicle::JointKind::Slide {
                        joint.kind
                    } else {
                        nudyn::vehicle::JointKind::Hinge
                    };
                }
                if !present(1) {
                    joint.stiffness = 0.0;
                }
                if !present(2) {
                    joint.damping = 0.0;
                }
                joint.armature = if present(3) && b > 0 { 0.1 + 0.05 * b as f64 } else { 0.0 };
            }
        }
        let shortcuts = check_shortcuts_change_nothing(&vehicle, &mut rng).unwrap();
        assert_eq!(
            [shortcuts.no_gravity, shortcuts.no_springs, shortcuts.no_dampers, shortcuts.no_armature],
            [!present(0), !present(1), !present(2), !present(3)],
            "combination {combination:04b}"
        );
        check_vehicle(&vehicle, &mut rng).unwrap_or_else(|e| panic!("combination {combination:04b}: {e}"));
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, ..ProptestConfig::default() })]

    #[test]
    fn shortcuts_change_nothing_on_random_trees(seed in any::<u64>(), bodies in 1usize..9, free_base in any::<bool>(), passive in any::<bool>()) {
        let mut rng = Rng::new(seed);
        let vehicle = random_vehicle(&mut rng, TreeOptions { bodies, free_base, passive, chain: false });
        if let Err(e) = check_shortcuts_change_nothing(&vehicle, &mut rng) {
            prop_assert!(false, "{e}\n{vehicle:#?}");
        }
    }
}

/// `tests/fixtures/mjcf/every_shortcut.xml` is the vehicle on which the
/// Python tests compare the fully specialized passes with MuJoCo: it must
/// keep taking every shortcut.
#[test]
fn the_every_shortcut_fixture_takes_every_shortcut() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/mjcf/every_shortcut.xml");
    let model = Model::compile(&nudyn::mjcf::load_mjcf(&path).unwrap().vehicle).unwrap();
    let s = model.shortcuts;
    assert!(s.no_gravity && s.no_springs && s.no_dampers && s.no_armature && s.no_passive_forces(), "{s:?}");
    assert!(model.links.iter().skip(2).all(|l| l.ndof == 1), "only 1-dof joints past the free base");
}

/// Joints of `vehicle` about coordinate axes through their body origins
/// (most MJCF joints): about every other body's first joint, if a hinge or
/// ball, gets anchor 0 and axis e_x, e_y or e_z, the shapes the passes
/// specialize on (subspace.rs). Only the first: two joints of a body about
/// one axis through one point would move it one way twice.
fn align_some_joints(vehicle: &mut Vehicle, rng: &mut Rng) {
    let axes = [nalgebra::Vector3::x(), nalgebra::Vector3::y(), nalgebra::Vector3::z()];
    for joint in vehicle.bodies.iter_mut().filter_map(|body| body.joints.first_mut()) {
        if matches!(joint.kind, JointKind::Hinge | JointKind::Ball) && rng.below(2) == 0 {
            joint.pos = nalgebra::Vector3::zeros();
            joint.axis = axes[rng.below(3)];
        }
    }
}

/// ν̇, C, θ̇, ν (pass 2 from θ̇) and θ̈ with the subspaces' shapes as found
/// and with every link taken as general: the specialized passes must give
/// the same numbers bit for bit.
fn check_shapes_change_no_bit(model: &Model, rng: &mut Rng, vehicle: &Vehicle) -> Result<(), String> {
    let theta = random_theta(rng, vehicle);
    let (nu, eps, qvel) = (rng.vec(model.nv, 1.5), rng.vec(model.nv, 2.0), rng.vec(model.nv, 1.0));
    let mut results = Vec::new();
    for general in [false, true] {
        let mut ws = model.workspace();
        if general {
            let forced =
                |link: &nudyn::model::Link| if link.ndof == 1 { Subspace::General1 } else { Subspace::General3 };
            ws.subspaces = model.links.iter().map(forced).collect();
        }
        nudyn::dynamics::forward(model, &mut ws, &theta, &nu, &eps).map_err(|e| e.to_string())?;
        let (nu_dot, coriolis, from_nu) = (ws.nu_dot.clone(), ws.coriolis.clone(), ws.qvel.clone());
        ws.set_qvel(model, &qvel).map_err(|e| e.to_string())?;
        ws.compute_qacc(model, &eps).map_err(|e| e.to_string())?;
        results.push([nu_dot, coriolis, from_nu, ws.nu.clone(), ws.qacc.clone()]);
    }
    let names = ["nu_dot", "coriolis", "qvel", "nu", "qacc"];
    for ((name, specialized), general) in names.iter().zip(&results[0]).zip(&results[1]) {
        if specialized != general {
            return Err(format!("{name} differs: {specialized:?} against {general:?}"));
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn axis_aligned_joints_agree_with_the_dense_reference_and_with_the_general_passes(
        seed in any::<u64>(), bodies in 2usize..9, free_base in any::<bool>(), passive in any::<bool>()
    ) {
        let mut rng = Rng::new(seed);
        let mut vehicle = random_vehicle(&mut rng, TreeOptions { bodies, free_base, passive, chain: false });
        align_some_joints(&mut vehicle, &mut rng);
        if let Err(e) = check_vehicle(&vehicle, &mut rng) {
            prop_assert!(false, "{e}\n{vehicle:#?}");
        }
        let model = Model::compile(&vehicle).unwrap();
        if let Err(e) = check_shapes_change_no_bit(&model, &mut rng, &vehicle) {
            prop_assert!(false, "{e}\n{vehicle:#?}");
        }
    }
}

/// bus_arm7's links take every specialized shape: the free joint's two
/// halves and hinges about x, y and z (the last two bodies rotated in
/// their parents), and the passes give the general passes' bits.
#[test]
fn bus_arm7_takes_the_specialized_shapes_with_the_general_numbers() {
    let imported = nudyn::mjcf::load_mjcf(std::path::Path::new("examples/bus_arm7.xml")).unwrap();
    let model = Model::compile(&imported.vehicle).unwrap();
    use Subspace::*;
    let shapes = model.workspace().subspaces;
    assert_eq!(shapes, [Translation, Rotation, AboutX, AboutY, AboutX, AboutY, AboutX, AboutY, AboutZ]);
    let mut rng = Rng::new(36);
    check_shapes_change_no_bit(&model, &mut rng, &imported.vehicle).unwrap();
}
