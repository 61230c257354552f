//! `nudyn-bench`: the timing side of `scripts/bench.py`. It times nudyn
//! and MuJoCo (its C library, loaded from the mujoco Python package) side
//! by side in one process, and runs nudyn's integrators for the
//! work-precision comparison; it prints JSON that the driver turns into
//! the tables and plots of `docs/bench/`.

mod dense;
mod mujoco;
mod timing;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use nudyn::integrate::{Input, JacobianSource, MethodSetting, Settings, Simulation};
use nudyn::model::{Model, Shortcuts};
use nudyn::workspace::Workspace;
use serde::{Deserialize, Serialize};
use timing::Case;

#[derive(Parser)]
#[command(name = "nudyn-bench", about = "Timing side of scripts/bench.py: nudyn and MuJoCo side by side")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Nanoseconds per ν̇ evaluation (nudyn's `forward`: all four passes,
    /// from θ and ν), beside MuJoCo's pipelines on the same state, nudyn
    /// with each shortcut turned off, and the dense O(N³) path.
    EvalCost {
        /// The vehicle's MJCF file (nudyn's import).
        model: PathBuf,
        /// The state: a JSON file with "theta" (nq), "nu" and "qvel" (nv).
        #[arg(long)]
        state: PathBuf,
        /// MuJoCo's libmujoco.so; with --mujoco-model, also time MuJoCo.
        #[arg(long, requires = "mujoco_model")]
        mujoco_lib: Option<PathBuf>,
        /// The same vehicle for MuJoCo, as a binary model (mj_saveModel) with contacts and constraints off.
        #[arg(long, requires = "mujoco_lib")]
        mujoco_model: Option<PathBuf>,
        /// Also time nudyn with each shortcut the model takes turned off, and with none.
        #[arg(long)]
        shortcuts: bool,
        /// Also time the dense O(N³) path (and compare its ν̇ with nudyn's).
        #[arg(long)]
        dense: bool,
        /// Repetitions (one batch of each case per repetition).
        #[arg(long, default_value_t = 15)]
        repetitions: usize,
        /// Length of one batch (ms).
        #[arg(long, default_value_t = 20.0)]
        batch_ms: f64,
    },
    /// Nanoseconds per ν̇ evaluation of several vehicles, timed side by
    /// side (the scaling target's ratio of two chain lengths).
    EvalCostSideBySide {
        /// The vehicles' MJCF files, in order.
        #[arg(long = "model", required = true)]
        models: Vec<PathBuf>,
        /// Their states (as for eval-cost), one per --model, in the same order.
        #[arg(long = "state", required = true)]
        states: Vec<PathBuf>,
        /// Repetitions (one batch of each vehicle per repetition).
        #[arg(long, default_value_t = 15)]
        repetitions: usize,
        /// Length of one batch (ms).
        #[arg(long, default_value_t = 20.0)]
        batch_ms: f64,
    },
    /// Integrate with nudyn's methods from a given state, timing each run;
    /// prints the state at every sample time.
    Simulate {
        /// The vehicle's MJCF file.
        model: PathBuf,
        /// The initial state: a JSON file with "theta" (nq) and "nu" (nv).
        #[arg(long)]
        state: PathBuf,
        /// Simulated time (s).
        #[arg(long, default_value_t = 10.0)]
        duration: f64,
        /// Interval between samples (s): each is one call of the
        /// integrator's `advance`, as one FMU doStep.
        #[arg(long, default_value_t = 0.1)]
        sample: f64,
        /// Runs, as METHOD:VALUE — rk4:STEP, or dopri5, dop853, ros34pw2, bs3, tsit5 or auto with :TOLERANCE;
        /// ros34pw2 forms W in closed form where it covers the vehicle, else by forward
        /// differences; ros34pw2/exact (or auto/exact) adds the dual numbers' exact W where they cover
        /// the vehicle, ros34pw2/differences (or auto/differences) forms W by forward differences only.
        #[arg(long = "run", required = true)]
        runs: Vec<String>,
        /// Timed repetitions of each run.
        #[arg(long, default_value_t = 1)]
        repetitions: usize,
        /// Print only times and step counts, not the sampled states.
        #[arg(long)]
        no_samples: bool,
    },
}

