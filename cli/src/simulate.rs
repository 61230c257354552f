//! `nudyn simulate`: the vehicle integrated as the FMU integrates it, its
//! states written as they are computed, in constant memory, with a
//! progress bar on a terminal when the run is long.

use std::fs::File;
use std::io::{BufWriter, IsTerminal, Read, Seek, Write};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use nudyn::integrate::{Input, MethodSetting, Settings, Simulation};
use nudyn::model::Model;
use serde::Deserialize;

/// How `nudyn simulate` writes the trajectory.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// One JSON object {"time": [...], "theta": [[...], ...], "nu": [[...], ...]},
    /// with "act" after them when actuators have activation states,
    /// written when the run has finished.
    Json,
    /// A header `time,theta[1],...,nu[1],...` (then `act[1],...` when
    /// actuators have activation states) and one row per output time,
    /// written as each is computed.
    Csv,
}

/// What the run does, besides the vehicle and its initial state.
pub struct Run {
    /// The output interval H (s).
    pub step: f64,
    /// The stop time (s), a multiple of H.
    pub stop: f64,
    /// The integration method, or `auto`.
    pub method: MethodSetting,
    /// Its settings.
    pub settings: Settings,
    /// The output format.
    pub format: Format,
}

/// `nudyn simulate`'s input.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Request {
    theta: Option<Vec<f64>>,
    nu: Option<Vec<f64>>,
    eps: Option<Vec<f64>>,
    eps_rate: Option<Vec<f64>>,
    ctrl: Option<Vec<f64>>,
    act: Option<Vec<f64>>,
}

/// A run shorter than this shows no progress bar (it would only flicker).
const QUIET_TIME: Duration = Duration::from_secs(1);

/// How often streamed rows are flushed to their reader.
const FLUSH_INTERVAL: Duration = Duration::from_millis(200);

/// Reads stdin, saying what it waits for when a person is typing.
pub fn read_stdin(what: &str) -> Result<String> {
    let mut stdin = std::io::stdin();
    if stdin.is_terminal() {
        eprintln!("nudyn: reading {what} as JSON from standard input ({{}} for the defaults), ended by Ctrl-D");
    }
    let mut input = String::new();
    stdin.read_to_string(&mut input).context("cannot read standard input")?;
    Ok(input)
}

