//! `scanhil-emulator probe` (being written by the optics work).

use std::process::ExitCode;

/// Arguments of `scanhil-emulator probe`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs `scanhil-emulator probe`.
pub fn run(_args: Args) -> anyhow::Result<ExitCode> {
    anyhow::bail!("probe is not written yet")
}
