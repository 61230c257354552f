//! ROS34PW2's matrix W from exact derivatives (dual numbers through the
//! passes) against the same W by forward differences, formed at the same
//! point by two runs that differ only in W's source; and the models the
//! derivatives do not cover, whose W stays by differences.

use std::path::Path;

use nudyn::integrate::{HeldJacobian, Input, JacobianSource, Method, Settings, Simulation, Stats, retract};
use nudyn::model::Model;

use crate::common;

fn load(path: &str) -> Model {
    let imported = nudyn::mjcf::load_mjcf(Path::new(path)).unwrap();
    Model::compile(&imported.vehicle).unwrap()
}

/// A moving start off the file's pose: every dof displaced along the
/// tangent space by up to `displaced` and spinning.
fn start(model: &Model, source: JacobianSource, displaced: f64) -> Simulation {
    let settings = Settings { tolerance: 1e-6, max_step: 0.0, energy_projection: false };
    let mut sim = Simulation::new(model, Method::Ros34pw2, settings);
    let delta: Vec<f64> = (0..model.nv).map(|k| displaced * (1.3 * k as f64 + 0.5).sin()).collect();
    retract(model, &mut sim.state.theta, &delta);
    sim.state.nu.iter_mut().enumerate().for_each(|(k, x)| *x = 0.3 * (k as f64 + 1.0).cos());
    sim.initialize(model).unwrap();
    sim.set_jacobian_source(source);
    sim
}

/// The W held after one short advance from [`start`], the actuators
/// driven, with the advance's counts: formed once, it was formed at the start.
fn first_w(model: &Model, source: JacobianSource, displaced: f64) -> (HeldJacobian, Stats) {
    let mut sim = start(model, source, displaced);
    let eps: Vec<f64> = (0..model.nv).map(|k| 0.1 * (k as f64).cos()).collect();
    let ctrl = vec![0.3; model.actuators.len()];
    let (zero_eps, zero_ctrl) = (vec![0.0; model.nv], vec![0.0; model.actuators.len()]);
    let input = Input { eps: &eps, eps_rate: &zero_eps, ctrl: &ctrl, ctrl_rate: &zero_ctrl };
    let stats = sim.advance_to(model, 1e-5, input).unwrap().stats;
    let mut w = HeldJacobian::default();
    sim.save_jacobian(&mut w);
    (w, stats)
}

/// max |a − b| / max |b| over each block of W (∂θ̈/∂Δ, then ∂θ̈/∂θ̇); NaN
/// where an entry is.
fn block_differences(model: &Model, exact: &HeldJacobian, differenced: &HeldJacobian) -> [f64; 2] {
    let block = model.nv * model.nv;
    let relative =
        |a: &[f64], b: &[f64]| common::max_abs_difference(a, b) / b.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    let (a, b) = (exact.derivatives.split_at(block), differenced.derivatives.split_at(block));
    [relative(a.0, b.0), relative(a.1, b.1)]
}

/// On vehicles with a free base (rotation vectors), ball joints, hinges
/// and slides, a flexible body, actuators, friction loss and joint limits,
/// and a weld: the exact W equals the differences' within their own error
/// (about √ε relative), and takes no evaluation of θ̈. The damped stiff
/// boom starts on its rest shape, as in stiff_integration.rs: displaced by
/// 0.04, its 10⁷ N·m/rad springs make θ̈ so large that the differences'
/// cancellation reaches 3e-6 of ∂θ̈/∂θ̇.
#[test]
fn exact_w_equals_the_differences_w() {
    for (path, displaced) in [
        ("examples/bus_arm7.xml", 0.04),
        ("examples/servicer.xml", 0.04),
        ("examples/flexible_boom.xml", 0.04),
        ("tests/fixtures/damped_stiff_boom.xml", 0.0),
        ("tests/fixtures/constraints/limited_arm.xml", 0.04),
        ("tests/fixtures/constraints/docked_servicer.xml", 0.04),
    ] {
        let model = load(path);
        let (exact, exact_stats) = first_w(&model, JacobianSource::Exact, displaced);
        let (differenced, differenced_stats) = first_w(&model, JacobianSource::Differences, displaced);
        assert_eq!((exact_stats.jacobians, exact_stats.exact_jacobians), (1, 1), "{path}: {exact_stats:?}");
        assert_eq!((differenced_stats.jacobians, differenced_stats.exact_jacobians), (1, 0), "{path}");
        let [by_delta, by_qvel] = block_differences(&model, &exact, &differenced);
        eprintln!("{path}: W exact against differences: ∂θ̈/∂Δ {by_delta:.1e}, ∂θ̈/∂θ̇ {by_qvel:.1e}");
        assert!(by_delta < 1e-6 && by_qvel < 1e-6, "{path}: {by_delta:e}, {by_qvel:e}");
        // The differences' 2·nv evaluations of θ̈ are the whole difference in counts when the steps agree.
        if exact_stats.accepted == differenced_stats.accepted && exact_stats.rejected == differenced_stats.rejected {
            assert_eq!(differenced_stats.evaluations - exact_stats.evaluations, 2 * model.nv, "{path}");
        }
    }
}

/// Activation states are not covered by the derivatives: W is by
/// differences there, with act's rows and columns.
#[test]
fn a_model_the_derivatives_do_not_cover_keeps_the_differences() {
    let model = load("tests/fixtures/activation/filtered_arm.xml");
    assert!(model.activation_count() > 0);
    let (exact, stats) = first_w(&model, JacobianSource::Exact, 0.04);
    let (differenced, _) = first_w(&model, JacobianSource::Differences, 0.04);
    assert_eq!((stats.jacobians, stats.exact_jacobians), (1, 0), "{stats:?}");
    assert_eq!(exact, differenced);
}