/// A state read from a JSON file.
#[derive(Deserialize)]
struct State {
    theta: Vec<f64>,
    nu: Vec<f64>,
    qvel: Option<Vec<f64>>,
}

fn read_json<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<T> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{} is not the expected JSON", path.display()))
}

fn load_model(path: &Path) -> Result<Model> {
    let imported = nudyn::mjcf::load_mjcf(path).with_context(|| format!("cannot import {}", path.display()))?;
    Model::compile(&imported.vehicle).with_context(|| format!("cannot compile {}", path.display()))
}

fn main() -> Result<()> {
    match Cli::parse().command {
        Command::EvalCost { model, state, mujoco_lib, mujoco_model, shortcuts, dense, repetitions, batch_ms } => {
            let mujoco = mujoco_lib.zip(mujoco_model);
            let options = CostOptions { shortcuts, dense, repetitions, batch: Duration::from_secs_f64(batch_ms / 1e3) };
            let result = eval_cost(&load_model(&model)?, &read_json(&state)?, mujoco.as_ref(), &options)?;
            println!("{}", serde_json::to_string(&result)?);
        }
        Command::EvalCostSideBySide { models, states, repetitions, batch_ms } => {
            if models.len() != states.len() {
                bail!("{} --model but {} --state: give one state per model", models.len(), states.len());
            }
            let vehicles = models
                .iter()
                .zip(&states)
                .map(|(model, state)| Ok((load_model(model)?, read_json::<State>(state)?)))
                .collect::<Result<Vec<_>>>()?;
            let result =
                eval_cost_side_by_side(&models, &vehicles, repetitions, Duration::from_secs_f64(batch_ms / 1e3))?;
            println!("{}", serde_json::to_string(&result)?);
        }
        Command::Simulate { model, state, duration, sample, runs, repetitions, no_samples } => {
            let model = load_model(&model)?;
            let state: State = read_json(&state)?;
            let mut results = Vec::new();
            for run in &runs {
                results.push(simulate(&model, &state, run, duration, sample, repetitions, !no_samples)?);
            }
            println!("{}", serde_json::to_string(&results)?);
        }
    }
    Ok(())
}

struct CostOptions {
    shortcuts: bool,
    dense: bool,
    repetitions: usize,
    batch: Duration,
}

#[derive(Serialize)]
struct CostResult {
    nv: usize,
    /// The shortcuts the compiled model takes.
    shortcuts: Shortcuts,
    /// Nanoseconds per evaluation, per case, one entry per repetition.
    nanoseconds: std::collections::BTreeMap<String, Vec<f64>>,
    /// max |ν̇_dense − ν̇| / max(1, max |ν̇|), when the dense path ran.
    dense_difference: Option<f64>,
}

/// The model with one shortcut turned off.
fn without(model: &Model, name: &str) -> Model {
    let mut general = model.clone();
    let s = &mut general.shortcuts;
    match name {
        "no_gravity" => s.no_gravity = false,
        "no_springs" => s.no_springs = false,
        "no_dampers" => s.no_dampers = false,
        "no_armature" => s.no_armature = false,
        _ => *s = Shortcuts::none(),
    }
    general
}

