//! The `nudyn` command's library side: the exporter, which writes the FMI
//! contract of `nudyn-contract` down as an FMU archive.
#![warn(missing_docs)]

pub mod export;
pub mod output;
