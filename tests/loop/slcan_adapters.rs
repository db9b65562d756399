//! The host against SLCAN adapters as their firmware behaves: the emulator's device end plays
//! a silent adapter, a CANable (answers nothing but a free-text version), a Lawicel with
//! timestamps on and a classic Lawicel with transmit acks (`--slcan-adapter`), and
//! `scanhil conformance --fsm slcan:PTY@1000000` passes every check through each; a scan runs
//! through the Lawicel with timestamps and reports what the adapter did.

use crate::util::{ServedEmulator, assert_success, fixture, report, run_scanhil};

/// Serves the mirror node of `scene` on a pty with the device end playing `adapter` (the
/// watchdog the 50 periods of 10 ms conformance is run with).
fn serve_as(scene: &str, adapter: &str) -> ServedEmulator {
    let scene = fixture(scene);
    let emulator = ServedEmulator::start(&[
        "--scene",
        &scene,
        "--fsm",
        "slcan:pty",
        "--slcan-adapter",
        adapter,
        "--watchdog-periods",
        "50",
    ]);
    assert_eq!(
        emulator.ready["slcan_adapter"], adapter,
        "{}",
        emulator.ready
    );
    emulator
}

#[test]
fn conformance_passes_through_every_adapter_firmware() {
    for adapter in ["silent", "canable", "lawicel-timestamps", "lawicel"] {
        let emulator = serve_as("scenes/duplo-2x4-130mm.json", adapter);
        let fsm = format!("slcan:{}@1000000", emulator.path("fsm"));
        let output = run_scanhil(&["conformance", "--fsm", &fsm, "--watchdog-periods", "50"]);
        let table = String::from_utf8_lossy(&output.stdout);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_success(&output, &format!("conformance through {adapter}"));
        let checks: Vec<&str> = table.lines().filter(|l| l.starts_with("fsm ")).collect();
        assert!(checks.len() >= 8, "{adapter}:\n{table}");
        for line in &checks {
            assert!(line.contains("PASS"), "{adapter}: {line}");
        }
        // The link says what it found: the bit rate set with S8, whether the adapter answers.
        let answers = if matches!(adapter, "silent" | "canable") {
            "it answered no command"
        } else {
            "it answers commands"
        };
        assert!(
            stderr.contains(&format!(
                "{fsm}: canable SLCAN adapter, bit rate 1000000 set with S8; {answers}"
            )),
            "{adapter}: {stderr}"
        );
    }
}

#[test]
fn a_scan_through_a_lawicel_with_timestamps_uses_and_reports_its_stamps() {
    let emulator = serve_as("scenes/loop-fast.json", "lawicel-timestamps");
    let out = tempfile::tempdir().expect("a temporary folder");
    // No bit rate: the 20 kHz loop fits no real bus; the adapter keeps its own setting.
    let fsm = format!("slcan:{}?family=lawicel", emulator.path("fsm"));
    let output = run_scanhil(&[
        "scan",
        &fixture("scenarios/test-loop-small.json"),
        "--fsm",
        &fsm,
        "--no-emulator",
        "--out",
        out.path().to_str().expect("UTF-8 path"),
    ]);
    assert_success(&output, "scan through a Lawicel with timestamps");
    let report = report(out.path());
    let link = &report["links"]["mirror_link"];
    assert_eq!(link["transport"], "slcan", "{link}");
    assert_eq!(link["slcan"]["family"], "lawicel", "{link}");
    assert_eq!(
        link["slcan"]["bitrate_set"],
        serde_json::Value::Null,
        "{link}"
    );
    assert_eq!(link["slcan"]["adapter_answers"], true, "{link}");
    let stats = &link["stats"]["slcan"];
    let received = link["stats"]["frames_received"].as_u64().expect("a count");
    assert!(received > 0, "{link}");
    assert_eq!(
        stats["stamped_frames"], received,
        "every frame stamped: {link}"
    );
    assert_eq!(
        stats["transmit_acks"], link["stats"]["frames_sent"],
        "a z for every frame sent: {link}"
    );
    assert_eq!(
        stats["bus"]["status_replies"], 2,
        "F after O and before C: {link}"
    );
    assert_eq!(stats["malformed_lines"], 0, "{link}");
}
