//! The controller's side of the watchdog: the emulator freezes (SIGSTOP) or dies (SIGKILL)
//! mid-run; the scan stops with a link timeout / hang-up, commands zero, exits non-zero, and
//! what it recorded stays valid.

use std::time::{Duration, Instant};

use scanhil_protocol::message::Message;

use crate::util::{
    children, decode_candump, recording_grows, report, scan_against_served_emulator, signal,
    start_long_scan,
};

/// Runs a long scan against a hand-started emulator with the scan's watchdog at
/// `watchdog_periods` (of the scenario's 50 ms allowance), sends the emulator `signal_name`
/// after a moment, and returns scanhil's exit code, stderr, output folder, and the wall time
/// from the signal to its exit.
fn scan_and_signal(
    signal_name: &str,
    watchdog_periods: u32,
) -> (Option<i32>, String, tempfile::TempDir, Duration) {
    let out = tempfile::tempdir().expect("a temporary folder");
    let periods = watchdog_periods.to_string();
    let (emulator, child) = scan_against_served_emulator(
        out.path(),
        &[],
        &["--duration-s", "60", "--watchdog-periods", &periods],
    );
    // Let the loop run, then stop the emulator.
    let _ = recording_grows(out.path(), 10_000);
    signal(emulator.child.id(), signal_name);
    let signalled = Instant::now();
    let output = child.wait_with_output().expect("waiting for scanhil");
    let detected_within = signalled.elapsed();
    if signal_name == "STOP" {
        signal(emulator.child.id(), "CONT");
    }
    drop(emulator);
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
        out,
        detected_within,
    )
}

/// Asserts a scan stopped early for `why`: exit 3, the reason on stderr and in the report, a
/// recording that decodes, and (if `zero_command_sent`) a zero last command.
pub fn assert_stopped_cleanly(
    code: Option<i32>,
    stderr: &str,
    out: &tempfile::TempDir,
    why: &str,
    zero_command_sent: bool,
) {
    assert_eq!(
        code,
        Some(3),
        "exit status 3 for a scan stopped early; stderr:\n{stderr}"
    );
    assert!(
        stderr.contains(why),
        "stderr names the cause `{why}`:\n{stderr}"
    );
    let report = report(out.path());
    assert_eq!(report["outcome"]["complete"], false);
    assert!(
        report["outcome"]["stopped_by"]
            .as_str()
            .is_some_and(|s| s.contains(why)),
        "{}",
        report["outcome"]
    );
    // Everything recorded decodes, and (when the link still takes it) the controller's last
    // word is a zero command.
    let recording = decode_candump(&out.path().join("fsm.log"));
    assert!(
        recording.angle_seqs.len() > 100,
        "the loop ran before the stop"
    );
    if !zero_command_sent {
        return;
    }
    let text = std::fs::read_to_string(out.path().join("fsm.log")).expect("fsm.log");
    let last_command = text
        .lines()
        .rev()
        .find(|line| line.contains(" 100#"))
        .expect("a CoilCommand in the log");
    let data = last_command.split('#').nth(1).expect("frame data");
    let bytes = scanhil_protocol::can::parse_hex(data.as_bytes()).expect("hex");
    let frame = scanhil_protocol::can::CanFrame::new(
        scanhil_protocol::can::CanId::standard(0x100).expect("11-bit id"),
        &bytes,
    )
    .expect("a frame");
    let Ok(Message::CoilCommand(command)) = Message::decode(&frame) else {
        panic!("not a CoilCommand: {last_command}");
    };
    assert_eq!(
        (command.current_a_ua, command.current_b_ua),
        (0, 0),
        "{last_command}"
    );
}

#[test]
fn a_frozen_emulator_stops_the_scan_with_a_link_timeout() {
    // 40 x 50 ms = 2 s: far above a loaded machine's hiccup before the freeze, so the
    // timeout is the freeze's (a 0.5 s watchdog nearly coincided with such stalls).
    let (code, stderr, out, _) = scan_and_signal("STOP", 40);
    assert_stopped_cleanly(code, &stderr, &out, "link timeout", true);
}

#[test]
fn a_killed_emulator_stops_the_scan_with_a_hang_up() {
    // A watchdog no run reaches (100 000 x 50 ms): only the hang-up can stop this scan, so
    // the cause cannot be a timeout racing the kill.
    let (code, stderr, out, detected_within) = scan_and_signal("KILL", 100_000);
    assert_stopped_cleanly(code, &stderr, &out, "hung up", false);
    // The detection bound: the host's next read sees the hang-up (no watchdog involved, its
    // 5000 s are never reached); 10 s covers writing the outputs on a loaded machine.
    assert!(
        detected_within < Duration::from_secs(10),
        "the scan ended {detected_within:?} after the kill"
    );
}

#[test]
fn an_emulator_killed_mid_scan_is_reported_as_killed_by_its_signal() {
    // The emulator the scan started itself is SIGKILLed by someone else mid-scan: the scan
    // stops (hang-up, exit 3) and report.json says the emulator was killed, and by what.
    let out = tempfile::tempdir().expect("a temporary folder");
    let scan = start_long_scan(out.path(), 10_000);
    let emulators = children(scan.id());
    assert_eq!(
        emulators.len(),
        1,
        "one emulator under the scan: {emulators:?}"
    );
    signal(emulators[0], "KILL");
    let output = scan.wait_with_output().expect("waiting for scanhil");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(3), "{stderr}");
    let emulator = &report(out.path())["emulator"];
    assert_eq!(emulator["killed"], true, "{emulator}");
    assert_eq!(emulator["signal"], "SIGKILL", "{emulator}");
    assert_eq!(emulator["killed_by_host"], false, "{emulator}");
    assert_eq!(
        emulator["exit_status"],
        serde_json::Value::Null,
        "{emulator}"
    );
}
