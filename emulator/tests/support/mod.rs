//! Helpers shared by the command-line tests: running the binary and naming fixture scenes.

use std::path::Path;
use std::process::{Command, Output};

/// Runs `scanhil-emulator` with `args` and collects its output.
pub fn emulator(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_scanhil-emulator"))
        .args(args)
        .output()
        .expect("run scanhil-emulator")
}

/// The path of the scene `fixtures/scenes/<name>`, as an argument.
pub fn fixture(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/scenes")
        .join(name)
        .display()
        .to_string()
}
