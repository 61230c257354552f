//! The `nudyn` command line.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use nudyn::control::ControlLaw;
use nudyn::eval::{EvalRequest, EvalResponse, evaluate};
use nudyn::integrate::{Input, Method, Settings, Simulation};
use nudyn::model::Model;
use nudyn::vehicle::Vehicle;
use nudyn_cli::export::controller::write_controller_fmu;
use nudyn_cli::export::model_identifier_from;
use nudyn_cli::export::plant::{ExportOptions, write_fmu};
use nudyn_contract::plant::{DEFAULT_TOLERANCE, OptionalOutputs};
use serde::{Deserialize, Serialize};

#[derive(Parser)]
#[command(name = "nudyn", version, about = "Diagonalized dynamics of robotic space vehicles, as FMI 2.0 FMUs")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Evaluate ν̇, C(θ,ν), ε, energy and momentum for JSON states read on stdin.
    ///
    /// Input: one object, or an array of objects, with "theta" (nq), "nu" or
    /// "qvel" (nv), and optionally "eps" and "torque" (nv). Output: one JSON
    /// object per input with theta, qvel, nu, nu_dot, coriolis, eps,
    /// eps_passive, kinetic_energy, power, momentum.
    Eval {
        /// The vehicle's MJCF file.
        model: PathBuf,
    },
    /// Export the vehicle as an FMI 2.0 co-simulation FMU.
    ///
    /// The FMU's binary is the `nudyn_fmu` library that
    /// `cargo build --release --workspace` puts beside the `nudyn`
    /// executable (libnudyn_fmu.so); the environment variable NUDYN_FMU_LIB
    /// overrides where it is looked for.
    Export {
        /// The vehicle's MJCF file.
        model: PathBuf,
        /// The FMU file to write.
        #[arg(short, long)]
        output: PathBuf,
        /// The model identifier (the name of the FMU's shared library);
        /// default: the MJCF file name without extension, made a C identifier.
        #[arg(long)]
        model_identifier: Option<String>,
        /// Optional outputs, comma-separated.
        #[arg(long, default_value = "", conflicts_with = "controller", help = outputs_help())]
        outputs: OptionalOutputs,
        /// Write the controller FMU of the vehicle instead of the plant:
        /// inputs theta, nu; output eps = -c1 nu + l J^T c2 (Yhat - Y);
        /// Y = every hinge and slide joint value, or the pose of --end-effector.
        /// Default model identifier: the file name with "_controller".
        #[arg(long)]
        controller: bool,
        /// With --controller: Y is the pose (position and orientation) of this body.
        #[arg(long, requires = "controller", value_name = "BODY")]
        end_effector: Option<String>,
    },
    /// Print the vehicle's joints and where each sits in θ (qpos) and ν (qvel).
    ///
    /// With --json: {"name", "nq", "nv", "gravity", "qpos0", "joints": [{"name",
    /// "body", "kind", "qpos_adr", "nq", "dof_adr", "nv", "quaternion_adr"}]},
    /// addresses 0-based (FMU variable theta[qpos_adr + 1] is the joint's first).
    Describe {
        /// The vehicle's MJCF file.
        model: PathBuf,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Integrate the vehicle as the FMU does, without the FMI layer: by
    /// default with one RK4 step per output interval H.
    ///
    /// Input on stdin: a JSON object with optional "theta" (nq, default the
    /// model's qpos0), "nu" (nv, default 0), "eps" (nv, default 0) and
    /// "eps_rate" (nv, default 0): ε(t) = eps + eps_rate·t. Output: {"time": [...], "theta": [[...], ...], "nu": [...]}
    /// at t = 0, H, 2H, ... up to the stop time.
    // Negative numbers are values (`--step -0.01` is refused as negative, not taken for a flag).
    #[command(allow_negative_numbers = true)]
    Simulate {
        /// The vehicle's MJCF file.
        model: PathBuf,
        /// The step H (s).
        #[arg(long)]
        step: f64,
        /// The stop time (s), a multiple of the step.
        #[arg(long)]
        stop: f64,
        /// Integration method: rk4 (fixed internal steps of --max-step), dopri5 or dop853 (adaptive).
        #[arg(long, default_value = "rk4", value_parser = parse_method)]
        method: Method,
        /// Error allowed per second of simulated time, relative to 1 + |value| (adaptive methods).
        #[arg(long, default_value_t = DEFAULT_TOLERANCE)]
        tolerance: f64,
        /// Longest internal step (s); default: the step H.
        #[arg(long)]
        max_step: Option<f64>,
        /// Rescale nu after each internal step so that K follows the work done.
        #[arg(long)]
        energy_projection: bool,
    },
}