fn eval_cost(
    model: &Model,
    state: &State,
    mujoco: Option<&(PathBuf, PathBuf)>,
    options: &CostOptions,
) -> Result<CostResult> {
    let eps = vec![0.0; model.nv];
    // Variants of the model: as compiled, then each shortcut it takes turned off, then none.
    let taken = model.shortcuts;
    let mut variants = vec![("nudyn".to_string(), model.clone())];
    if options.shortcuts {
        for (name, on) in [
            ("no_gravity", taken.no_gravity),
            ("no_springs", taken.no_springs),
            ("no_dampers", taken.no_dampers),
            ("no_armature", taken.no_armature),
        ] {
            if on {
                variants.push((format!("nudyn without {name}"), without(model, name)));
            }
        }
        variants.push(("nudyn without shortcuts".to_string(), without(model, "all")));
    }
    let mut workspaces: Vec<_> = variants.iter().map(|(_, m)| m.workspace()).collect();
    for (ws, (_, m)) in workspaces.iter_mut().zip(&variants) {
        nudyn::dynamics::forward(m, ws, &state.theta, &state.nu, &eps)?;
    }
    let mut dense_ws = model.workspace();
    let dense_difference = if options.dense {
        dense::check_supported(model)?;
        let dense = dense::nu_dot(model, &mut dense_ws, &state.theta, &state.nu)?;
        let fast = &workspaces[0].nu_dot;
        Some((&dense - fast).amax() / fast.amax().max(1.0))
    } else {
        None
    };

    let api = mujoco.map(|(lib, _)| mujoco::Api::load(lib)).transpose()?;
    let mut simulations = Vec::new();
    if let (Some(api), Some((_, path))) = (&api, mujoco) {
        for pipeline in mujoco::Pipeline::ALL {
            let mut simulation = mujoco::Simulation::load(api, path)?;
            let qvel = state.qvel.as_ref().context("the state has no qvel, which MuJoCo needs")?;
            simulation.set_state(&state.theta, qvel)?;
            simulations.push((pipeline, simulation));
        }
    }

    // The physical ports: the same state with the actuators at a fixed
    // ctrl, then with the sensors evaluated too; and the vehicle stripped of
    // both, which must cost what "nudyn" costs.
    let ported = !model.actuators.is_empty() || !model.sensors.is_empty();
    let stripped = stripped_of_ports(model);
    let mut stripped_ws = stripped.workspace();
    let ctrl = mid_range_ctrl(model);
    // The activation states at MuJoCo's start.
    let act = vec![0.0; model.activation_count()];
    let (mut actuated_ws, mut sensed_ws) = (model.workspace(), model.workspace());

    let mut qacc_ws = model.workspace();
    let mut derivatives = Some(nudyn::dynamics::derivatives::Derivatives::new(model));
    let mut jacobian_derivatives = derivatives.clone();
    // ros34pw2 forms no exact W with activation states (its act rows and columns).
    let mut w_derivatives = derivatives.clone().filter(|_| model.activation_count() == 0);
    let mut w_ws = model.workspace();
    let mut closed_form = nudyn::dynamics::qacc_jacobian::QaccJacobian::new(model).ok();
    let mut closed_form_with_eps = closed_form.clone();
    let square = || nalgebra::DMatrix::zeros(model.nv, model.nv);
    let (mut closed_form_out, mut closed_form_with_eps_out) = ((square(), square()), (square(), square()));
    let mut unit = vec![0.0; model.nv];
    let zeros = nudyn::dynamics::derivatives::Input::ALL.map(|input| vec![0.0; input.len(model)]);
    let ones = vec![1.0; model.nv];
    let mut cases: Vec<Case> = Vec::new();
    for ((name, m), ws) in variants.iter().zip(workspaces.iter_mut()) {
        cases.push(forward_case(name.clone(), m, ws, state, &eps));
    }
    if let Some(qvel) = &state.qvel {
        cases.push(qacc_case(model, &mut qacc_ws, &state.theta, qvel, &eps));
    }
    if let Some(derivatives) = derivatives.as_mut() {
        cases.push(directional_derivative_case(model, derivatives, state, (&eps, &ctrl, &act), &ones));
    }
    if let Some(derivatives) = jacobian_derivatives.as_mut() {
        cases.push(jacobian_case(model, derivatives, state, (&eps, &ctrl, &act)));
    }
    if let (Some(qvel), Some(derivatives)) = (&state.qvel, w_derivatives.as_mut()) {
        cases.push(exact_w_case(model, derivatives, (&state.theta, qvel), (&mut unit, &zeros)));
    }
    let zero = &zeros[nudyn::dynamics::derivatives::Input::Eps as usize];
    if let (Some(qvel), Some(closed_form)) = (&state.qvel, closed_form.as_mut()) {
        let name = "nudyn θ̈ Jacobians in θ and θ̇ (closed form)";
        let state = (state.theta.as_slice(), qvel.as_slice());
        cases.push(closed_form_case(name, model, closed_form, state, (zero, zero, &ctrl), &mut closed_form_out));
    }
    if let (Some(qvel), Some(closed_form)) = (&state.qvel, closed_form_with_eps.as_mut()) {
        let name = "nudyn θ̈ Jacobians in θ and θ̇ (closed form, ε = 1 on every dof)";
        let state = (state.theta.as_slice(), qvel.as_slice());
        cases.push(closed_form_case(
            name,
            model,
            closed_form,
            state,
            (&ones, zero, &ctrl),
            &mut closed_form_with_eps_out,
        ));
    }
    if let Some(qvel) = &state.qvel {
        cases.push(differences_w_case(model, &mut w_ws, &state.theta, qvel, &eps));
    }
    if ported {
        cases.push(forward_case(
            "nudyn stripped of actuators and sensors".into(),
            &stripped,
            &mut stripped_ws,
            state,
            &eps,
        ));
        cases.push(ported_case("nudyn with actuators".into(), model, &mut actuated_ws, state, &eps, &ctrl, false));
        cases.push(ported_case(
            "nudyn with actuators and sensors".into(),
            model,
            &mut sensed_ws,
            state,
            &eps,
            &ctrl,
            true,
        ));
    }
    for (pipeline, simulation) in simulations.iter_mut() {
        let pipeline = *pipeline;
        cases.push(Case { name: pipeline.name().to_string(), call: Box::new(move || simulation.evaluate(pipeline)) });
    }
    if options.dense {
        let (theta, nu) = (&state.theta, &state.nu);
        let dense_ws = &mut dense_ws;
        cases.push(Case {
            name: "dense".to_string(),
            call: Box::new(move || {
                dense::nu_dot(model, dense_ws, theta, nu).expect("the dense path evaluates");
            }),
        });
    }
    let times = timing::interleaved(&mut cases, options.repetitions, options.batch);
    let nanoseconds = cases.iter().map(|c| c.name.clone()).zip(times).collect();
    Ok(CostResult { nv: model.nv, shortcuts: taken, nanoseconds, dense_difference })
}

