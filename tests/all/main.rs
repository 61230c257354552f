//! nudyn's integration tests, one test binary with a module per topic: one
//! link instead of one per file, and the harness runs every topic's tests
//! on all cores at once. `common` is the shared harness (random vehicles and
//! the independent dense reference).
//!
//! A new topic is a module here: `tests/all/<topic>.rs` and a `mod` line
//! below. A file directly under `tests/` would become a binary of its own,
//! linked separately: [`one_integration_test_binary_per_crate`] refuses a
//! second one in any crate of the workspace.

mod common;

mod actuation;
mod actuator_import;
mod adaptive_integration;
mod compile_stage;
mod constraints;
mod control_law;
mod damped_errors;
mod deep_trees;
mod derivatives;
mod dynamics_checks;
mod dynamics_errors;
mod end_effector;
mod error_modes;
mod flex_actuators;
mod flex_dynamics;
mod flex_import;
mod flex_modal_file;
mod flex_sites;
mod gravity_compensation;
mod integration_order;
mod mjcf_files;
mod mjcf_import;
mod mjcf_support;
mod model_json;
mod qacc_jacobian;
mod reaching;
mod rosenbrock_jacobian;
mod sensor_import;
mod simulation;
mod stiff_integration;
mod stiffness;
mod tendon_import;

#[test]
fn one_integration_test_binary_per_crate() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    for krate in [".", "bench", "cli", "contract", "fmu", "modeldescription"] {
        let Ok(entries) = std::fs::read_dir(root.join(krate).join("tests")) else { continue };
        // Cargo's auto-discovered test targets: tests/*.rs and tests/*/main.rs.
        let binaries: Vec<String> = entries
            .map(|entry| entry.unwrap().path())
            .filter(|path| path.extension().is_some_and(|ext| ext == "rs") || path.join("main.rs").is_file())
            .map(|path| path.display().to_string())
            .collect();
        assert!(binaries.len() <= 1, "{krate}: fold these into one tests/all/main.rs with a module each: {binaries:?}");
    }
}
