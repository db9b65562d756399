//! `scanhil`, the host program: runs scans, analyses controllers, identifies the plant and
//! decodes recordings. Each subcommand lives in its own module under `commands/`.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod commands;

/// The scanhil host: scans, control analysis, identification and protocol tools.
#[derive(Debug, Parser)]
#[command(name = "scanhil", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run a scan scenario over real links (the emulator on pty pairs by default).
    Scan(commands::scan::Args),
    /// Check a mirror node and a sensor, real or emulated, against the loop protocol.
    Conformance(commands::conformance::Args),
    /// Decode a candump log, an SLCAN stream or an ILD 2300 byte stream into JSON lines.
    Decode(commands::decode::Args),
    /// Reconstruct a recording of samples: PLY points, height map PNG/CSV, JSON report.
    Reconstruct(commands::reconstruct::Args),
    /// Draw two scan or reconstruct output folders side by side: snapshots and profiles.
    Compare(commands::compare::Args),
    /// Analyse a controller file: discrete sections, poles, zeros and the nominal closed loop.
    Analyze(commands::analyze::Args),
    /// Measure a frequency response (open-loop plant or closed loop) with a stepped sine.
    Identify(commands::identify::Args),
    /// Design a PID or dual-tone controller for a plant at a rig's (or its bus's) rate.
    Design(commands::design::Args),
    /// Print a trajectory's frame rate and line spacing (JSON).
    Trajectory(commands::trajectory::Args),
}

fn main() -> ExitCode {
    die_quietly_on_a_closed_pipe();
    scanhil_controller::run::chunked::return_freed_chunks_to_the_os();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Scan(args) => commands::scan::run(args),
        Command::Conformance(args) => commands::conformance::run(args),
        Command::Decode(args) => commands::decode::run(args),
        Command::Reconstruct(args) => commands::reconstruct::run(args),
        Command::Compare(args) => commands::compare::run(args),
        Command::Analyze(args) => commands::analyze::run(args),
        Command::Identify(args) => commands::identify::run(args),
        Command::Design(args) => commands::design::run(args),
        Command::Trajectory(args) => commands::trajectory::run(args),
    };
    match result {
        Ok(code) => code,
        Err(err) => {
            eprintln!(
                "scanhil: error: {}",
                scanhil_protocol::error_text::chain_text(&*err)
            );
            ExitCode::FAILURE
        }
    }
}

/// A closed pipe on stdout (`scanhil analyze ... | head`) ends the program quietly, as it ends
/// any Unix filter, instead of a panic in `println!` (Rust starts programs with SIGPIPE
/// ignored). Writes to ptys, serial lines and CAN sockets raise no SIGPIPE, so the links'
/// own errors are unchanged.
fn die_quietly_on_a_closed_pipe() {
    use nix::sys::signal::{SigHandler, Signal, signal};
    // SAFETY: restoring a signal's default disposition at start-up, before any other thread
    // exists, installs no handler code and races with nothing.
    let _ = unsafe { signal(Signal::SIGPIPE, SigHandler::SigDfl) };
}