/// The integrators' rate: θ̈ from θ and θ̇ (passes 0–2 from θ̇, pass 3
/// without the factor's rates, the outward pass), as each stage evaluates it.
fn qacc_case<'a>(
    model: &'a Model,
    ws: &'a mut Workspace,
    theta: &'a [f64],
    qvel: &'a [f64],
    eps: &'a [f64],
) -> Case<'a> {
    Case {
        name: "nudyn qacc (integrator stage)".to_string(),
        call: Box::new(move || {
            ws.set_configuration(model, std::hint::black_box(theta)).expect("the state evaluates");
            ws.set_qvel(model, qvel).expect("the state evaluates");
            ws.compute_qacc(model, eps).expect("the state evaluates");
        }),
    }
}

/// A timed case of one directional derivative of ν̇ (and θ̇) at `state`,
/// along `direction` in θ (tangent), ν and ε at once: the passes in dual numbers.
fn directional_derivative_case<'a>(
    model: &'a Model,
    derivatives: &'a mut nudyn::dynamics::derivatives::Derivatives,
    state: &'a State,
    (eps, ctrl, act): (&'a [f64], &'a [f64], &'a [f64]),
    direction: &'a [f64],
) -> Case<'a> {
    use nudyn::dynamics::derivatives::{Direction, ThetaDirection};
    Case {
        name: "nudyn directional derivative of ν̇ (dual numbers)".to_string(),
        call: Box::new(move || {
            let point = derivative_point(state, eps, ctrl, act);
            let along = Direction {
                theta: direction,
                theta_in: ThetaDirection::Tangent,
                velocity: direction,
                eps: direction,
                torque: eps,
                ctrl,
                act,
            };
            derivatives
                .run(model, &point, &along, &[nudyn::dynamics::derivatives::Output::NuDot])
                .expect("the state evaluates");
        }),
    }
}

