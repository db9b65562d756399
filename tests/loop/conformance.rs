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
