//! Outputs that cannot be written: a full disk (a symlink to `/dev/full`, which fails every
//! write with ENOSPC) under a recording stops the scan naming the file, and under report.json
//! leaves the other outputs written; a directory in the way of one output does not stop the
//! others. Each exits 3 and names the file; report.json (when it can be written) lists the
//! failed files with why.

use std::path::Path;

use crate::util::{fixture, report, run_scanhil};

/// Scans test-loop-small into `out`; returns the exit code and stderr.
fn scan_into(out: &Path) -> (Option<i32>, String) {
    let output = run_scanhil(&[
        "scan",
        &fixture("scenarios/test-loop-small.json"),
        "--out",
        out.to_str().expect("UTF-8 path"),
    ]);
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

/// Scans into a fresh folder where `file` is a symlink to `/dev/full`; returns the folder,
/// the exit code, stderr and the ENOSPC text.
fn scan_with_full_disk_under(file: &str) -> (tempfile::TempDir, Option<i32>, String, String) {
    let out = tempfile::tempdir().expect("a temporary folder");
    std::os::unix::fs::symlink("/dev/full", out.path().join(file)).expect("a symlink");
    let (code, stderr) = scan_into(out.path());
    let full = std::io::Error::from_raw_os_error(28).to_string(); // ENOSPC
    (out, code, stderr, full)
}

/// The reason report.json gives for `file` in `outputs.failed`.
fn failure_of<'a>(report: &'a serde_json::Value, file: &str) -> &'a str {
    report["outputs"]["failed"][file]
        .as_str()
        .unwrap_or_else(|| panic!("{file} listed as failed: {}", report["outputs"]))
}

#[test]
fn a_full_disk_under_the_mirror_recording_stops_the_scan_naming_the_file() {
    let (out, code, stderr, full) = scan_with_full_disk_under("fsm.log");
    assert_eq!(code, Some(3), "{stderr}");
    let log = out.path().join("fsm.log");
    let named = format!("writing {}: {full}", log.display());
    assert!(
        stderr.contains("scan stopped early: writing the capture of") && stderr.contains(&named),
        "stderr names the file and the error:\n{stderr}"
    );
    let report = report(out.path());
    assert_eq!(report["outcome"]["complete"], false);
    assert_eq!(failure_of(&report, "fsm.log"), named);
}

#[test]
fn a_full_disk_under_report_json_leaves_the_other_outputs_written() {
    let (out, code, stderr, full) = scan_with_full_disk_under("report.json");
    assert_eq!(code, Some(3), "{stderr}");
    let report_path = out.path().join("report.json");
    assert!(
        stderr.contains(&format!(
            "outputs not written in {}: report.json (writing {}: {full})",
            out.path().display(),
            report_path.display()
        )),
        "{stderr}"
    );
    for file in ["fsm.log", "tracking.svg"] {
        let size = std::fs::metadata(out.path().join(file)).map_or(0, |m| m.len());
        assert!(size > 1000, "{file} written ({size} bytes)");
    }
}

#[test]
fn a_directory_in_the_way_of_one_output_does_not_stop_the_others() {
    let out = tempfile::tempdir().expect("a temporary folder");
    std::fs::create_dir(out.path().join("tracking.svg")).expect("a directory in the way");
    let (code, stderr) = scan_into(out.path());
    assert_eq!(code, Some(3), "{stderr}");
    assert!(
        stderr.contains("outputs not written in") && stderr.contains("tracking.svg ("),
        "{stderr}"
    );
    let report = report(out.path());
    assert_eq!(report["outcome"]["complete"], true, "the loop ran whole");
    let why = failure_of(&report, "tracking.svg");
    assert!(
        why.contains(&std::io::Error::from_raw_os_error(21).to_string()), // EISDIR
        "{why}"
    );
    assert_eq!(
        report["outputs"]["failed"].as_object().map(|o| o.len()),
        Some(1),
        "only the blocked output failed"
    );
    assert!(
        out.path()
            .join("fsm.log")
            .metadata()
            .is_ok_and(|m| m.len() > 1000)
    );
}

#[test]
fn a_stdout_that_cannot_be_written_is_an_error_once_the_outputs_are_written() {
    // `scanhil scan > /dev/full` once panicked after writing everything (exit 101).
    let out = tempfile::tempdir().expect("a temporary folder");
    let full = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .expect("opening /dev/full");
    let child = std::process::Command::new(crate::util::scanhil())
        .args([
            "scan",
            &fixture("scenarios/test-loop-small.json"),
            "--duration-s",
            "0.01",
            "--out",
            out.path().to_str().expect("UTF-8 path"),
        ])
        .env("SCANHIL_EMULATOR", crate::util::emulator())
        .stdout(full)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("starting scanhil");
    let output = crate::util::exits_within(child, crate::util::RUN_LIMIT, "scanhil > /dev/full");
    let stderr = String::from_utf8_lossy(&output.stderr);
    let enospc = std::io::Error::from_raw_os_error(28).to_string();
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains(&format!("scanhil: error: writing to stdout: {enospc}"))
            && !stderr.contains("panicked"),
        "{stderr}"
    );
    assert_eq!(report(out.path())["outcome"]["verdict"], "complete");
}
