//! `nudyn modal`: checks a modal data file (docs/flexible.md) and
//! summarizes what a structures or GNC engineer looks at first: the nodes'
//! mass properties, and per mode its frequency, damping and how much of the
//! body's mass it moves (participation factors and effective masses).

use std::path::Path;

use anyhow::Result;
use nudyn::flex::{ModalBody, ModalError, Mode};
use nudyn::math::{Mat3, Vec3};
use serde::Serialize;

/// What `nudyn modal --json` prints (docs/cli.md lists the fields).
#[derive(Serialize)]
struct Summary {
    file: String,
    nodes: usize,
    /// Nodes that no mode moves: the clamped interface.
    fixed_nodes: usize,
    fixed_mass: f64,
    mass: f64,
    com: [f64; 3],
    /// About the centre of mass, body axes.
    inertia: [[f64; 3]; 3],
    /// About the body origin, body axes: the rigid-body rotations' mass.
    inertia_about_origin: [[f64; 3]; 3],
    modes: Vec<ModeSummary>,
    /// Σ effective masses over the rigid-body mass (total mass, and the
    /// diagonal of the inertia about the origin); null where that is 0.
    effective_mass_fraction: Directions<Option<f64>>,
}

#[derive(Serialize)]
struct ModeSummary {
    frequency: f64,
    damping_ratio: f64,
    /// L = Φᵀ M B, Φ of unit modal mass in SI: kg^½ (translations), kg^½ m (rotations).
    participation: Directions<f64>,
    /// L²: kg, kg m².
    effective_mass: Directions<f64>,
    effective_mass_fraction: Directions<Option<f64>>,
}

/// The six rigid-body motions of the body: translations along, and
/// rotations about, the body axes through its origin.
#[derive(Serialize)]
struct Directions<T> {
    translation: [T; 3],
    rotation: [T; 3],
}

impl<T: Copy> Directions<T> {
    fn from_fn(f: impl Fn(usize) -> T) -> Self {
        Directions { translation: [f(0), f(1), f(2)], rotation: [f(3), f(4), f(5)] }
    }
    fn get(&self, k: usize) -> T {
        if k < 3 { self.translation[k] } else { self.rotation[k - 3] }
    }
}

/// Reads, checks and summarizes the modal file at `path`.
pub fn run(path: &Path, json: bool) -> Result<()> {
    // The file is read alone, for no MJCF body: name only the file.
    let body = read(path)?;
    let summary = summarize(path, &body);
    if json { super::emit(&serde_json::to_string_pretty(&summary)?) } else { super::emit(&table(&summary)) }
}

fn read(path: &Path) -> Result<ModalBody> {
    nudyn::flex::modal_file::read(path, "").map_err(|e| match e {
        ModalError::Read { source, .. } => anyhow::anyhow!("cannot read the modal file {}: {source}", path.display()),
        ModalError::Invalid { problem, .. } => anyhow::anyhow!("modal file {}: {problem}", path.display()),
        other => other.into(),
    })
}

/// L_k = Σ_j m_j Φᵗ_j·bᵗ_jk + Φʳ_j·(I_j bʳ_jk) for the rigid-body mode k
/// (bᵗ = e, bʳ = 0 for a translation along e; bᵗ = e × r_j, bʳ = e for a
/// rotation about e through the origin).
fn participation(body: &ModalBody, mode: &Mode) -> Directions<f64> {
    Directions::from_fn(|k| {
        let axis = Vec3::ith(k % 3, 1.0);
        body.nodes
            .iter()
            .enumerate()
            .map(|(j, node)| {
                if k < 3 {
                    node.mass * mode.translation[j].dot(&axis)
                } else {
                    node.mass * mode.translation[j].dot(&axis.cross(&node.position))
                        + mode.rotation[j].dot(&(node.rotary_inertia * axis))
                }
            })
            .sum()
    })
}

