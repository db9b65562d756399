//! One module per `scanhil` subcommand: its clap `Args` and a `run` returning the exit code.

pub mod analyze;
pub mod compare;
pub mod conformance;
pub mod decode;
pub mod design;
pub mod identify;
pub mod reconstruct;
pub mod scan;
pub mod trajectory;
