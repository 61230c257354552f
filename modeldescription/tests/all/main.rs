//! The modelDescription crate's integration tests, one test binary with a
//! module per topic; `common` builds the valid model they start from (and
//! the one examples/write_example.rs prints).

#[path = "../common/mod.rs"]
mod common;

mod golden;
mod round_trip;
mod validation;
