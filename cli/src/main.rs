//! The `nudyn` command line.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use nudyn::control::{BodyFrame, ControlLaw};
use nudyn::eval::{EvalRequest, EvalResponse, evaluate};
use nudyn::integrate::{MethodSetting, Settings};
use nudyn::linearize::{Inputs, LinearOutput};
use nudyn::model::Model;
use nudyn::vehicle::{ConstraintKind, Vehicle};
use nudyn_cli::export::controller::write_controller_fmu;
use nudyn_cli::export::plant::{ExportOptions, write_plant_fmu};
use nudyn_cli::export::system::{SystemOptions, write_system};
use nudyn_cli::export::{FmiVersion, Platform, PlatformBinary, model_identifier_from};
use nudyn_contract::plant::{DEFAULT_METHOD, DEFAULT_TOLERANCE, OptionalOutputs, PlantResource};
use serde::Deserialize;
use simulate::Format;

mod linearize;
mod modal;
mod simulate;

#[derive(Parser)]
#[command(name = "nudyn", version, about = "Diagonalized dynamics of robotic space vehicles, as FMI 2.0 and 3.0 FMUs")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Evaluate ν̇, C(θ,ν), ε, energy and momentum for JSON states read on stdin.
    ///
    /// Input: one object, or an array of objects, with "theta" (nq), "nu" or
    /// "qvel" (nv), and optionally "eps" and "torque" (nv) and "ctrl" (nu,
    /// the actuators' controls). Output: one JSON object per input with theta,
    /// qvel, nu, nu_dot, coriolis, eps, eps_passive, kinetic_energy, power,
    /// momentum (qfrc_gravcomp with gravity compensation), and with "ctrl"
    /// actuator_length, actuator_velocity, actuator_force, qfrc_actuator,
    /// eps_actuator.
    Eval {
        /// The vehicle's MJCF file.
        model: PathBuf,
    },
    /// Export the vehicle as an FMU: FMI 2.0 (default) or 3.0, co-simulation
    /// and model exchange in one file.
    ///
    /// The FMU carries the `nudyn_fmu` library of every platform built:
    /// linux64 is the libnudyn_fmu.so that `cargo build --release
    /// --workspace` puts beside the `nudyn` executable (NUDYN_FMU_LIB
    /// overrides it); win64 is the nudyn_fmu.dll that
    /// scripts/build-windows.sh puts in target/share/nudyn/binaries/win64
    /// (NUDYN_FMU_BINARIES overrides that folder). Debug sections are left
    /// out. The command says which platforms it packed.
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
        /// Add inputs xfrc_applied[1..6n] for an external wrench (world-frame
        /// force, then torque, at the centre of mass; MuJoCo's xfrc_applied)
        /// on each of these bodies, comma-separated.
        #[arg(long, value_name = "BODY[,BODY...]", value_delimiter = ',', conflicts_with = "controller")]
        wrench_inputs: Vec<String>,
        /// Leave these constraint kinds out of the plant, as the MJCF's
        /// <flag KIND="disable"/> would: equality, frictionloss, limit
        /// (comma-separated). The FMU's description says what it carries.
        #[arg(long, value_name = "KIND[,KIND...]", value_delimiter = ',', conflicts_with = "controller")]
        disable: Vec<ConstraintKind>,
        /// The start value of the FMU's `method` parameter: rk4, dopri5,
        /// dop853 (default), ros34pw2, bs3, tsit5, or auto (the FMU chooses
        /// from the tolerance and the vehicle's motion, and logs its choice).
        #[arg(long, value_parser = parse_method, conflicts_with = "controller", default_value = DEFAULT_METHOD.name())]
        method: MethodSetting,
        /// Write the controller FMU of the vehicle instead of the plant:
        /// inputs theta, nu; output eps = -c1 nu + l J^T c2 (Yhat - Y);
        /// Y = every hinge and slide joint value, or the pose of --end-effector.
        /// Default model identifier: the file name with "_controller".
        #[arg(long)]
        controller: bool,
        /// With --controller: Y is the pose (position and orientation) of this body.
        #[arg(long, requires = "controller", value_name = "BODY")]
        end_effector: Option<String>,
        /// The FMI version: 2 (binaries/linux64, scalar variables eps[k], theta[k], ...)
        /// or 3 (binaries/x86_64-linux, array variables eps, theta, ...).
        #[arg(long, default_value = "2", value_name = "2|3")]
        fmi_version: FmiVersion,
        /// With --fmi-version 3: declare every array element as a scalar
        /// variable under its FMI 2.0 name (theta[1], theta[2], ...), each
        /// with its own value reference, for hosts that read no FMI 3.0
        /// arrays (OMSimulator, PyFMI).
        #[arg(long)]
        fmi3_scalars: bool,
    },
    /// Print the vehicle's joints and where each sits in θ (qpos) and ν (qvel),
    /// and its actuators in ctrl order.
    ///
    /// With --json: {"name", "nq", "nv", "gravity", "qpos0", "joints": [{"name",
    /// "body", "kind", "qpos_adr", "nq", "dof_adr", "nv", "quaternion_adr"}],
    /// "actuators": [{"name", "kind", "transmission", "target", "refsite",
    /// "gear", "ctrlrange", "forcerange", "gaintype", "gainprm", "biastype",
    /// "biasprm"}]}, addresses 0-based (FMU variable theta[qpos_adr + 1] is the
    /// joint's first).
    Describe {
        /// The vehicle's MJCF file.
        model: PathBuf,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Check a modal data file (docs/flexible.md) and summarize it: the
    /// nodes' mass, centre of mass and inertia (body frame), and per mode its
    /// frequency, damping ratio, participation factors and effective masses
    /// for translations along and rotations about the body axes through the
    /// origin, with their sums as fractions of the mass and inertia.
    ///
    /// With --json: {"file", "nodes", "fixed_nodes", "fixed_mass", "mass",
    /// "com", "inertia", "inertia_about_origin", "modes": [{"frequency",
    /// "damping_ratio", "participation", "effective_mass",
    /// "effective_mass_fraction"}], "effective_mass_fraction"}, each of the
    /// last three {"translation": [x, y, z], "rotation": [x, y, z]}; SI units.
    Modal {
        /// The modal data file (JSON, version 1).
        file: PathBuf,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Integrate the vehicle as the FMU does, without the FMI layer: by
    /// default with one RK4 step per output interval H.
    ///
    /// Input on stdin: a JSON object with optional "theta" (nq, default the
    /// model's qpos0), "nu" (nv, default 0), "eps" (nv, default 0) and
    /// "eps_rate" (nv, default 0): ε(t) = eps + eps_rate·t. Output, at
    /// t = 0, H, 2H, ... up to the stop time: {"time": [...], "theta":
    /// [[...], ...], "nu": [...]} at the end of the run, or with --format
    /// csv a row per time as it is computed. On a terminal, a run that
    /// lasts shows its progress on stderr.
    // Numbers may be negative (`--step -0.01`, `--tolerance -1e-9` are refused
    // as negative, not taken for flags): every option here takes a value.
    Simulate {
        /// The vehicle's MJCF file.
        model: PathBuf,
        /// The step H (s).
        #[arg(long, allow_hyphen_values = true)]
        step: f64,
        /// The stop time (s), a multiple of the step.
        #[arg(long, allow_hyphen_values = true)]
        stop: f64,
        /// Integration method: rk4 (fixed internal steps of --max-step), dopri5, dop853, ros34pw2, bs3 or tsit5
        /// (adaptive; ros34pw2 is implicit, for stiff vehicles; bs3 the cheapest per step, for loose tolerances),
        /// or auto (the cheapest of bs3, tsit5 and dop853 for the tolerance and the motion over the first step,
        /// one order up when later motion asks, tsit5 or dop853 once the input is held, ros34pw2 while stability holds
        /// the explicit steps: chosen as the FMU's auto chooses and said on stderr).
        #[arg(long, default_value = "rk4", value_parser = parse_method)]
        method: MethodSetting,
        /// Error allowed per second of simulated time, relative to 1 + |value| (adaptive methods; ros34pw2:
        /// 1/80 of it per internal step).
        #[arg(long, default_value_t = DEFAULT_TOLERANCE, allow_hyphen_values = true)]
        tolerance: f64,
        /// Longest internal step (s); default: the step H.
        #[arg(long, allow_hyphen_values = true)]
        max_step: Option<f64>,
        /// Rescale nu after each internal step so that K follows the work done.
        #[arg(long)]
        energy_projection: bool,
        /// Output format.
        #[arg(long, value_enum, default_value = "json")]
        format: Format,
    },
    /// Linearize the dynamics at a state from their exact derivatives:
    /// A, B, C, D of dx/dt = A x + B u, y = C x + D u, with x = (dq, qvel,
    /// act) (dq the displacement in the tangent space, rotations as rotation
    /// vectors in the body frame, act the activation states if any:
    /// MuJoCo's mjd_transitionFD state) and u the eps inputs, the joint
    /// forces or ctrl; with --step, the zero-order hold's Ad, Bd. Writes
    /// JSON (stdout or --output) with the matrices by rows and the names of
    /// x, u and y, optionally an .npz; prints the eigenvalues (frequency,
    /// damping) on stderr. Points on a switch of the constraint forces are
    /// refused.
    Linearize {
        /// The vehicle's MJCF file.
        model: PathBuf,
        /// Start from this `<key>` of the file's `<keyframe>` (its name, or
        /// its index from 0): its qpos, qvel, act and ctrl, which --qpos,
        /// --qvel, --act and --ctrl replace where given.
        #[arg(long)]
        keyframe: Option<String>,
        /// θ (nq values, comma-separated); default the model's qpos0.
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
        qpos: Option<Vec<f64>>,
        /// θ̇ (nv values); default 0.
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
        qvel: Option<Vec<f64>>,
        /// The actuators' activation states (na values, MuJoCo's act), states
        /// of the linearization after θ̇; default 0.
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
        act: Option<Vec<f64>>,
        /// The eps held at the point (nv values); default 0.
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
        eps: Option<Vec<f64>>,
        /// The joint forces held at the point (nv values, MuJoCo's qfrc_applied); default 0.
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
        torque: Option<Vec<f64>>,
        /// The actuators' ctrl held at the point (one value per actuator, then
        /// the wrench inputs'); default 0.
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
        ctrl: Option<Vec<f64>>,
        /// The inputs u of B and D.
        #[arg(long, value_enum, default_value = "eps")]
        inputs: InputsArg,
        /// The outputs y of C and D, comma-separated: qpos (dq), qvel, nu, qacc, sensordata,
        /// end_effector (the pose of --end-effector).
        #[arg(long, value_enum, value_delimiter = ',', default_value = "qpos,qvel")]
        outputs: Vec<OutputArg>,
        /// The body whose pose the end_effector output is (6 rows: its origin
        /// in world axes, then its turn as a rotation vector in its own axes);
        /// adds end_effector to --outputs if it is not there.
        #[arg(long, value_name = "BODY")]
        end_effector: Option<String>,
        /// Also the zero-order hold's discrete pair for this step (s).
        #[arg(long, allow_hyphen_values = true)]
        step: Option<f64>,
        /// The JSON file to write (default: stdout).
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// Also write the matrices as NumPy's .npz.
        #[arg(long)]
        npz: Option<PathBuf>,
    },
    /// Write the plant and its controller as one SSP 1.0 system file
    /// (docs/systems.md): SystemStructure.ssd connecting plant θ, ν to the
    /// controller and the controller's ε to the plant, both FMUs in
    /// resources/, and the values of --set in a ParameterValues file per
    /// component. FMPy (fmpy.ssp.simulation.simulate_ssp) and OSP's
    /// libcosim (CosimExecution.from_ssp_file) run it.
    // Numbers may be negative (`--set plant.nu[4]=-0.5`, `--step -1` is refused as negative).
    System {
        /// The vehicle's MJCF file.
        model: PathBuf,
        /// The .ssp file to write.
        #[arg(short, long)]
        output: PathBuf,
        /// The controller's Y is the pose of this body (default: every hinge and slide joint).
        #[arg(long, value_name = "BODY")]
        end_effector: Option<String>,
        /// The FMI version of both FMUs: 2 (the SSP importers run FMI 2.0 components only).
        #[arg(long, default_value = "2", value_name = "2|3")]
        fmi_version: FmiVersion,
        /// The plant's optional outputs, comma-separated.
        #[arg(long, default_value = "", help = outputs_help())]
        outputs: OptionalOutputs,
        /// The DefaultExperiment's communication step H (s); libcosim's fixed step.
        #[arg(long, default_value_t = 0.01, allow_hyphen_values = true)]
        step: f64,
        /// The DefaultExperiment's stop time (s), a multiple of the step.
        #[arg(long, default_value_t = 10.0, allow_hyphen_values = true)]
        stop: f64,
        /// A start value of either component: plant.NAME=VALUE or
        /// controller.NAME=VALUE (an array's name without index sets every
        /// entry: controller.c1=2); repeat for several.
        #[arg(long = "set", value_name = "COMPONENT.NAME=VALUE", allow_hyphen_values = true)]
        sets: Vec<String>,
    },
}

/// `nudyn linearize --inputs`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum InputsArg {
    /// ε, the FMU's inputs.
    Eps,
    /// The physical joint forces (MuJoCo's qfrc_applied).
    Torque,
    /// The actuators' ctrl.
    Ctrl,
}