/// The point of the derivatives' cases: `state` (θ, ν) with ε and the
/// joint forces both `eps`, `ctrl` and `act`.
fn derivative_point<'a>(
    state: &'a State,
    eps: &'a [f64],
    ctrl: &'a [f64],
    act: &'a [f64],
) -> nudyn::dynamics::derivatives::Point<'a> {
    let given = nudyn::dynamics::velocity::Given::Nu;
    let theta = std::hint::black_box(state.theta.as_slice());
    nudyn::dynamics::derivatives::Point { theta, velocity: &state.nu, given, eps, torque: eps, ctrl, act, time: 0.0 }
}

/// A timed case of the Jacobians of ν̇ in θ, ν, ε, T, ctrl and act at `state`
/// (4nv + nu directions, one run each).
fn jacobian_case<'a>(
    model: &'a Model,
    derivatives: &'a mut nudyn::dynamics::derivatives::Derivatives,
    state: &'a State,
    (eps, ctrl, act): (&'a [f64], &'a [f64], &'a [f64]),
) -> Case<'a> {
    Case {
        name: "nudyn Jacobians of ν̇ (dual numbers)".to_string(),
        call: Box::new(move || {
            let point = derivative_point(state, eps, ctrl, act);
            let nu_dot = nudyn::dynamics::derivatives::Output::NuDot;
            derivatives.jacobians(model, &point, nu_dot).expect("the state evaluates");
        }),
    }
}

/// A timed case of ROS34PW2's W from exact derivatives, as the integrator
/// forms it: ∂θ̈/∂Δ and ∂θ̈/∂θ̇, one run of the passes in dual numbers
/// per column (2·nv), θ̈ only, ε and ctrl 0.
fn exact_w_case<'a>(
    model: &'a Model,
    derivatives: &'a mut nudyn::dynamics::derivatives::Derivatives,
    (theta, qvel): (&'a [f64], &'a [f64]),
    (unit, zeros): (&'a mut [f64], &'a [Vec<f64>; 6]),
) -> Case<'a> {
    use nudyn::dynamics::derivatives::{Direction, Input, Output, Point};
    Case {
        name: "nudyn ros34pw2 W from exact derivatives (2nv runs in dual numbers)".to_string(),
        call: Box::new(move || {
            let given = nudyn::dynamics::velocity::Given::Qvel;
            let theta = std::hint::black_box(theta);
            let zero = |input: Input| zeros[input as usize].as_slice();
            let (eps, torque, ctrl) = (zero(Input::Eps), zero(Input::Torque), zero(Input::Ctrl));
            let point = Point { theta, velocity: qvel, given, eps, torque, ctrl, act: &[], time: 0.0 };
            for input in [Input::Theta, Input::Velocity] {
                for column in 0..model.nv {
                    unit[column] = 1.0;
                    let direction = Direction::along(input, unit, zeros);
                    derivatives.run(model, &point, &direction, &[Output::Qacc]).expect("the state evaluates");
                    std::hint::black_box(derivatives.derivative(Output::Qacc).sum::<f64>());
                    unit[column] = 0.0;
                }
            }
        }),
    }
}

