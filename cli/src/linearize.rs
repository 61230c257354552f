//! `nudyn linearize`: A, B, C, D at a state as JSON (and .npz), the
//! eigenvalues as a table on stderr.

use std::io::Write;
use std::path::Path;

use anyhow::{Context, Result, bail};
use nalgebra::DMatrix;
use nudyn::linearize::{Inputs, LinearOutput, Linearization, OperatingPoint, frequency_and_damping, linearize};
use nudyn::model::Model;
use serde::Serialize;

/// What `nudyn linearize` was asked.
pub struct Request<'a> {
    /// θ; default the model's qpos0.
    pub qpos: Option<Vec<f64>>,
    /// θ̇; default 0.
    pub qvel: Option<Vec<f64>>,
    /// act; default 0.
    pub act: Option<Vec<f64>>,
    /// ε held; default 0.
    pub eps: Option<Vec<f64>>,
    /// T held; default 0.
    pub torque: Option<Vec<f64>>,
    /// ctrl held; default 0.
    pub ctrl: Option<Vec<f64>>,
    /// The inputs of B and D.
    pub inputs: Inputs,
    /// The outputs of C and D.
    pub outputs: &'a [LinearOutput],
    /// The zero-order hold's step.
    pub step: Option<f64>,
    /// The JSON file (default stdout).
    pub json: Option<&'a Path>,
    /// The .npz file.
    pub npz: Option<&'a Path>,
}

/// The JSON written: the point, the names of x, u and y, the matrices by rows.
#[derive(Serialize)]
struct LinearizationFile {
    qpos: Vec<f64>,
    qvel: Vec<f64>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    act: Vec<f64>,
    eps: Vec<f64>,
    torque: Vec<f64>,
    ctrl: Vec<f64>,
    state: Vec<String>,
    inputs: Vec<String>,
    outputs: Vec<String>,
    #[serde(rename = "A")]
    a: Vec<Vec<f64>>,
    #[serde(rename = "B")]
    b: Vec<Vec<f64>>,
    #[serde(rename = "C")]
    c: Vec<Vec<f64>>,
    #[serde(rename = "D")]
    d: Vec<Vec<f64>>,
    eigenvalues: Vec<Eigenvalue>,
    #[serde(skip_serializing_if = "Option::is_none")]
    step: Option<f64>,
    #[serde(rename = "Ad", skip_serializing_if = "Option::is_none")]
    ad: Option<Vec<Vec<f64>>>,
    #[serde(rename = "Bd", skip_serializing_if = "Option::is_none")]
    bd: Option<Vec<Vec<f64>>>,
}

#[derive(Serialize)]
struct Eigenvalue {
    real: f64,
    imag: f64,
    frequency_hz: f64,
    damping_ratio: f64,
}