/// `nudyn linearize --outputs`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum OutputArg {
    /// dq.
    Qpos,
    /// θ̇.
    Qvel,
    /// ν = m*θ̇.
    Nu,
    /// θ̈.
    Qacc,
    /// MuJoCo's sensordata.
    Sensordata,
    /// The pose of --end-effector: its origin (world axes), then its turn (rotation vector, its own axes).
    #[value(name = "end_effector", alias = "end-effector")]
    EndEffector,
}

/// `--outputs`' help, from the contract's list of optional outputs.
fn outputs_help() -> String {
    format!("Optional outputs, comma-separated: {}", OptionalOutputs::NAMES.join(", "))
}

fn parse_method(name: &str) -> Result<MethodSetting, String> {
    MethodSetting::from_name(name).ok_or_else(|| {
        let names: Vec<&str> = MethodSetting::ALL.iter().map(|m| m.name()).collect();
        format!("unknown method '{name}' (known: {})", names.join(", "))
    })
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("nudyn: error: {}", report(&e));
            ExitCode::FAILURE
        }
    }
}

/// The error and its causes, each said once: many errors (io errors with a
/// path, the exporter's) already include their cause's words.
fn report(error: &anyhow::Error) -> String {
    let mut message = String::new();
    for cause in error.chain() {
        let text = cause.to_string();
        if message.contains(&text) {
            continue;
        }
        if !message.is_empty() {
            message += ": ";
        }
        message += &text;
    }
    message
}

