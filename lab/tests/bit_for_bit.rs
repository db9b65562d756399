//! The in-process loop against `scanhil scan` over ptys: the same scenario and seed give the
//! same recordings and point cloud bit for bit, and the same tracking error and periods.

#[allow(dead_code)]
#[path = "../../tests/loop/util.rs"]
mod util;

use std::path::Path;

use scanhil_controller::run::ScanEnd;
use scanhil_controller::run::scenario::Scenario;
use util::{assert_success, report, root, run_scanhil};

/// Runs `scenario` (with `duration_s` if given) in process and over ptys, and compares.
/// `files` must exist in both folders and be byte-identical.
fn compare(scenario: &str, duration_s: Option<&str>, files: &[&str]) {
    let path = root().join("fixtures/scenarios").join(scenario);
    let mut loaded = Scenario::load(&path).expect("the scenario loads");
    if let Some(duration_s) = duration_s {
        loaded.duration_s = duration_s.parse().expect("a duration in seconds");
    }
    let in_process = tempfile::tempdir().expect("a temporary folder");
    let outcome =
        scanhil_lab::in_process::run(&loaded, Some(in_process.path())).expect("the in-process run");
    assert_eq!(
        outcome.end,
        ScanEnd::Complete,
        "the in-process run ended early"
    );

    let over_pty = tempfile::tempdir().expect("a temporary folder");
    let path_arg = path.to_str().expect("UTF-8 path");
    let out_arg = over_pty.path().to_str().expect("UTF-8 path");
    let mut args = vec!["scan", path_arg, "--out", out_arg];
    if let Some(duration_s) = duration_s {
        args.extend(["--duration-s", duration_s]);
    }
    assert_success(&run_scanhil(&args), "scanhil scan");

    for file in files {
        let lab = read(in_process.path(), file);
        let pty = read(over_pty.path(), file);
        assert!(!pty.is_empty(), "{scenario}: {file} is empty");
        assert!(
            lab == pty,
            "{scenario}: {file} differs between the in-process and the pty run \
             ({} and {} bytes)",
            lab.len(),
            pty.len()
        );
    }
    let lab = report(in_process.path());
    let pty = report(over_pty.path());
    assert_eq!(
        lab.pointer("/scenario/duration_s"),
        pty.pointer("/scenario/duration_s"),
        "{scenario}: the two runs ran different durations"
    );
    for pointer in ["/tracking_error", "/periods", "/outcome"] {
        assert_eq!(
            lab.pointer(pointer),
            pty.pointer(pointer),
            "{scenario}: report.json {pointer} differs"
        );
    }
    assert!(
        lab.pointer("/periods/done")
            .and_then(serde_json::Value::as_u64)
            > Some(0),
        "{scenario}: no period ran"
    );
}

fn read(dir: &Path, file: &str) -> Vec<u8> {
    std::fs::read(dir.join(file))
        .unwrap_or_else(|error| panic!("{}: {error}", dir.join(file).display()))
}

#[test]
fn the_small_loop_records_the_same_mirror_link_in_process_as_over_ptys() {
    compare("test-loop-small.json", None, &["fsm.log"]);
}

#[test]
fn the_duplo_scan_records_and_images_the_same_in_process_as_over_ptys() {
    // Its whole 0.25 s: the ILD stream, and fault frames (over-current) on the mirror's link.
    compare(
        "test-duplo-stud.json",
        None,
        &["fsm.log", "sensor.ild", "points.ply"],
    );
}

#[test]
fn a_shortened_raster_scan_records_and_images_the_same_in_process_as_over_ptys() {
    compare(
        "duplo-raster-pid.json",
        Some("0.1"),
        &["fsm.log", "sensor.ild", "points.ply"],
    );
}
