//! One module per `scanhil-emulator` subcommand: its clap `Args` and a `run` returning the
//! exit code.

pub mod probe;