/// Parses JSON into `T`; a value of the wrong type is named by its place
/// (`nu[3]`, 1-based like the FMU's variables).
fn parse_json<T: serde::de::DeserializeOwned>(text: &str) -> Result<T> {
    let mut parser = serde_json::Deserializer::from_str(text);
    let value = serde_path_to_error::deserialize(&mut parser).map_err(|e| {
        let place = place(e.path());
        let inner = e.into_inner();
        // JSON has no NaN or Infinity; say so rather than leave a bare syntax error.
        let hint = if inner.is_syntax() && ["NaN", "Infinity"].iter().any(|t| text.contains(t)) {
            " (JSON has no NaN or Infinity: every number must be finite)"
        } else {
            ""
        };
        match place {
            Some(place) => anyhow::anyhow!("{place}: {inner}{hint}"),
            None => anyhow::anyhow!("{inner}{hint}"),
        }
    })?;
    parser.end()?;
    Ok(value)
}

/// Where in a JSON document serde_path_to_error's path points: `nu[3]`
/// (1-based entries), `[2].theta[1]` in an array of requests (whose
/// requests are numbered 0-based, as in "request 2").
fn place(path: &serde_path_to_error::Path) -> Option<String> {
    use serde_path_to_error::Segment;
    let mut place = String::new();
    for (depth, segment) in path.iter().enumerate() {
        match segment {
            Segment::Seq { index } if depth == 0 => place += &format!("request {index}, "),
            Segment::Seq { index } => place += &format!("[{}]", index + 1),
            Segment::Map { key } if place.is_empty() || place.ends_with(", ") => place += key,
            Segment::Map { key } => place += &format!(".{key}"),
            Segment::Enum { variant } => place += &format!(".{variant}"),
            Segment::Unknown => {}
        }
    }
    (!place.is_empty()).then(|| place.trim_end_matches(", ").to_string())
}

