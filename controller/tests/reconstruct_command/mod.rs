//! The `scanhil reconstruct` command for this crate's tests.

use std::path::Path;
use std::process::Command;

use scanhil_controller::imaging::pipeline::ImagingReport;

/// `scanhil reconstruct <input> --out-dir <out_dir>`, ready for more arguments.
pub fn scanhil_reconstruct(input: &Path, out_dir: &Path) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_scanhil"));
    command.args([
        "reconstruct",
        input.to_str().unwrap(),
        "--out-dir",
        out_dir.to_str().unwrap(),
    ]);
    command
}

/// Runs a `scanhil reconstruct` command that must succeed (it fails the test with the
/// command's output otherwise): its stdout and the `report.json` it wrote into `out_dir`.
pub fn reconstruct_succeeds(command: &mut Command, out_dir: &Path) -> (String, ImagingReport) {
    let run = command.output().unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout).into_owned();
    assert!(
        run.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("report.json")).unwrap())
            .unwrap();
    (
        stdout,
        serde_json::from_value(report["imaging"].clone()).unwrap(),
    )
}
