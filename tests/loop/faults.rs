//! Faults declared in a scenario, over the pty links (`fixtures/scenarios/test-loop-faults.json`):
//! random frame faults on both directions of the mirror's SLCAN link plus a Step and an
//! AngleReading dropped at listed periods, the laser off for 5 ms and bursts of occlusion on
//! the ILD stream. The scan completes; `report.json` `faults` lists what was injected and what
//! each side detected, and the recording (the node's side of the link) agrees with the node's
//! counters frame for frame. A command-line override passes the file's checks.

use crate::util::{assert_success, decode_candump, fixture, report, run_scanhil};

#[test]
fn faults_declared_in_a_scenario_are_injected_detected_and_reported_over_ptys() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let dir = out.path().to_str().expect("UTF-8 path");
    let output = run_scanhil(&[
        "scan",
        &fixture("scenarios/test-loop-faults.json"),
        "--out",
        dir,
    ]);
    assert_success(&output, "scanhil scan test-loop-faults");
    let report = report(out.path());
    assert_eq!(report["outcome"]["complete"], true);
    assert_eq!(report["periods"]["done"], 1000);
    let faults = &report["faults"];
    let frames = &faults["injected"]["frames"];
    for direction in ["host_to_node", "node_to_host"] {
        assert_eq!(frames[direction]["balances"], true, "{faults:#}");
        assert!(frames[direction]["ledger"]["dropped"].as_u64().unwrap() >= 1);
    }
    let listed = |direction: &str, period: u64, message: &str| {
        frames[direction]["first_faults"]
            .as_array()
            .unwrap()
            .iter()
            .any(|f| f["period"] == period && f["message"] == message && f["fault"] == "drop")
    };
    assert!(listed("host_to_node", 300, "Step"), "{faults:#}");
    assert!(listed("node_to_host", 600, "AngleReading"), "{faults:#}");
    // Each lost Step or reading costs one repeated Step; the node answers a repeat it had
    // stepped already from its last reading.
    let host = &faults["host_detected"];
    let node = &faults["node_detected"];
    assert!(host["repeated_steps"].as_u64().unwrap() >= 2, "{host}");
    assert!(node["repeated_steps"].as_u64().unwrap() >= 1, "{node}");
    assert_eq!(node["final_state"], "running");
    assert_eq!(host["stopped_by"], serde_json::Value::Null);
    // The laser off for 5 ms at 20 kHz: 100 samples, all seen by the host as `laser_off`.
    let sensor = &faults["injected"]["sensor_samples"];
    assert_eq!(sensor["laser_off"], 100, "{sensor}");
    assert_eq!(host["sensor_error_values"]["laser_off"], 100, "{host}");
    assert!(sensor["occluded"].as_u64().unwrap() > 0, "{sensor}");
    assert!(
        host["sensor_error_values"]["no_peak"].as_u64().unwrap()
            >= sensor["occluded"].as_u64().unwrap(),
        "{host} {sensor}"
    );
    // The recording is the node's side: every reading the node sent (one per period plus one
    // per repeated Step) and every command it received (applied or counted late) is there.
    let recording = decode_candump(&out.path().join("fsm.log"));
    let summary = &report["emulator"]["summary"]["node"];
    let count = |field: &str| summary[field].as_u64().unwrap() as usize;
    assert_eq!(
        recording.angle_seqs.len(),
        count("periods") + count("repeated_steps"),
        "{summary}"
    );
    assert_eq!(
        recording.command_seqs.len(),
        count("commands") + count("late_commands"),
        "{summary}"
    );
}

#[test]
fn a_fault_override_on_the_command_line_is_checked_as_the_file_is() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let dir = out.path().to_str().expect("UTF-8 path");
    let output = run_scanhil(&[
        "scan",
        &fixture("scenarios/test-loop-faults.json"),
        "--out",
        dir,
        "--fault",
        "node_to_host.drop_rate=1.5",
    ]);
    assert_eq!(output.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("test-loop-faults.json: field `faults.node_to_host.drop_rate`: 1.5 must be within 0 and 1"),
        "{stderr}"
    );
}
