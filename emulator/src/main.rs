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
    /// Serve the emulated mirror node and/or sensor on real links (SLCAN, SocketCAN, ILD).
    Serve(commands::serve::Args),
    /// Serve a recorded session (fsm.log, sensor.ild) as the mirror node and the sensor, in lockstep.
    Replay(commands::replay::Args),
    /// Where the spot lands, the true surface there and what the sensor reports, for a static mirror.
    Probe(commands::probe::Args),
    /// Open-loop response of the emulated mirror to a coil current step (a bench bump test).
    Step(commands::step::Args),
    /// Integrators' error against the exact solution and run time (work-precision study).
    Precision(commands::precision::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Serve(args) => commands::serve::run(args),
        Command::Replay(args) => commands::replay::run(args),
        Command::Probe(args) => commands::probe::run(args),
        Command::Step(args) => commands::step::run(args),
        Command::Precision(args) => commands::precision::run(args),
    };
    match result {
        Ok(code) => code,
        Err(err) => {
            eprintln!(
                "scanhil-emulator: error: {}",
                scanhil_protocol::error_text::chain_text(&*err)
            );
            ExitCode::FAILURE
        }
    }
}