/// A timed case of ∂θ̈/∂Δ and ∂θ̈/∂θ̇ in closed form (qacc_jacobian.rs)
/// with `eps` applied, no joint forces and the actuators at `ctrl`: what Pinocchio's
/// `computeABADerivatives` gives for θ and θ̇ (with ε 0), and ros34pw2's W.
fn closed_form_case<'a>(
    name: &str,
    model: &'a Model,
    closed_form: &'a mut nudyn::dynamics::qacc_jacobian::QaccJacobian,
    (theta, qvel): (&'a [f64], &'a [f64]),
    (eps, torque, ctrl): (&'a [f64], &'a [f64], &'a [f64]),
    (by_delta, by_qvel): &'a mut (nalgebra::DMatrix<f64>, nalgebra::DMatrix<f64>),
) -> Case<'a> {
    Case {
        name: name.to_string(),
        call: Box::new(move || {
            let theta = std::hint::black_box(theta);
            let inputs = (eps, torque, ctrl);
            closed_form.compute(model, (theta, qvel), inputs, (by_delta, by_qvel)).expect("the state evaluates");
        }),
    }
}

/// A timed case of ROS34PW2's W by forward differences, as the integrator
/// forms it: 2·nv evaluations of θ̈, each at θ moved along one tangent
/// direction or θ̇ along one entry (the actuators at ctrl 0).
fn differences_w_case<'a>(
    model: &'a Model,
    ws: &'a mut Workspace,
    theta: &'a [f64],
    qvel: &'a [f64],
    eps: &'a [f64],
) -> Case<'a> {
    let (mut moved_theta, mut moved_qvel, mut delta) = (theta.to_vec(), qvel.to_vec(), vec![0.0; model.nv]);
    let no_ctrl = vec![0.0; model.actuators.len()];
    Case {
        name: "nudyn ros34pw2 W by forward differences (2nv evaluations of θ̈)".to_string(),
        call: Box::new(move || {
            for column in 0..2 * model.nv {
                moved_theta.copy_from_slice(std::hint::black_box(theta));
                moved_qvel.copy_from_slice(qvel);
                if column < model.nv {
                    delta[column] = 1.5e-8;
                    nudyn::integrate::retract(model, &mut moved_theta, &delta);
                    delta[column] = 0.0;
                } else {
                    moved_qvel[column - model.nv] += 1.5e-8;
                }
                ws.set_configuration(model, &moved_theta).expect("the state evaluates");
                ws.set_qvel(model, &moved_qvel).expect("the state evaluates");
                ws.compute_qacc_actuated(model, eps, &no_ctrl).expect("the state evaluates");
            }
        }),
    }
}

/// A timed case of nudyn's ν̇: one `forward` from `state` with applied `eps`.
fn forward_case<'a>(
    name: String,
    model: &'a Model,
    ws: &'a mut Workspace,
    state: &'a State,
    eps: &'a [f64],
) -> Case<'a> {
    let (theta, nu) = (&state.theta, &state.nu);
    Case {
        name,
        call: Box::new(move || {
            nudyn::dynamics::forward(model, ws, std::hint::black_box(theta), nu, eps).expect("the state evaluates");
        }),
    }
}

/// The model without actuators, sensors and wrench inputs.
fn stripped_of_ports(model: &Model) -> Model {
    let mut stripped = model.clone();
    stripped.actuators.clear();
    stripped.actuator_force_limits.clear();
    stripped.wrench_bodies.clear();
    stripped.sensors.clear();
    stripped.body_masses.clear();
    stripped.link_tree_quats.clear();
    stripped
}

/// A fixed ctrl that makes every actuator act: the middle of a limited
/// range, 0.5 otherwise.
fn mid_range_ctrl(model: &Model) -> Vec<f64> {
    model.actuators.iter().map(|a| a.ctrl_range.map_or(0.5, |[low, high]| 0.5 * (low + high))).collect()
}