/// `--outputs`' help, from the contract's list of optional outputs.
fn outputs_help() -> String {
    format!("Optional outputs, comma-separated: {}", OptionalOutputs::NAMES.join(", "))
}

fn parse_method(name: &str) -> Result<Method, String> {
    Method::from_name(name).ok_or_else(|| {
        let names: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
        format!("unknown method '{name}' (known: {})", names.join(", "))
    })
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("nudyn: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    if let Command::Export { model, output, .. } = &cli.command {
        refuse_overwriting_the_input(model, output)?;
    }
    match cli.command {
        Command::Eval { model } => eval(&model),
        Command::Describe { model, json } => describe(&model, json),
        Command::Export { model, output, model_identifier, controller: true, end_effector, .. } => {
            export_controller(&model, &output, model_identifier, end_effector.as_deref())
        }
        Command::Export { model, output, model_identifier, outputs, .. } => {
            export(&model, &output, model_identifier, outputs)
        }
        Command::Simulate { model, step, stop, method, tolerance, max_step, energy_projection } => {
            let settings = Settings { tolerance, max_step: max_step.unwrap_or(step), energy_projection };
            simulate(&model, step, stop, method, &settings)
        }
    }
}

/// A number as a person reads it: plainly in the usual range, in exponent
/// form beyond it (Rust's plain form of 1e-300 has 300 digits).
fn number(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-4..1e15).contains(&x.abs()) { format!("{x}") } else { format!("{x:e}") }
}

/// Refuses an output path that names the MJCF file itself (`-o` mistyped):
/// the export would replace the vehicle's only description.
fn refuse_overwriting_the_input(model: &Path, output: &Path) -> Result<()> {
    let same = match (std::fs::canonicalize(model), std::fs::canonicalize(output)) {
        (Ok(model), Ok(output)) => model == output,
        _ => false,
    };
    if same {
        bail!("the output {} is the input MJCF file: choose another path for the FMU", output.display());
    }
    Ok(())
}

/// Imports and compiles an MJCF file, printing the importer's warnings.
fn load_model(path: &Path) -> Result<Model> {
    Ok(load_vehicle(path)?.1)
}

/// The vehicle as imported (body names and offsets, for a controller's
/// end effector) and compiled, printing the importer's warnings.
fn load_vehicle(path: &Path) -> Result<(Vehicle, Model)> {
    let imported = nudyn::mjcf::load_mjcf(path).with_context(|| format!("cannot import {}", path.display()))?;
    for warning in &imported.warnings {
        eprintln!("nudyn: warning: {}: {warning}", path.display());
    }
    let model = Model::compile(&imported.vehicle).with_context(|| format!("cannot compile {}", path.display()))?;
    Ok((imported.vehicle, model))
}

