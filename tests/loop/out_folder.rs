//! The output folder belongs to one scan at a time: a second scan into a folder in use is
//! refused (nothing spliced into the first's recordings), and a re-scan leaves no stale file of
//! an earlier scan beside its new report.

use crate::util::{assert_success, fixture, report, run_scanhil, start_long_scan};

#[test]
fn a_second_scan_into_a_folder_in_use_is_refused() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let out_arg = out.path().to_str().expect("UTF-8 path");
    let mut first = start_long_scan(out.path(), 1000);
    let second = run_scanhil(&[
        "scan",
        &fixture("scenarios/test-loop-small.json"),
        "--out",
        out_arg,
    ]);
    let _ = first.kill();
    let _ = first.wait();
    assert_eq!(second.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&second.stderr);
    assert!(
        stderr.contains("another scan still running") && stderr.contains(out_arg),
        "{stderr}"
    );
}

#[test]
fn a_rescan_leaves_no_stale_output_beside_the_new_report() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let out_arg = out.path().to_str().expect("UTF-8 path");
    // An earlier scan with optics left a snapshot; the mirror-only scan now writes none.
    std::fs::write(out.path().join("snapshots.png"), b"stale").expect("writing");
    std::fs::write(out.path().join("notes.txt"), b"mine").expect("writing");
    let output = run_scanhil(&[
        "scan",
        &fixture("scenarios/test-loop-small.json"),
        "--out",
        out_arg,
    ]);
    assert_success(&output, "scanhil scan");
    assert_eq!(report(out.path())["outcome"]["complete"], true);
    assert!(
        !out.path().join("snapshots.png").exists(),
        "stale snapshot removed"
    );
    assert_eq!(
        std::fs::read(out.path().join("notes.txt")).expect("kept"),
        b"mine",
        "files the scan does not write are left alone"
    );
}

#[test]
fn a_scan_told_to_leave_out_its_recordings_and_figures_writes_neither_and_says_so() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let out_arg = out.path().to_str().expect("UTF-8 path");
    // An earlier scan's recording is not left beside a report that says there is none.
    std::fs::write(out.path().join("fsm.log"), b"stale").expect("writing");
    let output = run_scanhil(&[
        "scan",
        &fixture("scenarios/test-duplo-stud.json"),
        "--out",
        out_arg,
        "--duration-s",
        "0.05",
        "--no-recordings",
        "--no-figures",
    ]);
    assert_success(&output, "scanhil scan --no-recordings --no-figures");
    let report = report(out.path());
    assert_eq!(report["outcome"]["complete"], true);
    let left_out: Vec<&str> = report["outputs"]["left_out"]
        .as_array()
        .expect("a list")
        .iter()
        .filter_map(|file| file.as_str())
        .collect();
    assert_eq!(
        left_out,
        [
            "fsm.log",
            "sensor.ild",
            "tracking.svg",
            "height_map.png",
            "progressive.svg",
            "snapshots.png",
            "profiles.svg"
        ]
    );
    for file in left_out {
        assert!(!out.path().join(file).exists(), "{file} written");
    }
    for file in ["points.ply", "height_map.csv", "profiles.csv"] {
        assert!(out.path().join(file).exists(), "{file} missing");
    }
    assert!(
        report["imaging"]["feature"]["height_mm"].as_f64().is_some(),
        "the stud is still measured: {}",
        report["imaging"]
    );
}