/// Runs `nudyn linearize`.
pub fn run(model: &Model, request: &Request) -> Result<()> {
    let (nv, na) = (model.nv, model.activation_count());
    let given = |values: &Option<Vec<f64>>, default: Vec<f64>, what: &str, expected: usize| -> Result<Vec<f64>> {
        let values = values.clone().unwrap_or(default);
        if values.len() != expected {
            bail!("--{what} has {} values; this model needs {expected}", values.len());
        }
        Ok(values)
    };
    let point = OperatingPoint {
        qpos: given(&request.qpos, model.qpos0.clone(), "qpos", model.nq)?,
        qvel: given(&request.qvel, vec![0.0; nv], "qvel", nv)?,
        act: given(&request.act, vec![0.0; na], "act", na)?,
        eps: given(&request.eps, vec![0.0; nv], "eps", nv)?,
        torque: given(&request.torque, vec![0.0; nv], "torque", nv)?,
        ctrl: given(&request.ctrl, vec![0.0; model.actuators.len()], "ctrl", model.actuators.len())?,
    };
    let linear = linearize(model, &point, request.inputs, request.outputs, request.step)
        .context("cannot linearize this model")?;
    let names = |prefix: &'static str| (1..=nv).map(move |k| format!("{prefix}[{k}]"));
    let inputs = match request.inputs {
        Inputs::Eps => names("eps").collect(),
        Inputs::Torque => names("torque").collect(),
        Inputs::Ctrl => (1..=model.actuators.len()).map(|k| format!("ctrl[{k}]")).collect(),
    };
    let file = LinearizationFile {
        state: names("dq").chain(names("qvel")).chain((1..=na).map(|k| format!("act[{k}]"))).collect(),
        inputs,
        outputs: request
            .outputs
            .iter()
            .flat_map(|o| (1..=o.len(model)).map(|k| format!("{}[{k}]", o.name())))
            .collect(),
        a: rows(&linear.a),
        b: rows(&linear.b),
        c: rows(&linear.c),
        d: rows(&linear.d),
        eigenvalues: linear
            .eigenvalues
            .iter()
            .map(|&lambda| {
                let (frequency_hz, damping_ratio) = frequency_and_damping(lambda);
                Eigenvalue { real: lambda.re, imag: lambda.im, frequency_hz, damping_ratio }
            })
            .collect(),
        step: linear.discrete.as_ref().map(|(h, ..)| *h),
        ad: linear.discrete.as_ref().map(|(_, ad, _)| rows(ad)),
        bd: linear.discrete.as_ref().map(|(.., bd)| rows(bd)),
        qpos: point.qpos,
        qvel: point.qvel,
        act: point.act,
        eps: point.eps,
        torque: point.torque,
        ctrl: point.ctrl,
    };
    let json = serde_json::to_string(&file)?;
    match request.json {
        Some(path) => std::fs::write(path, json + "\n").with_context(|| format!("cannot write {}", path.display()))?,
        None => println!("{json}"),
    }
    if let Some(path) = request.npz {
        write_npz(path, &linear).with_context(|| format!("cannot write {}", path.display()))?;
    }
    print_modes(&file.eigenvalues)
}

fn rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    m.row_iter().map(|row| row.iter().copied().collect()).collect()
}

/// The eigenvalues as a table: a complex pair once, with its frequency and damping.
fn print_modes(eigenvalues: &[Eigenvalue]) -> Result<()> {
    let mut err = std::io::stderr().lock();
    writeln!(err, "{:>14} {:>14} {:>14} {:>9}", "real (1/s)", "imag (1/s)", "frequency (Hz)", "damping")?;
    for e in eigenvalues.iter().filter(|e| e.imag >= 0.0) {
        writeln!(err, "{:>14.6e} {:>14.6e} {:>14.6e} {:>9.4}", e.real, e.imag, e.frequency_hz, e.damping_ratio)?;
    }
    Ok(())
}

/// The matrices as NumPy's .npz (a zip of .npy files: A, B, C, D, Ad, Bd
/// with a step, and eigenvalues as rows of (real, imag)).
fn write_npz(path: &Path, linear: &Linearization) -> Result<()> {
    let eigenvalues = DMatrix::from_fn(linear.eigenvalues.len(), 2, |i, j| {
        if j == 0 { linear.eigenvalues[i].re } else { linear.eigenvalues[i].im }
    });
    let mut arrays = vec![("A", &linear.a), ("B", &linear.b), ("C", &linear.c), ("D", &linear.d)];
    if let Some((_, ad, bd)) = &linear.discrete {
        arrays.extend([("Ad", ad), ("Bd", bd)]);
    }
    arrays.push(("eigenvalues", &eigenvalues));
    let mut archive = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let options = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    for (name, matrix) in arrays {
        archive.start_file(format!("{name}.npy"), options)?;
        archive.write_all(&npy(matrix))?;
    }
    std::fs::write(path, archive.finish()?.into_inner())?;
    Ok(())
}

/// One matrix in NumPy's .npy format 1.0: the magic string, the version,
/// a little-endian header length, a Python dict literal padded with
/// spaces to a multiple of 64 bytes and ended by a newline, then the
/// entries as little-endian f64 in row-major order. Written here: the
/// format is this one page of NumPy's documentation, and the crate that
/// writes it (npyz) brings a Python-literal parser and an old zip with it.
fn npy(matrix: &DMatrix<f64>) -> Vec<u8> {
    let dict =
        format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({}, {}), }}", matrix.nrows(), matrix.ncols());
    let unpadded = 10 + dict.len() + 1;
    let header = format!("{dict}{}\n", " ".repeat(unpadded.next_multiple_of(64) - unpadded));
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((header.len() as u16).to_le_bytes());
    out.extend(header.bytes());
    for row in matrix.row_iter() {
        row.iter().for_each(|v| out.extend(v.to_le_bytes()));
    }
    out
}
