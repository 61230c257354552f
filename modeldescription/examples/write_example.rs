//! Prints the model description of a small but representative co-simulation
//! FMU (see `tests/common/mod.rs`); the Python tests validate this output
//! against the official FMI 2.0 schema.
//!
//! ```sh
//! cargo run -q -p modeldescription --example write_example
//! ```

#[path = "../tests/common/mod.rs"]
mod common;

fn main() -> Result<(), modeldescription::Error> {
    let model = common::arm();
    let problems = modeldescription::validate(&model);
    assert!(problems.is_empty(), "the example breaks FMI 2.0 rules: {problems:#?}");
    print!("{}", modeldescription::to_xml(&model)?);
    Ok(())
}