fn eval(model_path: &Path) -> Result<()> {
    let model = load_model(model_path)?;
    let mut input = String::new();
    std::io::stdin().read_to_string(&mut input).context("cannot read stdin")?;
    let value: serde_json::Value = serde_json::from_str(&input).map_err(|e| {
        // JSON has no NaN or Infinity; say so rather than leave a bare syntax error.
        let hint = if ["NaN", "Infinity"].iter().any(|t| input.contains(t)) {
            " (JSON has no NaN or Infinity: every number must be finite)"
        } else {
            ""
        };
        anyhow::anyhow!("stdin is not valid JSON: {e}{hint}")
    })?;
    let mut ws = model.workspace();
    let mut answer = |request: serde_json::Value| -> Result<EvalResponse> {
        let request: EvalRequest = serde_json::from_value(request)?;
        let response = evaluate(&model, &mut ws, &request)?;
        if !response.nu_dot.iter().chain(&response.qvel).all(|x| x.is_finite()) {
            bail!("the result is not finite: the state or inputs are too large");
        }
        Ok(response)
    };
    let output = match value {
        serde_json::Value::Array(requests) => {
            let responses = requests
                .into_iter()
                .enumerate()
                .map(|(k, r)| answer(r).with_context(|| format!("request {k} (0-based)")))
                .collect::<Result<Vec<_>>>()?;
            serde_json::to_string(&responses)?
        }
        request => serde_json::to_string(&answer(request)?)?,
    };
    emit(&output)
}

fn describe(model_path: &Path, json: bool) -> Result<()> {
    let description = nudyn::describe::Description::of(&load_model(model_path)?);
    if json {
        return emit(&serde_json::to_string_pretty(&description)?);
    }
    let mut table = format!("{}: nq = {}, nv = {}\n", description.name, description.nq, description.nv);
    table += &format!("{:<24} {:<24} {:<6} {:>9} {:>9}", "joint", "body", "kind", "theta", "nu, eps");
    for joint in &description.joints {
        // 1-based FMU variable indices, as in theta[k] and nu[k].
        let range = |first: usize, n: usize| {
            if n == 1 { format!("{}", first + 1) } else { format!("{}..{}", first + 1, first + n) }
        };
        table += &format!(
            "\n{:<24} {:<24} {:<6} {:>9} {:>9}",
            joint.name,
            joint.body,
            joint.kind.name(),
            range(joint.qpos_adr, joint.nq),
            range(joint.dof_adr, joint.nv)
        );
    }
    emit(&table)
}

/// Writes `text` and a newline to standard output. A reader that closed
/// the pipe early (`nudyn describe MODEL.xml | head -1`) has what it
/// wanted: that is no error, and no panic.
fn emit(text: &str) -> Result<()> {
    let mut out = std::io::stdout().lock();
    match writeln!(out, "{text}").and_then(|()| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        result => result.context("cannot write to standard output"),
    }
}

/// The FMU binary: $NUDYN_FMU_LIB, or libnudyn_fmu.so beside this executable.
fn fmu_library() -> Result<PathBuf> {
    if let Some(path) = std::env::var_os("NUDYN_FMU_LIB") {
        return Ok(PathBuf::from(path));
    }
    let exe = std::env::current_exe().context("cannot locate the nudyn executable")?;
    let library = exe.with_file_name("libnudyn_fmu.so");
    if !library.is_file() {
        bail!(
            "the FMU binary {} is missing: build it with `cargo build --release --workspace`, \
             or point NUDYN_FMU_LIB at libnudyn_fmu.so",
            library.display()
        );
    }
    Ok(library)
}

fn export(model_path: &Path, output: &Path, model_identifier: Option<String>, outputs: OptionalOutputs) -> Result<()> {
    let model = load_model(model_path)?;
    let stem = model_path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let options =
        ExportOptions { model_identifier: model_identifier.unwrap_or_else(|| model_identifier_from(&stem)), outputs };
    let library = fmu_library()?;
    write_fmu(&model, &options, &library, output).with_context(|| format!("cannot export {}", output.display()))
}