fn run(cli: Cli) -> Result<()> {
    if let Command::Export { model, output, .. } | Command::System { model, output, .. } = &cli.command {
        refuse_overwriting_the_input(model, output)?;
    }
    match cli.command {
        Command::Eval { model } => eval(&model),
        Command::Describe { model, json } => describe(&model, json),
        Command::Modal { file, json } => modal::run(&file, json),
        Command::Export { fmi_version, fmi3_scalars: true, .. } if fmi_version != FmiVersion::Fmi3 => {
            bail!("--fmi3-scalars declares FMI 3.0 variables: it needs --fmi-version 3")
        }
        Command::Export {
            model,
            output,
            model_identifier,
            controller: true,
            end_effector,
            fmi_version,
            fmi3_scalars,
            ..
        } => export_controller(&model, &output, model_identifier, end_effector.as_deref(), fmi_version, fmi3_scalars),
        Command::Export {
            model,
            output,
            model_identifier,
            outputs,
            fmi_version,
            wrench_inputs,
            disable,
            method,
            fmi3_scalars,
            ..
        } => {
            let options =
                PlantOptions { model_identifier, outputs, wrench_inputs, disable, fmi_version, fmi3_scalars, method };
            export(&model, &output, options)
        }
        Command::System { model, output, end_effector, fmi_version, outputs, step, stop, sets } => {
            let stem = model.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
            let options = SystemOptions {
                plant_identifier: model_identifier_from(&stem),
                controller_identifier: model_identifier_from(&format!("{stem}_controller")),
                plant: ExportOptions { model_identifier: model_identifier_from(&stem), outputs, fmi_version },
                step,
                stop,
                sets,
            };
            system(&model, &output, end_effector.as_deref(), &options)
        }
        Command::Linearize {
            model,
            keyframe,
            qpos,
            qvel,
            act,
            eps,
            torque,
            ctrl,
            inputs,
            mut outputs,
            end_effector,
            step,
            output,
            npz,
        } => {
            if let Some(h) = step
                && !(h.is_finite() && h > 0.0)
            {
                bail!("--step must be a positive number of seconds, not {h}");
            }
            if end_effector.is_some() && !outputs.contains(&OutputArg::EndEffector) {
                outputs.push(OutputArg::EndEffector);
            }
            let inputs = match inputs {
                InputsArg::Eps => Inputs::Eps,
                InputsArg::Torque => Inputs::Torque,
                InputsArg::Ctrl => Inputs::Ctrl,
            };
            let imported = import(&model)?;
            let compiled = compile(&model, &imported.vehicle)?;
            let frame = match (&end_effector, outputs.contains(&OutputArg::EndEffector)) {
                (Some(body), _) => Some(BodyFrame::find(&imported.vehicle, &compiled, body).context("--end-effector")?),
                (None, true) => bail!("--outputs end_effector needs --end-effector BODY"),
                (None, false) => None,
            };
            let outputs: Vec<LinearOutput> = outputs
                .iter()
                .map(|o| match o {
                    OutputArg::Qpos => LinearOutput::Qpos,
                    OutputArg::Qvel => LinearOutput::Qvel,
                    OutputArg::Nu => LinearOutput::Nu,
                    OutputArg::Qacc => LinearOutput::Qacc,
                    OutputArg::Sensordata => LinearOutput::Sensordata,
                    OutputArg::EndEffector => {
                        let frame = frame.as_ref().expect("checked above");
                        LinearOutput::EndEffector { link: frame.link, offset: frame.offset }
                    }
                })
                .collect();
            let key = keyframe.map(|asked| nudyn::mjcf::keyframe::find(&imported.keyframes, &asked)).transpose()?;
            if let Some(key) = key
                && key.places_mocap_bodies
            {
                bail!(
                    "keyframe {} (line {}) places mocap bodies (mpos, mquat); nudyn holds them at their modelled pose",
                    key.name.as_deref().unwrap_or("without a name"),
                    key.line
                );
            }
            let from_key =
                |given: Option<Vec<f64>>, of_key: fn(&nudyn::mjcf::keyframe::Keyframe) -> &Option<Vec<f64>>| {
                    given.or_else(|| key.and_then(|key| of_key(key).clone()))
                };
            let request = linearize::Request {
                qpos: from_key(qpos, |key| &key.qpos),
                qvel: from_key(qvel, |key| &key.qvel),
                act: from_key(act, |key| &key.act),
                eps,
                torque,
                ctrl: from_key(ctrl, |key| &key.ctrl),
                inputs,
                outputs: &outputs,
                step,
                json: output.as_deref(),
                npz: npz.as_deref(),
            };
            linearize::run(&compiled, &request)
        }
        Command::Simulate { model, step, stop, method, tolerance, max_step, energy_projection, format } => {
            let settings = Settings { tolerance, max_step: max_step.unwrap_or(step), energy_projection };
            check_simulate_options(step, stop, &settings)?;
            simulate::simulate(&load_model(&model)?, &simulate::Run { step, stop, method, settings, format })
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
    let vehicle = import_vehicle(path)?;
    let model = compile(path, &vehicle)?;
    Ok((vehicle, model))
}

/// The vehicle as imported, printing the importer's warnings.
fn import_vehicle(path: &Path) -> Result<Vehicle> {
    Ok(import(path)?.vehicle)
}

/// The file as imported (the vehicle and its keyframes), printing the importer's warnings.
fn import(path: &Path) -> Result<nudyn::mjcf::Imported> {
    let imported = nudyn::mjcf::load_mjcf(path).with_context(|| format!("cannot import {}", path.display()))?;
    for warning in &imported.warnings {
        eprintln!("nudyn: warning: {}: {warning}", path.display());
    }
    Ok(imported)
}

/// The model of the vehicle of the file at `path`.
fn compile(path: &Path, vehicle: &Vehicle) -> Result<Model> {
    Model::compile(vehicle).with_context(|| format!("cannot compile {}", path.display()))
}

fn eval(model_path: &Path) -> Result<()> {
    let model = load_model(model_path)?;
    let input = simulate::read_stdin("the states to evaluate")?;
    let requests: Requests = parse_json(&input).context("standard input is not a valid eval request")?;
    let mut ws = model.workspace();
    let mut answer = |request: &EvalRequest| -> Result<EvalResponse> {
        let response = evaluate(&model, &mut ws, request)?;
        if !response.nu_dot.iter().chain(&response.qvel).all(|x| x.is_finite()) {
            bail!("the result is not finite: the state or inputs are too large");
        }
        Ok(response)
    };
    let output = match requests {
        Requests::Many(requests) => {
            let responses = requests
                .iter()
                .enumerate()
                .map(|(k, r)| answer(r).with_context(|| format!("request {k} (0-based)")))
                .collect::<Result<Vec<_>>>()?;
            serde_json::to_string(&responses)?
        }
        Requests::One(request) => serde_json::to_string(&answer(&request)?)?,
    };
    emit(&output)
}

/// `nudyn eval`'s input: one request or an array of them.
enum Requests {
    One(EvalRequest),
    Many(Vec<EvalRequest>),
}

// By hand rather than `#[serde(untagged)]`, whose error for a bad field in
// either form is only "did not match any variant".
impl<'de> Deserialize<'de> for Requests {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> std::result::Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = Requests;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a request object or an array of them")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(self, map: A) -> std::result::Result<Requests, A::Error> {
                EvalRequest::deserialize(serde::de::value::MapAccessDeserializer::new(map)).map(Requests::One)
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, seq: A) -> std::result::Result<Requests, A::Error> {
                Vec::deserialize(serde::de::value::SeqAccessDeserializer::new(seq)).map(Requests::Many)
            }
        }
        deserializer.deserialize_any(Visitor)
    }
}

