//! One module per `scanhil-emulator` subcommand: its clap `Args` and a `run` returning the
//! exit code.

pub mod precision;
pub mod probe;
pub mod replay;
pub mod serve;
pub mod step;

/// Passes an output error on, except a closed pipe (`... | head`), which ends output quietly.
pub fn print_or_broken_pipe(result: std::io::Result<()>) -> std::io::Result<()> {
    match result {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        other => other,
    }
}
