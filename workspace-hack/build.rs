//! Empty: cargo resolves a crate's build-dependencies only when it has a
//! build script, and `workspace-hack`'s are there for their features.
fn main() {}