fn describe(model_path: &Path, json: bool) -> Result<()> {
    let (vehicle, model) = load_vehicle(model_path)?;
    let description = nudyn::describe::Description::of(&vehicle, &model);
    if json {
        return emit(&serde_json::to_string_pretty(&description)?);
    }
    let mut table = format!("{}: nq = {}, nv = {}\n", description.name, description.nq, description.nv);
    let mode_labels: Vec<String> =
        description.modes.iter().map(|mode| format!("{}, {:.3} Hz", mode.name, mode.frequency)).collect();
    let joint_width = column_width(
        24,
        description.joints.iter().map(|j| j.name.as_str()).chain(mode_labels.iter().map(String::as_str)),
    );
    let body_width = column_width(
        24,
        description.joints.iter().map(|j| j.body.as_str()).chain(description.modes.iter().map(|m| m.body.as_str())),
    );
    table +=
        &format!("{:<joint_width$} {:<body_width$} {:<6} {:>9} {:>9}", "joint", "body", "kind", "theta", "nu, eps");
    for joint in &description.joints {
        // 1-based FMU variable indices, as in theta[k] and nu[k].
        let range = |first: usize, n: usize| {
            if n == 1 { format!("{}", first + 1) } else { format!("{}..{}", first + 1, first + n) }
        };
        table += &format!(
            "\n{:<joint_width$} {:<body_width$} {:<6} {:>9} {:>9}",
            joint.name,
            joint.body,
            joint.kind.name(),
            range(joint.qpos_adr, joint.nq),
            range(joint.dof_adr, joint.nv)
        );
    }
    for (mode, label) in description.modes.iter().zip(&mode_labels) {
        table += &format!(
            "\n{:<joint_width$} {:<body_width$} {:<6} {:>9} {:>9}",
            label,
            mode.body,
            "mode",
            mode.qpos_adr + 1,
            mode.dof_adr + 1
        );
    }
    let actuator_width = column_width(24, description.actuators.iter().map(|a| a.name.as_deref().unwrap_or("-")));
    if !description.actuators.is_empty() {
        let transmissions: Vec<String> = description
            .actuators
            .iter()
            .map(|actuator| match &actuator.refsite {
                Some(refsite) => format!("{} {} (refsite {refsite})", actuator.transmission, actuator.target),
                None => format!("{} {}", actuator.transmission, actuator.target),
            })
            .collect();
        let transmission_width = column_width(36, transmissions.iter().map(String::as_str));
        table += &format!("\n\n{} actuators (ctrl order)\n", description.actuators.len());
        table += &format!(
            "{:<5} {:<actuator_width$} {:<9} {:<transmission_width$} {}",
            "ctrl", "actuator", "kind", "transmission", "ctrlrange"
        );
        for (k, (actuator, transmission)) in description.actuators.iter().zip(&transmissions).enumerate() {
            let range = actuator.ctrlrange.map_or("unlimited".to_string(), |[low, high]| format!("{low} .. {high}"));
            table += &format!(
                "\n{:<5} {:<actuator_width$} {:<9} {:<transmission_width$} {range}",
                k + 1,
                actuator.name.as_deref().unwrap_or("-"),
                actuator.kind.name(),
                transmission
            );
        }
    }
    let activations: Vec<(usize, &nudyn::describe::ActuatorDescription)> =
        description.actuators.iter().enumerate().filter(|(_, a)| a.activation.is_some()).collect();
    if !activations.is_empty() {
        table += &format!("\n\n{} activation states (act order)\n", activations.len());
        table += &format!(
            "{:<5} {:<5} {:<actuator_width$} {:<12} {:>10} {:<16} {}",
            "act", "ctrl", "actuator", "dyntype", "tau", "actrange", "actearly"
        );
        for (k, (index, actuator)) in activations.into_iter().enumerate() {
            let activation = actuator.activation.expect("filtered");
            let dyntype = match activation.kind {
                nudyn::vehicle::ActivationKind::Integrator => "integrator",
                nudyn::vehicle::ActivationKind::Filter => "filter",
                nudyn::vehicle::ActivationKind::FilterExact => "filterexact",
            };
            let range = activation.range.map_or("unlimited".to_string(), |[low, high]| format!("{low} .. {high}"));
            table += &format!(
                "\n{:<5} {:<5} {:<actuator_width$} {:<12} {:>10} {:<16} {}",
                k + 1,
                index + 1,
                actuator.name.as_deref().unwrap_or("-"),
                dyntype,
                activation.time_constant,
                range,
                activation.early
            );
        }
    }
    if !description.tendons.is_empty() {
        table += &format!("\n\n{} tendons\n", description.tendons.len());
        let tendon_width = column_width(24, description.tendons.iter().map(|t| t.name.as_deref().unwrap_or("-")));
        table += &format!("{:<tendon_width$} {:<8} {:>12} {}", "tendon", "kind", "length0", "range");
        for tendon in &description.tendons {
            let range = tendon.range.map_or("unlimited".to_string(), |[low, high]| format!("{low} .. {high}"));
            table += &format!(
                "\n{:<tendon_width$} {:<8} {:>12.6} {range}",
                tendon.name.as_deref().unwrap_or("-"),
                tendon.kind,
                tendon.length0
            );
        }
    }
    // The plant FMU's variables, from the contract's table, as docs/fmi.md shows them.
    table += "\n\nFMU variables of `nudyn export` without options (--outputs and --wrench-inputs add some)\n";
    table += &nudyn_cli::export::variable_table::markdown(&PlantResource::new(model, OptionalOutputs::default()));
    emit(table.trim_end())
}

