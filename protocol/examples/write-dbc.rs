//! Writes the DBC file for the message set to the path given (default `protocol/scanhil.dbc`
//! when run from the repository root). `cargo run -p scanhil-protocol --example write-dbc`.

use std::process::ExitCode;

fn main() -> ExitCode {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "protocol/scanhil.dbc".to_owned());
    match std::fs::write(&path, scanhil_protocol::dbc::render()) {
        Ok(()) => {
            eprintln!("wrote {path}");
            ExitCode::SUCCESS
        }
        Err(err) => {
            eprintln!("write-dbc: cannot write {path}: {err}");
            ExitCode::FAILURE
        }
    }
}
