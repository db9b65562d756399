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
    // Complete, and ended with the coils at zero: the end's zero command is never faulted.
    assert_eq!(node["final_state"], "ready");
    assert_eq!(node["held_coil_currents_a"]["a"], 0.0, "{node}");
    assert_eq!(node["held_coil_currents_a"]["b"], 0.0, "{node}");
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
fn with_every_frame_bit_flipped_the_final_zero_command_still_reaches_the_node_intact() {
    // Every frame the host sends has a bit flipped, so the node never answers and the scan
    // stops on its watchdog; the zero command it ends with goes past the injected faults.
    let out = tempfile::tempdir().expect("a temporary folder");
    let dir = out.path();
    let output = run_scanhil(&[
        "scan",
        &fixture("scenarios/test-loop-small.json"),
        "--out",
        dir.to_str().expect("UTF-8 path"),
        "--fault",
        "host_to_node.bit_flip_rate=1",
        "--watchdog-periods",
        "20",
    ]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(3), "{stderr}");
    let report = report(dir);
    let coils = &report["coils_at_end"];
    assert_eq!(coils["zero_commanded"], true, "{coils}");
    assert_eq!(coils["node_held_coil_currents_a"]["a"], 0.0, "{coils}");
    assert_eq!(coils["node_held_coil_currents_a"]["b"], 0.0, "{coils}");
    assert!(
        report["faults"]["injected"]
            .to_string()
            .contains("bit_flip")
    );
    // The recording is the node's side of the link: its last CoilCommand is the zero, whole.
    let log = std::fs::read_to_string(dir.join("fsm.log")).expect("fsm.log");
    let last_command = log
        .lines()
        .rfind(|line| line.contains(" 100#"))
        .expect("a CoilCommand recorded");
    assert!(
        last_command.ends_with(" 100#0000000000000000"),
        "{last_command}"
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
        stderr.contains(
            "--fault node_to_host.drop_rate=1.5: field `faults.node_to_host.drop_rate`: 1.5 \
             must be within 0 and 1"
        ),
        "{stderr}"
    );
}

#[test]
fn frame_faults_in_real_time_are_injected_passed_over_and_reported() {
    let out = tempfile::tempdir().expect("a temporary folder");
    // Bit flips rarer than the rest: a corrupted angle is taken for its period in real time
    // (it cannot be asked for again), and each one kicks the controller.
    let rates = "{\"drop_rate\":0.005,\"delay_rate\":0.005,\"delay_periods\":2,\
                 \"duplicate_rate\":0.005,\"reorder_rate\":0.005,\"bit_flip_rate\":0.0005}";
    let host_to_node = format!("host_to_node={rates}");
    let node_to_host = format!("node_to_host={rates}");
    let args = crate::util::realtime_scan_args(
        out.path(),
        "0.5",
        &["--fault", &host_to_node, "--fault", &node_to_host],
    );
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let output = run_scanhil(&args);
    let report = crate::util::assert_ran_every_period(&output, out.path());
    assert_eq!(report["periods"]["done"], 10_000, "{:#}", report["periods"]);
    let faults = &report["faults"];
    for direction in ["host_to_node", "node_to_host"] {
        let frames = &faults["injected"]["frames"][direction];
        assert_eq!(frames["balances"], true, "{faults:#}");
        for kind in [
            "dropped",
            "delayed",
            "duplicated",
            "reordered",
            "bit_flipped",
        ] {
            assert!(
                frames["ledger"][kind].as_u64().unwrap() > 0,
                "{direction}: {kind}: {faults:#}"
            );
        }
    }
    // The host passes over duplicated and delayed readings (late), never taking one for a
    // reading 2^16 periods on, and counts the ones that went missing.
    let host = &faults["host_detected"];
    assert!(host["late_readings"].as_u64().unwrap() > 0, "{host}");
    assert!(host["angle_sequence_gaps"].as_u64().unwrap() > 0, "{host}");
    assert_eq!(host["stopped_by"], serde_json::Value::Null, "{host}");
    let node = &faults["node_detected"];
    assert!(node["command_gaps"].as_u64().unwrap() > 0, "{node}");
    println!("host {host}\nnode {node}");
}
