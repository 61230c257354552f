//! A freeze of what the importer and the compiler produce today, for the
//! refactor of issue 46 (parse, then compile; one qpos0 stage), which must
//! change none of it.
//!
//! For every MJCF file under `examples/` and `tests/fixtures/`, the files in
//! `tests/fixtures/compile_freeze/` hold what importing and compiling it
//! gave before the refactor: the import's error message, or its warnings,
//! the compiled model's JSON (or the compile error) and the dynamics
//! (`nudyn eval`'s response) at qpos0 at rest and at one random state with
//! random controls. These files are today's output frozen on purpose, not
//! an independent check of it: the dynamics are checked against MuJoCo and
//! the dense reference elsewhere. Every number must agree to 1e-15
//! relative, every string exactly.
//!
//! To write the files again (only when a change of the output is intended
//! and named in its commit): `NUDYN_FREEZE_WRITE=1 cargo test --release
//! --test compile_stage`.

use std::path::{Path, PathBuf};

use crate::common::Rng;
use nudyn::eval::{EvalRequest, evaluate};
use nudyn::model::Model;
use serde_json::{Value, json};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every `.xml` under `dir`, sorted.
fn mjcf_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            mjcf_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "xml") {
            out.push(path);
        }
    }
}

/// A message with the checkout's path replaced, so that the freeze does
/// not depend on where the repository is.
fn portable(message: String) -> String {
    message.replace(&repo().display().to_string(), "<repo>")
}

/// The dynamics at `theta` (random ν, ε and ctrl when `rng` is given; at
/// rest and without inputs otherwise).
fn dynamics(model: &Model, theta: Vec<f64>, rng: Option<&mut Rng>) -> Value {
    let mut ws = model.workspace();
    let request = match rng {
        None => EvalRequest {
            theta,
            nu: Some(vec![0.0; model.nv]),
            qvel: None,
            eps: None,
            torque: None,
            ctrl: None,
            act: None,
            time: None,
        },
        Some(rng) => EvalRequest {
            theta,
            nu: Some((0..model.nv).map(|_| rng.uniform(-1.0, 1.0)).collect()),
            qvel: None,
            eps: Some((0..model.nv).map(|_| rng.uniform(-1.0, 1.0)).collect()),
            torque: None,
            ctrl: Some((0..model.actuators.len()).map(|_| rng.uniform(-1.0, 1.0)).collect()),
            act: None,
            time: Some(0.25),
        },
    };
    match evaluate(model, &mut ws, &request) {
        Ok(response) => serde_json::to_value(response).unwrap(),
        Err(error) => json!({ "error": error.to_string() }),
    }
}

/// What importing and compiling `path` gives, as JSON.
fn freeze(path: &Path) -> Value {
    let imported = match nudyn::mjcf::load_mjcf(path) {
        Ok(imported) => imported,
        Err(error) => return json!({ "import_error": portable(error.to_string()) }),
    };
    let warnings: Vec<String> = imported.warnings.iter().map(|w| portable(w.to_string())).collect();
    let model = match Model::compile(&imported.vehicle) {
        Ok(model) => model,
        Err(error) => return json!({ "warnings": warnings, "compile_error": error.to_string() }),
    };
    let mut rng = Rng::new(46);
    let random_theta: Vec<f64> = model.qpos0.iter().map(|q| q + rng.uniform(-0.3, 0.3)).collect();
    let mut frozen = json!({
        "warnings": warnings,
        "model": serde_json::to_value(&model).unwrap(),
        "dynamics_at_qpos0": dynamics(&model, model.qpos0.clone(), None),
        "dynamics_at_random_state": dynamics(&model, random_theta, Some(&mut rng)),
    });
    // A wrench input on the last moving body (the examples only: what
    // `nudyn export --wrench-inputs` compiles).
    if path.starts_with(repo().join("examples")) {
        let body = model.links.last().unwrap().body_name.clone();
        let with_wrench = Model::compile_with_wrench_inputs(&imported.vehicle, &[body]).unwrap();
        frozen["model_with_wrench_input"] = serde_json::to_value(&with_wrench).unwrap();
    }
    frozen
}

/// Where the freeze of `path` is kept.
fn frozen_path(path: &Path) -> PathBuf {
    let relative = path.strip_prefix(repo()).unwrap().with_extension("json");
    let name = relative.to_str().unwrap().replace('/', "__");
    repo().join("tests/fixtures/compile_freeze").join(name)
}

/// The freeze as JSON with each top-level key on a line of its own
/// (compact within: pretty-printed, the models' arrays take 2.5 times the room).
fn one_key_a_line(frozen: &Value) -> String {
    let lines: Vec<String> = frozen
        .as_object()
        .unwrap()
        .iter()
        .map(|(key, value)| format!("{}: {}", Value::from(key.as_str()), value))
        .collect();
    format!("{{\n{}\n}}\n", lines.join(",\n"))
}

/// Whether `found` is `expected` to 1e-15 relative in every number and
/// exactly in everything else; the first difference's place otherwise.
fn agrees(expected: &Value, found: &Value, place: &str) -> Result<(), String> {
    match (expected, found) {
        (Value::Number(a), Value::Number(b)) => {
            let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
            if a == b || (a - b).abs() <= 1e-15 * a.abs().max(b.abs()) {
                Ok(())
            } else {
                Err(format!("{place}: expected {a:e}, found {b:e}"))
            }
        }
        (Value::Array(a), Value::Array(b)) if a.len() == b.len() => {
            a.iter().zip(b).enumerate().try_for_each(|(k, (a, b))| agrees(a, b, &format!("{place}[{k}]")))
        }
        (Value::Object(a), Value::Object(b)) if a.keys().eq(b.keys()) => {
            a.iter().try_for_each(|(key, value)| agrees(value, &b[key], &format!("{place}.{key}")))
        }
        (Value::Object(a), Value::Object(b)) => {
            let missing: Vec<&String> = a.keys().filter(|k| !b.contains_key(*k)).collect();
            let extra: Vec<&String> = b.keys().filter(|k| !a.contains_key(*k)).collect();
            let extra_values: Vec<String> = extra.iter().map(|k| format!("{k}: {}", b[*k])).collect();
            Err(format!("{place}: missing {missing:?}, new {}", extra_values.join(", ")))
        }
        _ if expected == found => Ok(()),
        _ => Err(format!("{place}: expected {expected}, found {found}")),
    }
}

#[test]
fn every_mjcf_file_imports_and_compiles_as_before_the_refactor() {
    let mut files = Vec::new();
    mjcf_files(&repo().join("examples"), &mut files);
    mjcf_files(&repo().join("tests/fixtures"), &mut files);
    assert!(files.len() >= 80, "expected the examples and fixtures, found {} files", files.len());
    let write = std::env::var_os("NUDYN_FREEZE_WRITE").is_some();
    let mut differences = Vec::new();
    for path in &files {
        let found = freeze(path);
        let kept = frozen_path(path);
        if write {
            std::fs::create_dir_all(kept.parent().unwrap()).unwrap();
            std::fs::write(&kept, one_key_a_line(&found)).unwrap();
            continue;
        }
        let text = std::fs::read_to_string(&kept).unwrap_or_else(|e| panic!("{}: {e}", kept.display()));
        let expected: Value = serde_json::from_str(&text).unwrap();
        if let Err(difference) = agrees(&expected, &found, "") {
            differences.push(format!("{}: {difference}", path.display()));
        }
    }
    assert!(differences.is_empty(), "{} files differ from the freeze:\n{}", differences.len(), differences.join("\n"));
}
