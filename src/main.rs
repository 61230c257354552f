//! The `nudyn` command line.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use nudyn::eval::{EvalRequest, EvalResponse, evaluate};
use nudyn::model::Model;

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
    match cli.command {
        Command::Eval { model } => eval(&model),
    }
}

/// Imports and compiles an MJCF file, printing the importer's warnings.
fn load_model(path: &Path) -> Result<Model> {
    let imported = nudyn::mjcf::load_mjcf(path).with_context(|| format!("cannot import {}", path.display()))?;
    for warning in &imported.warnings {
        eprintln!("nudyn: warning: {}: {warning}", path.display());
    }
    Model::compile(&imported.vehicle).with_context(|| format!("cannot compile {}", path.display()))
}

fn eval(model_path: &Path) -> Result<()> {
    let model = load_model(model_path)?;
    let mut input = String::new();
    std::io::stdin().read_to_string(&mut input).context("cannot read stdin")?;
    let value: serde_json::Value = serde_json::from_str(&input).context("stdin is not valid JSON")?;
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
    println!("{output}");
    Ok(())
}
