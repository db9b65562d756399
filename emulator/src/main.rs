//! `scanhil-emulator`, the plant: serves an emulated mirror and sensor, and runs bench
//! commands on the plant model. Each subcommand lives in its own module under `commands/`.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod commands;

/// The scanhil plant emulator.
#[derive(Debug, Parser)]
#[command(name = "scanhil-emulator", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Where the spot lands, the true surface there and what the sensor reports, for a static mirror.
    Probe(commands::probe::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Probe(args) => commands::probe::run(args),
    };
    match result {
        Ok(code) => code,
        Err(err) => {
            eprintln!("scanhil-emulator: error: {err:#}");
            ExitCode::FAILURE
        }
    }
}