/// Integrates the vehicle of `model` over `run` from the state on stdin.
pub fn simulate(model: &Model, run: &Run) -> Result<()> {
    let input = read_stdin("the initial state")?;
    let request: Request = crate::parse_json(&input).context("standard input is not a valid simulate request")?;
    let mut sim = Simulation::new(model, run.method, run.settings);
    if let Some(theta) = request.theta {
        sim.state.theta = theta;
    }
    if let Some(nu) = request.nu {
        sim.state.nu = nu;
    }
    if let Some(act) = request.act {
        let expected = model.activation_count();
        if act.len() != expected {
            bail!("act has {} entries, expected {expected} (one per actuator with activation dynamics)", act.len());
        }
        sim.act_mut(model).copy_from_slice(&act);
    }
    let eps = request.eps.unwrap_or_else(|| vec![0.0; model.nv]);
    let eps_rate = request.eps_rate.unwrap_or_else(|| vec![0.0; model.nv]);
    if eps_rate.len() != model.nv {
        bail!("eps_rate has {} entries, expected {}", eps_rate.len(), model.nv);
    }
    // The actuators' controls, held over the run (MuJoCo's d.ctrl; 0 by default, as there).
    let ctrl = request.ctrl.unwrap_or_else(|| vec![0.0; model.actuators.len()]);
    let ctrl_rate = vec![0.0; ctrl.len()];
    // Like the FMU at initialization: check the state and normalize its quaternions; check ε and ctrl too.
    sim.initialize(model)?;
    sim.evaluate_velocity(model)?.compute_nu_dot_actuated(model, &eps, &ctrl)?;

    let steps = (run.stop / run.step).round() as u64;
    // Between outputs, steps may reach past an output time (the same input held), never past the end.
    sim.set_horizon(Some(steps as f64 * run.step));
    let mut writer = Writer::new(run.format, model)?;
    let progress = Progress::new(steps);
    if !writer.write(0.0, &sim.state.theta, &sim.state.nu, sim.act(model))? {
        return Ok(());
    }
    // ε(t) = eps + eps_rate·t, as the simulation's input over each step: its value at the step's start and its rate.
    let mut eps_now = eps.clone();
    for n in 0..steps {
        let t = n as f64 * run.step;
        for ((now, e), r) in eps_now.iter_mut().zip(&eps).zip(&eps_rate) {
            *now = e + r * t;
        }
        let input = Input { eps: &eps_now, eps_rate: &eps_rate, ctrl: &ctrl, ctrl_rate: &ctrl_rate };
        let advanced = sim.advance_to(model, t + run.step, input).with_context(|| {
            progress.finish();
            format!("the step from t = {t} failed")
        })?;
        if let Some(choice) = advanced.chose {
            progress.suspend(|| eprintln!("nudyn: {choice}"));
        }
        if let Some(moved) = advanced.moved {
            progress.suspend(|| eprintln!("nudyn: {moved}"));
        }
        if let Some(held) = advanced.held {
            progress.suspend(|| eprintln!("nudyn: note: {held}"));
        }
        if let Some(relaxed) = advanced.relaxed {
            let kind = if relaxed.meets_asked() { "note" } else { "warning" };
            progress.suspend(|| eprintln!("nudyn: {kind}: {relaxed}"));
        }
        if !writer.write(t + run.step, &sim.state.theta, &sim.state.nu, sim.act(model))? {
            progress.finish();
            return Ok(());
        }
        progress.advance(n + 1);
    }
    progress.finish();
    writer.finish()
}

/// The progress bar: hidden until the run has lasted [`QUIET_TIME`], and
/// on a terminal only (indicatif draws nothing when stderr is not one).
struct Progress {
    bar: ProgressBar,
    started: Instant,
}

impl Progress {
    fn new(steps: u64) -> Self {
        let bar = ProgressBar::with_draw_target(Some(steps), ProgressDrawTarget::hidden());
        let style =
            ProgressStyle::with_template("simulate [{bar:40}] {pos}/{len} steps, {elapsed} elapsed, {eta} left")
                .expect("a valid template")
                .progress_chars("=> ");
        bar.set_style(style);
        Progress { bar, started: Instant::now() }
    }

    fn advance(&self, done: u64) {
        if self.bar.is_hidden() && self.started.elapsed() >= QUIET_TIME {
            self.bar.set_draw_target(ProgressDrawTarget::stderr());
        }
        self.bar.set_position(done);
    }

    fn suspend(&self, f: impl FnOnce()) {
        self.bar.suspend(f);
    }

    fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

/// Where the states go as they are computed. JSON keeps each column in a
/// temporary file until the end (the object's columns come one after the
/// other), so memory stays constant however long the run. The act column
/// is written only for a vehicle with activation states.
enum Writer {
    Json { columns: [BufWriter<File>; 4], rows: u64, with_act: bool },
    Csv { out: BufWriter<std::io::Stdout>, header: Option<String>, last_flush: Instant },
}

impl Writer {
    fn new(format: Format, model: &Model) -> Result<Self> {
        Ok(match format {
            Format::Json => {
                let column = || -> Result<BufWriter<File>> {
                    Ok(BufWriter::new(tempfile::tempfile().context("cannot create a temporary file")?))
                };
                let with_act = model.activation_count() > 0;
                Writer::Json { columns: [column()?, column()?, column()?, column()?], rows: 0, with_act }
            }
            Format::Csv => {
                let theta = (1..=model.nq).map(|k| format!(",theta[{k}]"));
                let nu = (1..=model.nv).map(|k| format!(",nu[{k}]"));
                let act = (1..=model.activation_count()).map(|k| format!(",act[{k}]"));
                let header: String = std::iter::once("time".to_string()).chain(theta).chain(nu).chain(act).collect();
                let out = BufWriter::new(std::io::stdout());
                Writer::Csv { out, header: Some(header), last_flush: Instant::now() }
            }
        })
    }

