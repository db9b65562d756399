//! One module per `scanhil` subcommand: its clap `Args` and a `run` returning the exit code.

pub mod conformance;
pub mod decode;
pub mod reconstruct;
pub mod scan;