/// A timed case of ν̇ with the actuators at `ctrl` (passes 0–3 and the
/// actuation), and with `sensors` the sensors too.
fn ported_case<'a>(
    name: String,
    model: &'a Model,
    ws: &'a mut Workspace,
    state: &'a State,
    eps: &'a [f64],
    ctrl: &'a [f64],
    sensors: bool,
) -> Case<'a> {
    Case {
        name,
        call: Box::new(move || {
            ws.set_configuration(model, std::hint::black_box(&state.theta)).expect("the state evaluates");
            ws.set_nu(model, &state.nu).expect("the state evaluates");
            ws.compute_nu_dot_actuated(model, eps, ctrl).expect("the state evaluates");
            if sensors {
                ws.compute_sensors(model, eps, ctrl, 0.0).expect("the state evaluates");
            }
        }),
    }
}

/// One vehicle's times from `eval-cost-side-by-side`.
#[derive(Serialize)]
struct SideBySideEntry {
    model: PathBuf,
    nv: usize,
    /// Nanoseconds per evaluation, one entry per repetition.
    nanoseconds: Vec<f64>,
}

fn eval_cost_side_by_side(
    paths: &[PathBuf],
    vehicles: &[(Model, State)],
    repetitions: usize,
    batch: Duration,
) -> Result<Vec<SideBySideEntry>> {
    let mut prepared = Vec::new();
    for (model, state) in vehicles {
        let eps = vec![0.0; model.nv];
        let mut ws = model.workspace();
        nudyn::dynamics::forward(model, &mut ws, &state.theta, &state.nu, &eps)?;
        prepared.push((model, state, eps, ws));
    }
    let mut cases: Vec<Case> = prepared
        .iter_mut()
        .zip(paths)
        .map(|((model, state, eps, ws), path)| forward_case(path.display().to_string(), model, ws, state, eps))
        .collect();
    let times = timing::interleaved(&mut cases, repetitions, batch);
    Ok(paths
        .iter()
        .zip(vehicles)
        .zip(times)
        .map(|((model, (m, _)), nanoseconds)| SideBySideEntry { model: model.clone(), nv: m.nv, nanoseconds })
        .collect())
}

#[derive(Serialize)]
struct SimulateResult {
    run: String,
    /// Wall time of each repetition (s): the integration only.
    seconds: Vec<f64>,
    /// Steps accepted and rejected in the (last) run, evaluations of the
    /// rates, and the times a Rosenbrock method formed its W.
    accepted: usize,
    rejected: usize,
    evaluations: usize,
    jacobians: usize,
    /// Of those W, the ones formed from exact derivatives (closed form or dual numbers).
    exact_jacobians: usize,
    /// Steps past a sample point taken again to end there, their interpolant refused.
    refused_interpolants: usize,
    /// Why the run stopped early, if it did (then the samples end there).
    failed: Option<String>,
    /// With `auto`: the method it chose at the start and ended with, and its log messages.
    chosen: Option<&'static str>,
    ended_with: Option<&'static str>,
    choice: Vec<String>,
    time: Vec<f64>,
    qpos: Vec<Vec<f64>>,
    qvel: Vec<Vec<f64>>,
}