fn export_controller(
    model_path: &Path,
    output: &Path,
    model_identifier: Option<String>,
    end_effector: Option<&str>,
) -> Result<()> {
    let (vehicle, model) = load_vehicle(model_path)?;
    let law = match end_effector {
        Some(body) => ControlLaw::pose(&vehicle, &model, body),
        None => ControlLaw::joints(&model),
    }
    .with_context(|| format!("cannot build the controller of {}", model_path.display()))?;
    let stem = model_path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let identifier = model_identifier.unwrap_or_else(|| model_identifier_from(&format!("{stem}_controller")));
    let library = fmu_library()?;
    write_controller_fmu(&model, &law, &identifier, &library, output)
        .with_context(|| format!("cannot export {}", output.display()))
}

/// `nudyn simulate`'s input.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SimulateRequest {
    theta: Option<Vec<f64>>,
    nu: Option<Vec<f64>>,
    eps: Option<Vec<f64>>,
    eps_rate: Option<Vec<f64>>,
}

/// `nudyn simulate`'s output: the state at each step.
#[derive(Serialize)]
struct Trajectory {
    time: Vec<f64>,
    theta: Vec<Vec<f64>>,
    nu: Vec<Vec<f64>>,
}

fn simulate(model_path: &Path, step: f64, stop: f64, method: Method, settings: &Settings) -> Result<()> {
    if !(step.is_finite() && step > 0.0 && stop.is_finite() && stop >= 0.0) {
        bail!("--step must be positive and --stop non-negative, found {} and {}", number(step), number(stop));
    }
    for (name, value) in [("--tolerance", settings.tolerance), ("--max-step", settings.max_step)] {
        if !(value.is_finite() && value > 0.0) {
            bail!("{name} must be positive, found {}", number(value));
        }
    }
    let steps = (stop / step).round();
    if ((steps * step - stop) / step).abs() > 1e-9 {
        bail!("--stop {} is not a multiple of --step {}", number(stop), number(step));
    }
    let model = load_model(model_path)?;
    let mut input = String::new();
    std::io::stdin().read_to_string(&mut input).context("cannot read stdin")?;
    let request: SimulateRequest = serde_json::from_str(&input).context("stdin is not a valid simulate request")?;
    let mut sim = Simulation::new(&model, method, *settings);
    if let Some(theta) = request.theta {
        sim.state.theta = theta;
    }
    if let Some(nu) = request.nu {
        sim.state.nu = nu;
    }
    let eps = request.eps.unwrap_or_else(|| vec![0.0; model.nv]);
    let eps_rate = request.eps_rate.unwrap_or_else(|| vec![0.0; model.nv]);
    if eps_rate.len() != model.nv {
        bail!("eps_rate has {} entries, expected {}", eps_rate.len(), model.nv);
    }
    // Like the FMU at initialization: check the state and normalize its quaternions; check ε too.
    sim.initialize(&model)?;
    sim.evaluate_velocity(&model)?.compute_nu_dot(&model, &eps)?;
    let mut trajectory =
        Trajectory { time: vec![0.0], theta: vec![sim.state.theta.clone()], nu: vec![sim.state.nu.clone()] };
    // ε(t) = eps + eps_rate·t, as the simulation's input over each step: its value at the step's start and its rate.
    let mut eps_now = eps.clone();
    for n in 0..steps as usize {
        let t = n as f64 * step;
        for ((now, e), r) in eps_now.iter_mut().zip(&eps).zip(&eps_rate) {
            *now = e + r * t;
        }
        let input = Input { eps: &eps_now, eps_rate: &eps_rate };
        let advanced =
            sim.advance_to(&model, t + step, input).with_context(|| format!("the step from t = {t} failed"))?;
        if let Some(relaxed) = advanced.relaxed {
            eprintln!("warning: {relaxed}");
        }
        trajectory.time.push(t + step);
        trajectory.theta.push(sim.state.theta.clone());
        trajectory.nu.push(sim.state.nu.clone());
    }
    emit(&serde_json::to_string(&trajectory)?)
}
