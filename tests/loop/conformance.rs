//! `scanhil conformance` against the emulator, with JUnit XML.

use crate::util::{assert_success, fixture, run_scanhil};

#[test]
fn the_emulator_passes_every_conformance_check() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let junit = out.path().join("conformance.xml");
    let output = run_scanhil(&[
        "conformance",
        "--fsm",
        "pty",
        "--sensor",
        "pty",
        "--scene",
        &fixture("scenes/duplo-2x4-130mm.json"),
        "--junit",
        junit.to_str().expect("UTF-8 path"),
    ]);
    assert_success(&output, "scanhil conformance");
    let table = String::from_utf8_lossy(&output.stdout);
    for check in [
        "answers_in_time",
        "angle_sequence_gapless",
        "angles_in_range",
        "status_frames",
        "over_current_fault",
        "survives_malformed_frames",
        "survives_garbage_slcan_lines",
        "sensor_values_decode",
        "sensor_counter_gapless",
        "sensor_values_in_range",
        "sensor_survives_bad_commands",
        "link_timeout_fault",
    ] {
        let line = table
            .lines()
            .find(|line| line.contains(check))
            .unwrap_or_else(|| panic!("{check} missing from:\n{table}"));
        assert!(line.contains("PASS"), "{line}");
    }
    let xml = std::fs::read_to_string(&junit).expect("JUnit XML written");
    assert!(xml.contains("tests=\"12\" failures=\"0\""), "{xml}");
    assert_eq!(xml.matches("<testcase ").count(), 12, "{xml}");
    // The new checks say what they sent and that the device still answered.
    for (check, seen) in [
        ("survives_garbage_slcan_lines", "still answering"),
        ("sensor_survives_bad_commands", "GETINFO still answered"),
    ] {
        let line = table.lines().find(|line| line.contains(check)).unwrap();
        assert!(line.contains(seen), "{line}");
    }
}

/// Runs `scanhil conformance` on the mirror node of a hand-started emulator served with
/// `emulator_args`; returns the exit code, the table and the JUnit XML.
fn conformance_against(emulator_args: &[&str]) -> (Option<i32>, String, String) {
    let scene = fixture("scenes/duplo-2x4-130mm.json");
    let mut args = vec!["--scene", scene.as_str(), "--fsm", "slcan:pty"];
    args.extend_from_slice(emulator_args);
    let emulator = crate::util::ServedEmulator::start(&args);
    let out = tempfile::tempdir().expect("a temporary folder");
    let junit = out.path().join("conformance.xml");
    let fsm = format!("slcan:{}", emulator.path("fsm"));
    let output = run_scanhil(&[
        "conformance",
        "--fsm",
        &fsm,
        "--junit",
        junit.to_str().expect("UTF-8 path"),
    ]);
    drop(emulator);
    let xml = std::fs::read_to_string(&junit).unwrap_or_default();
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stdout).into_owned(),
        xml,
    )
}

#[test]
fn a_node_without_a_watchdog_fails_the_link_timeout_check() {
    // The emulator with a watchdog no check waits for (10^6 periods of 10 ms): a node that
    // keeps its coils driven when the host goes silent. Only link_timeout_fault may fail, and
    // the JUnit XML says why.
    let (code, table, xml) = conformance_against(&["--watchdog-periods", "1000000"]);
    assert_eq!(code, Some(1), "conformance fails:\n{table}");
    let line = table
        .lines()
        .find(|line| line.contains("link_timeout_fault"))
        .unwrap_or_else(|| panic!("no link_timeout_fault in:\n{table}"));
    assert!(line.contains("FAIL"), "{line}");
    for other in table
        .lines()
        .filter(|l| l.starts_with("fsm ") && !l.contains("link_timeout_fault"))
    {
        assert!(
            other.contains("PASS"),
            "only the watchdog check fails: {other}"
        );
    }
    assert!(xml.contains("failures=\"1\""), "{xml}");
    let case = xml
        .split("<testcase ")
        .find(|case| case.contains("link_timeout_fault"))
        .expect("a testcase for link_timeout_fault");
    assert!(
        case.contains("<failure message=\"no LinkTimeout fault from the node"),
        "{case}"
    );
}