    /// Writes the state at `time`; `false` when the reader has gone (a
    /// closed pipe: `nudyn simulate … | head`), and the run can stop.
    fn write(&mut self, time: f64, theta: &[f64], nu: &[f64], act: &[f64]) -> Result<bool> {
        match self {
            Writer::Json { columns: [times, thetas, nus, acts], rows, with_act } => {
                let separator = if *rows == 0 { "" } else { "," };
                *rows += 1;
                write!(times, "{separator}{}", ryu::Buffer::new().format_finite(time))?;
                write!(thetas, "{separator}[{}]", joined(theta))?;
                write!(nus, "{separator}[{}]", joined(nu))?;
                if *with_act {
                    write!(acts, "{separator}[{}]", joined(act))?;
                }
                Ok(true)
            }
            Writer::Csv { out, header, last_flush } => {
                if let Some(header) = header.take()
                    && !reader_is_there(writeln!(out, "{header}"))?
                {
                    return Ok(false);
                }
                let time = ryu::Buffer::new().format_finite(time).to_string();
                let row = if act.is_empty() {
                    writeln!(out, "{time},{}", joined_pair(theta, nu))
                } else {
                    writeln!(out, "{time},{},{}", joined_pair(theta, nu), joined(act))
                };
                if !reader_is_there(row)? {
                    return Ok(false);
                }
                if last_flush.elapsed() < FLUSH_INTERVAL {
                    return Ok(true);
                }
                *last_flush = Instant::now();
                reader_is_there(out.flush())
            }
        }
    }

    /// Writes what is still held back.
    fn finish(self) -> Result<()> {
        match self {
            Writer::Json { columns: [times, thetas, nus, acts], with_act, .. } => {
                let mut out = BufWriter::new(std::io::stdout().lock());
                let result = (|| {
                    out.write_all(b"{\"time\":[")?;
                    copy_column(times, &mut out)?;
                    out.write_all(b"],\"theta\":[")?;
                    copy_column(thetas, &mut out)?;
                    out.write_all(b"],\"nu\":[")?;
                    copy_column(nus, &mut out)?;
                    if with_act {
                        out.write_all(b"],\"act\":[")?;
                        copy_column(acts, &mut out)?;
                    }
                    out.write_all(b"]}\n")?;
                    out.flush()
                })();
                reader_is_there(result).map(drop)
            }
            Writer::Csv { mut out, .. } => reader_is_there(out.flush()).map(drop),
        }
    }
}

/// The numbers as JSON writes them (shortest round-trip form), comma-separated.
fn joined(values: &[f64]) -> String {
    let mut numbers = ryu::Buffer::new();
    let mut text = String::with_capacity(24 * values.len());
    for (k, &x) in values.iter().enumerate() {
        if k > 0 {
            text.push(',');
        }
        text.push_str(numbers.format_finite(x));
    }
    text
}

/// Two rows of numbers, one after the other, comma-separated.
fn joined_pair(first: &[f64], second: &[f64]) -> String {
    format!("{},{}", joined(first), joined(second))
}

/// Appends a column's temporary file to `out`.
fn copy_column(column: BufWriter<File>, out: &mut impl Write) -> std::io::Result<()> {
    let mut file = column.into_inner().map_err(|e| e.into_error())?;
    file.rewind()?;
    std::io::copy(&mut file, out).map(drop)
}

/// Whether a write to standard output reached a reader: a closed pipe
/// means the reader has what it wanted, which is no error.
fn reader_is_there(result: std::io::Result<()>) -> Result<bool> {
    match result {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(false),
        Err(e) => Err(e).context("cannot write to standard output"),
    }
}