fn simulate(
    model: &Model,
    state: &State,
    run: &str,
    duration: f64,
    sample: f64,
    repetitions: usize,
    samples: bool,
) -> Result<SimulateResult> {
    let (method_name, value) = run.split_once(':').with_context(|| format!("--run {run}: expected METHOD:VALUE"))?;
    let (method_name, source) = match method_name.split_once('/') {
        Some((method_name, "exact")) => (method_name, JacobianSource::Exact),
        Some((method_name, "differences")) => (method_name, JacobianSource::Differences),
        Some(_) => bail!("--run {run}: the W source after / is exact or differences"),
        None => (method_name, JacobianSource::default()),
    };
    let method = MethodSetting::from_name(method_name).with_context(|| format!("--run {run}: unknown method"))?;
    let value: f64 = value.parse().with_context(|| format!("--run {run}: not a number"))?;
    let settings = if !matches!(method, MethodSetting::Fixed(m) if !m.is_adaptive()) {
        // No max_step, as the FMU's default: the sample points bound the steps.
        Settings { tolerance: value, max_step: 0.0, energy_projection: false }
    } else {
        Settings { tolerance: 1.0, max_step: value, energy_projection: false }
    };
    let intervals = (duration / sample).round() as usize;
    if (intervals as f64 * sample - duration).abs() > 1e-9 * duration {
        bail!("--duration {duration} is not a multiple of --sample {sample}");
    }
    let mut ws = model.workspace();
    let mut result = SimulateResult {
        run: run.to_string(),
        seconds: Vec::new(),
        accepted: 0,
        rejected: 0,
        evaluations: 0,
        jacobians: 0,
        exact_jacobians: 0,
        refused_interpolants: 0,
        failed: None,
        chosen: None,
        ended_with: None,
        choice: Vec::new(),
        time: Vec::new(),
        qpos: Vec::new(),
        qvel: Vec::new(),
    };
    let mut reached = intervals;
    // Preallocated outside the timed loop: the sampled (θ, ν).
    let mut trajectory = vec![(state.theta.clone(), state.nu.clone()); intervals + 1];
    let zero = vec![0.0; model.nv];
    let input = Input { eps: &zero, eps_rate: &zero, ctrl: &[], ctrl_rate: &[] };
    let start_run = || {
        let mut sim = Simulation::new(model, method, settings);
        sim.set_jacobian_source(source);
        sim.state.theta.copy_from_slice(&state.theta);
        sim.state.nu.copy_from_slice(&state.nu);
        sim
    };
    // Untimed, one sample long, as on MuJoCo's side: a run timed cold is slower.
    // A failure here shows again, and is reported, in the timed run.
    let _ = start_run().advance_to(model, sample, input);
    for _ in 0..repetitions {
        let mut sim = start_run();
        result.choice.clear();
        let (mut accepted, mut rejected, mut evaluations, mut jacobians, mut exact_jacobians) = (0, 0, 0, 0, 0);
        let mut refused_interpolants = 0;
        let start = Instant::now();
        for n in 0..intervals {
            let t = n as f64 * sample;
            match sim.advance_to(model, t + sample, input) {
                Ok(advanced) => {
                    accepted += advanced.stats.accepted;
                    rejected += advanced.stats.rejected;
                    evaluations += advanced.stats.evaluations;
                    jacobians += advanced.stats.jacobians;
                    exact_jacobians += advanced.stats.exact_jacobians;
                    refused_interpolants += advanced.stats.refused_interpolants;
                    if let Some(choice) = advanced.chose {
                        result.chosen = Some(choice.method.name());
                        result.choice.push(choice.to_string());
                    }
                    if let Some(moved) = advanced.moved {
                        result.choice.push(moved.to_string());
                    }
                }
                Err(error) => {
                    // Too large a step for the motion: a point of the curve all the same.
                    result.failed = Some(error.to_string());
                    reached = n;
                    break;
                }
            }
            trajectory[n + 1].0.copy_from_slice(&sim.state.theta);
            trajectory[n + 1].1.copy_from_slice(&sim.state.nu);
        }
        result.seconds.push(start.elapsed().as_secs_f64());
        result.ended_with = sim.state.auto_choice.map(|choice| choice.method.name());
        (result.accepted, result.rejected, result.evaluations, result.jacobians, result.exact_jacobians) =
            (accepted, rejected, evaluations, jacobians, exact_jacobians);
        result.refused_interpolants = refused_interpolants;
    }
    if samples {
        for (n, (theta, nu)) in trajectory.iter().enumerate().take(reached + 1) {
            ws.set_configuration(model, theta)?;
            ws.set_nu(model, nu)?;
            result.time.push(n as f64 * sample);
            result.qpos.push(ws.theta.as_slice().to_vec());
            result.qvel.push(ws.qvel.as_slice().to_vec());
        }
    }
    Ok(result)
}