fn summarize(path: &Path, body: &ModalBody) -> Summary {
    let properties = body.mass_properties();
    let inertia_about_origin: Mat3 = body
        .nodes
        .iter()
        .map(|n| {
            let r = n.position;
            n.rotary_inertia + (Mat3::identity() * r.norm_squared() - r * r.transpose()) * n.mass
        })
        .sum();
    let rigid_mass = |k: usize| if k < 3 { properties.mass } else { inertia_about_origin[(k - 3, k - 3)] };
    let fraction = |value: f64, k: usize| (rigid_mass(k) > 0.0).then(|| value / rigid_mass(k));
    let modes: Vec<ModeSummary> = body
        .modes
        .iter()
        .map(|mode| {
            let participation = participation(body, mode);
            let effective_mass = Directions::from_fn(|k| participation.get(k).powi(2));
            let effective_mass_fraction = Directions::from_fn(|k| fraction(effective_mass.get(k), k));
            ModeSummary {
                frequency: mode.angular_frequency / std::f64::consts::TAU,
                damping_ratio: mode.damping_ratio,
                participation,
                effective_mass,
                effective_mass_fraction,
            }
        })
        .collect();
    let effective_mass_fraction =
        Directions::from_fn(|k| fraction(modes.iter().map(|m| m.effective_mass.get(k)).sum(), k));
    let fixed: Vec<usize> = (0..body.nodes.len())
        .filter(|&j| body.modes.iter().all(|m| m.translation[j] == Vec3::zeros() && m.rotation[j] == Vec3::zeros()))
        .collect();
    let rows = |m: &Mat3| [0, 1, 2].map(|i| [m[(i, 0)], m[(i, 1)], m[(i, 2)]]);
    Summary {
        file: path.display().to_string(),
        nodes: body.nodes.len(),
        fixed_nodes: fixed.len(),
        fixed_mass: fixed.iter().map(|&j| body.nodes[j].mass).sum(),
        mass: properties.mass,
        com: properties.com.into(),
        inertia: rows(&properties.inertia),
        inertia_about_origin: rows(&inertia_about_origin),
        modes,
        effective_mass_fraction,
    }
}

/// Six significant digits: the table is read by a person; `--json` has every digit.
fn g(x: f64) -> String {
    let text = format!("{x:.5e}");
    let exponent: i32 = text.split('e').nth(1).and_then(|e| e.parse().ok()).unwrap_or(0);
    if x == 0.0 || !(-4..6).contains(&exponent) {
        return if x == 0.0 { "0".into() } else { text };
    }
    let plain = format!("{x:.*}", (5 - exponent) as usize);
    if plain.contains('.') { plain.trim_end_matches('0').trim_end_matches('.').to_string() } else { plain }
}

/// The `<inertial>` element that the MJCF body made flexible by this file
/// needs (mass, centre of mass and inertia about it in the body frame), to
/// paste: numbers in full, as the check is relative to 1e-6.
fn mjcf_inertial(s: &Summary) -> String {
    let i = &s.inertia;
    let numbers = |values: &[f64]| values.iter().map(|&x| super::number(x)).collect::<Vec<_>>().join(" ");
    format!(
        "<inertial pos=\"{}\" mass=\"{}\" fullinertia=\"{}\"/>",
        numbers(&s.com),
        super::number(s.mass),
        numbers(&[i[0][0], i[1][1], i[2][2], i[0][1], i[0][2], i[1][2]])
    )
}

fn table(s: &Summary) -> String {
    // Round-off in the products of inertia (1e-18 beside 0.07) shows as 0.
    let inertia = |m: &[[f64; 3]; 3]| {
        let entries = [m[0][0], m[1][1], m[2][2], m[0][1], m[0][2], m[1][2]];
        let scale = entries.iter().fold(0.0_f64, |a, x| a.max(x.abs()));
        entries.map(|x| g(if x.abs() <= 1e-12 * scale { 0.0 } else { x })).join(" ")
    };
    let percent = |f: Option<f64>| f.map_or("-".to_string(), |f| format!("{:.2}", 100.0 * f));
    let mut out = format!(
        "{}: {} nodes ({} that no mode moves, {} kg), {} modes\n\
         mass {} kg, centre of mass ({}, {}, {}) m (body frame)\n\
         inertia about the centre of mass (Ixx Iyy Izz Ixy Ixz Iyz): {} kg m²\n\
         inertia about the body origin: {} kg m²\n\
         the body's MJCF inertial, every digit (the nodes must give it within 1e-6):\n    {}\n\n\
         effective mass, % of the mass (translations) and of the inertia about the body origin (rotations)\n",
        s.file,
        s.nodes,
        s.fixed_nodes,
        g(s.fixed_mass),
        s.modes.len(),
        g(s.mass),
        g(s.com[0]),
        g(s.com[1]),
        g(s.com[2]),
        inertia(&s.inertia),
        inertia(&s.inertia_about_origin),
        mjcf_inertial(s),
    );
    out += &format!(
        "{:<5} {:>14} {:>9} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7}",
        "mode", "frequency (Hz)", "damping", "x", "y", "z", "rx", "ry", "rz"
    );
    let directions =
        |d: &Directions<Option<f64>>| (0..6).map(|k| format!(" {:>7}", percent(d.get(k)))).collect::<String>();
    for (k, mode) in s.modes.iter().enumerate() {
        out += &format!(
            "\n{:<5} {:>14} {:>9}{}",
            k + 1,
            g(mode.frequency),
            g(mode.damping_ratio),
            directions(&mode.effective_mass_fraction)
        );
    }
    out += &format!("\n{:<5} {:>14} {:>9}{}", "sum", "", "", directions(&s.effective_mass_fraction));
    out
}