/// The width of a column of `nudyn describe`'s tables: its longest entry's,
/// and never under `least`, the width it had when every column was fixed
/// (so that short names print as they always have).
fn column_width<'a>(least: usize, entries: impl Iterator<Item = &'a str>) -> usize {
    entries.map(|entry| entry.chars().count()).fold(least, usize::max)
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

/// The `nudyn_fmu` library built for each platform, linux64 first.
///
/// linux64: $NUDYN_FMU_LIB, else libnudyn_fmu.so beside this executable
/// (where cargo builds it), else in the binaries folder. Other platforms:
/// in the binaries folder, `<platform>/<library>` (win64/nudyn_fmu.dll). The
/// binaries folder is $NUDYN_FMU_BINARIES, else `share/nudyn/binaries` in
/// the folder above this executable's: `target/` for cargo's build (where
/// scripts/build-windows.sh puts the DLL), the environment's prefix for the
/// wheel.
fn fmu_binaries() -> Result<Vec<PlatformBinary>> {
    let exe = std::env::current_exe().context("cannot locate the nudyn executable")?;
    let folder = match std::env::var_os("NUDYN_FMU_BINARIES") {
        Some(folder) => PathBuf::from(folder),
        None => exe.parent().and_then(Path::parent).unwrap_or(Path::new("/")).join("share/nudyn/binaries"),
    };
    let in_folder = |platform: Platform| folder.join(platform.fmi2_folder()).join(platform.built_library_name());
    let linux64 = match std::env::var_os("NUDYN_FMU_LIB") {
        Some(path) => PathBuf::from(path),
        None => {
            let beside = exe.with_file_name(Platform::Linux64.built_library_name());
            let candidates = [beside.clone(), in_folder(Platform::Linux64)];
            let Some(found) = candidates.into_iter().find(|path| path.is_file()) else {
                bail!(
                    "the FMU binary {} is missing: build it with `cargo build --release --workspace`, \
                     or point NUDYN_FMU_LIB at libnudyn_fmu.so",
                    beside.display()
                );
            };
            found
        }
    };
    let mut binaries = vec![PlatformBinary { platform: Platform::Linux64, path: linux64 }];
    for platform in Platform::ALL.into_iter().filter(|&p| p != Platform::Linux64) {
        let path = in_folder(platform);
        if path.is_file() {
            binaries.push(PlatformBinary { platform, path });
        }
    }
    Ok(binaries)
}

/// What an export says it wrote: the platforms packed, and those not built.
fn report_platforms(output: &Path, binaries: &[PlatformBinary]) -> Result<()> {
    let packed: Vec<String> = binaries.iter().map(|b| b.platform.to_string()).collect();
    let missing: Vec<String> = Platform::ALL
        .into_iter()
        .filter(|p| binaries.iter().all(|b| b.platform != *p))
        .map(|p| p.to_string())
        .collect();
    let mut line = format!("wrote {} with binaries for {}", output.display(), packed.join(", "));
    if !missing.is_empty() {
        line += &format!(" (not built: {}; scripts/build-windows.sh builds win64)", missing.join(", "));
    }
    emit(&line)
}

/// What `nudyn export` is asked for a plant FMU.
struct PlantOptions {
    model_identifier: Option<String>,
    outputs: OptionalOutputs,
    wrench_inputs: Vec<String>,
    disable: Vec<ConstraintKind>,
    fmi_version: FmiVersion,
    fmi3_scalars: bool,
    method: MethodSetting,
}

fn export(model_path: &Path, output: &Path, plant: PlantOptions) -> Result<()> {
    let mut vehicle = import_vehicle(model_path)?;
    for &kind in &plant.disable {
        vehicle.disable_constraints(kind);
    }
    let model = Model::compile_with_wrench_inputs(&vehicle, &plant.wrench_inputs)
        .with_context(|| format!("cannot compile {}", model_path.display()))?;
    let stem = model_path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let model_identifier = plant.model_identifier.unwrap_or_else(|| model_identifier_from(&stem));
    let options = ExportOptions { model_identifier, outputs: plant.outputs, fmi_version: plant.fmi_version };
    let binaries = fmu_binaries()?;
    let resource = PlantResource {
        method: plant.method,
        fmi3_scalars: plant.fmi3_scalars,
        ..PlantResource::new(model, plant.outputs)
    };
    write_plant_fmu(&resource, &options, &binaries, output)
        .with_context(|| format!("cannot export {}", output.display()))?;
    report_platforms(output, &binaries)
}

fn export_controller(
    model_path: &Path,
    output: &Path,
    model_identifier: Option<String>,
    end_effector: Option<&str>,
    fmi_version: FmiVersion,
    fmi3_scalars: bool,
) -> Result<()> {
    let (vehicle, model) = load_vehicle(model_path)?;
    let law = match end_effector {
        Some(body) => ControlLaw::pose(&vehicle, &model, body),
        None => ControlLaw::joints(&model),
    }
    .with_context(|| format!("cannot build the controller of {}", model_path.display()))?;
    let stem = model_path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let identifier = model_identifier.unwrap_or_else(|| model_identifier_from(&format!("{stem}_controller")));
    let binaries = fmu_binaries()?;
    write_controller_fmu(&model, &law, &identifier, fmi_version, fmi3_scalars, &binaries, output)
        .with_context(|| format!("cannot export {}", output.display()))?;
    report_platforms(output, &binaries)
}

fn system(model_path: &Path, output: &Path, end_effector: Option<&str>, options: &SystemOptions) -> Result<()> {
    let (vehicle, model) = load_vehicle(model_path)?;
    let law = match end_effector {
        Some(body) => ControlLaw::pose(&vehicle, &model, body),
        None => ControlLaw::joints(&model),
    }
    .with_context(|| format!("cannot build the controller of {}", model_path.display()))?;
    let binaries = fmu_binaries()?;
    let values = write_system(&model, &law, options, &binaries, output)
        .with_context(|| format!("cannot write {}", output.display()))?;
    let set: usize = values.values().map(|v| v.len()).sum();
    report_platforms(output, &binaries)?;
    if set > 0 {
        emit(&format!("{set} start values set (resources/*.ssv; the plant's also in plant.fmu)"))?;
    }
    Ok(())
}

/// Refuses `nudyn simulate` options that cannot describe a run.
fn check_simulate_options(step: f64, stop: f64, settings: &Settings) -> Result<()> {
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
    Ok(())
}
