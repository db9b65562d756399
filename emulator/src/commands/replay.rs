//! `scanhil-emulator replay DIR`: a recorded session served as the mirror node and the sensor.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;

/// Serve a recorded session (`DIR/fsm.log`, `DIR/sensor.ild`) as the devices, on the links
/// `serve` takes.
#[derive(Debug, clap::Args)]
#[group(id = "replay_args")]
pub struct Args {
    /// The session's folder: a scan's output folder, or a bench capture (`fsm.log` in candump
    /// `-L` form, `sensor.ild` the raw ILD stream, `report.json` optional).
    dir: PathBuf,
    /// The links and settings, as `serve` takes them; the scene gives the control period and
    /// the sensor's settings (its answers to the host's commands), the recording everything
    /// the devices send.
    #[command(flatten)]
    serve: super::serve::Args,
}

/// Serves the session (in lockstep, or in real time at its recorded times) until the
/// controller ends the run; prints the `ready` and
/// `summary` lines as `serve` does, the summary's `replay` comparing the controller's coil
/// commands with the recorded ones. Exit status as `serve`'s.
///
/// # Errors
/// A recording that cannot be served (naming the file and the first bad line), a scene that
/// does not load, a link that does not open.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    args.serve.exit_with_parent_if_asked()?;
    let mut config = args.serve.config();
    config.replay = Some(args.dir);
    let outcome = scanhil_emulator::serve::serve(&config).context("replay")?;
    Ok(ExitCode::from(outcome.exit_status()))
}
