//! `scanhil decode` (being written by the protocol work).

use std::process::ExitCode;

/// Arguments of `scanhil decode`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs `scanhil decode`.
pub fn run(_args: Args) -> anyhow::Result<ExitCode> {
    anyhow::bail!("decode is not written yet")
}
